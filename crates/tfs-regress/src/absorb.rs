//! Zeroing rows into an upper-triangular factor by Householder reflections that keep its
//! structure (the kernel of [`Compressed`](crate::Compressed)'s appends and merges): one
//! reflection per column for few rows or another factor's trapezoid, a panel of reflections
//! at a time (compact WY) for tall chunks. On x86-64 processors with AVX2 the same code is
//! compiled a second time for that vector width and chosen at run time.

use faer::{Mat, Par};

/// Column entries beyond which (or, when non-zero, below which) the unscaled sums of squares
/// of [`absorb_rows`] could overflow or underflow; such input goes to the dense QR.
const ABSORB_SAFE: (f64, f64) = (1e-140, 1e140);

/// One column's Householder step of [`absorb_rows_unblocked`] and [`absorb_rows_blocked`]:
/// the reflection that zeroes the `a` rows of `B` (rows `n1..n1+a`) below the triangle's entry
/// `(j, j)` of column `j` of `w` (leading dimension `ld`), applied to the next `later` columns.
/// Returns `None` when an entry is outside [`ABSORB_SAFE`], `Some(0.0)` when the column of `B`
/// is already zero (no reflection), else `Some(τ)`; the reflection's vector is left in `B`.
#[inline(always)]
fn absorb_column(
    w: &mut [f64],
    (n1, ld, a): (usize, usize, usize),
    j: usize,
    later: usize,
) -> Option<f64> {
    use crate::kernels::{dot, sub_scaled};
    let (lo, hi) = ABSORB_SAFE;
    // Without branches (`a > hi` also holds for ∞), so that the test of a whole column
    // vectorises.
    let outside = |v: f64| {
        let a = v.abs();
        (a > hi) | ((a != 0.0) & (a < lo)) | a.is_nan()
    };
    let (head, tail) = w.split_at_mut((j + 1) * ld);
    let colj = &mut head[j * ld..];
    let alpha = colj[j];
    let v = &mut colj[n1..n1 + a];
    if outside(alpha) | v.iter().fold(false, |any, &x| any | outside(x)) {
        return None;
    }
    let Some((beta, tau)) = crate::fit::householder(alpha, v) else {
        return Some(0.0);
    };
    colj[j] = beta;
    let v = &colj[n1..n1 + a];
    for col in tail.chunks_exact_mut(ld).take(later) {
        let (t, b) = col.split_at_mut(n1);
        let b = &mut b[..a];
        let s = tau * (t[j] + dot(v, b));
        t[j] -= s;
        sub_scaled(b, s, v);
    }
    Some(tau)
}

/// Columns per panel of [`absorb_rows_blocked`].
const ABSORB_PANEL: usize = 12;

/// Rows from which [`absorb_rows`] applies the reflections a panel at a time.
const ABSORB_BLOCKED_MIN_ROWS: usize = 96;

/// Zero `k` rows into an upper-triangular factor (see [`absorb_rows_unblocked`] for the layout
/// and the contract): many rows in blocks of reflections ([`absorb_rows_blocked`]), few (or
/// another factor's trapezoid) one reflection at a time.
pub(crate) fn absorb_rows(w: &mut [f64], n1: usize, ld: usize, k: usize, trapezoid: bool) -> bool {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the processor has AVX2, checked just above.
        return unsafe { absorb_rows_avx2(w, n1, ld, k, trapezoid) };
    }
    absorb_rows_any(w, n1, ld, k, trapezoid)
}

/// [`absorb_rows_any`] compiled for AVX2: the inner products and updates four lanes at a time
/// instead of two. The same operations in the same order (Rust never fuses a multiply and an
/// add), so the same bits as the baseline code.
///
/// # Safety
/// The processor must have AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn absorb_rows_avx2(w: &mut [f64], n1: usize, ld: usize, k: usize, trapezoid: bool) -> bool {
    absorb_rows_any(w, n1, ld, k, trapezoid)
}

/// [`absorb_rows`] for any processor; inlined into the vector-width variants.
#[inline(always)]
fn absorb_rows_any(w: &mut [f64], n1: usize, ld: usize, k: usize, trapezoid: bool) -> bool {
    if trapezoid || k < ABSORB_BLOCKED_MIN_ROWS || n1 <= ABSORB_PANEL {
        absorb_rows_unblocked(w, n1, ld, k, trapezoid)
    } else {
        absorb_rows_blocked(w, n1, ld, k)
    }
}

/// [`absorb_rows_unblocked`] for `k` full rows, the reflections of `ABSORB_PANEL` columns at a
/// time (LAPACK's triangular-pentagonal QR, `dtpqrt`, with a pentagon of zero height). Each
/// panel is reduced column by column on its own columns; its reflections
/// `H_i = I − τ_i·u_i·u_iᵀ`, `u_i = e_{j_i} + v_i` (`v_i` in the rows of `B`), are then applied
/// to all later columns at once as `I − V·Tᵀ·Vᵀ` (compact WY): `W = C_T + V_Bᵀ·C_B`,
/// `W ← Tᵀ·W`, `C_T −= W`, `C_B −= V_B·W`, two matrix products where one reflection per column
/// made a pass over every later column of `B` for each column of the panel. The unit parts
/// `e_{j_i}` are orthogonal, so `T` needs only the `B` parts: `T_ii = τ_i`,
/// `T[..i, i] = −τ_i·T[..i, ..i]·(V_B[:, ..i]ᵀ·v_i)`. Same reflections as the unblocked form, so
/// the same factor to rounding.
#[inline(always)]
fn absorb_rows_blocked(w: &mut [f64], n1: usize, ld: usize, k: usize) -> bool {
    use crate::kernels::dot;
    use faer::linalg::matmul::matmul;
    use faer::{Accum, MatMut};
    debug_assert!(ld >= n1 + k && w.len() == ld * n1);
    let mut tau = [0.0f64; ABSORB_PANEL];
    let mut t = Mat::<f64>::zeros(ABSORB_PANEL, ABSORB_PANEL);
    let mut z = [0.0f64; ABSORB_PANEL];
    let mut j0 = 0;
    while j0 < n1 {
        let nb = ABSORB_PANEL.min(n1 - j0);
        let j1 = j0 + nb;
        // The panel, one reflection per column on the panel's own columns (a column of `B`
        // that is already zero gets τ = 0 and keeps its zero vector in V).
        for j in j0..j1 {
            match absorb_column(w, (n1, ld, k), j, j1 - j - 1) {
                Some(tj) => tau[j - j0] = tj,
                None => return false,
            }
        }
        if j1 < n1 {
            let (head, tail) = w.split_at_mut(j1 * ld);
            let vcol = |i: usize| &head[(j0 + i) * ld + n1..(j0 + i) * ld + n1 + k];
            // T of the panel (upper triangular, nb×nb).
            for i in 0..nb {
                for (p, zp) in z.iter_mut().enumerate().take(i) {
                    *zp = dot(vcol(p), vcol(i));
                }
                for p in 0..i {
                    let s: f64 = (p..i).map(|q| t[(p, q)] * z[q]).sum();
                    t[(p, i)] = -tau[i] * s;
                }
                t[(i, i)] = tau[i];
            }
            let m = n1 - j1;
            let vb =
                faer::MatRef::from_column_major_slice_with_stride(&head[j0 * ld + n1..], k, nb, ld);
            let trailing = MatMut::from_column_major_slice_with_stride_mut(
                &mut tail[j0..],
                n1 + k - j0,
                m,
                ld,
            );
            let (mut ct, rest) = trailing.split_at_row_mut(nb);
            let (_, mut cb) = rest.split_at_row_mut(n1 - j1);
            // W = C_T + V_Bᵀ·C_B, then W ← Tᵀ·W.
            let mut wm = ct.to_owned();
            matmul(
                wm.as_mut(),
                Accum::Add,
                vb.transpose(),
                cb.as_ref(),
                1.0,
                Par::Seq,
            );
            let tt = t.as_ref().get(..nb, ..nb);
            let mut w2 = Mat::<f64>::zeros(nb, m);
            faer::linalg::matmul::triangular::matmul(
                w2.as_mut(),
                faer::linalg::matmul::triangular::BlockStructure::Rectangular,
                Accum::Replace,
                tt.transpose(),
                faer::linalg::matmul::triangular::BlockStructure::TriangularLower,
                wm.as_ref(),
                faer::linalg::matmul::triangular::BlockStructure::Rectangular,
                1.0,
                Par::Seq,
            );
            // C_T −= W, C_B −= V_B·W.
            for c in 0..m {
                for r in 0..nb {
                    ct[(r, c)] -= w2[(r, c)];
                }
            }
            matmul(cb.as_mut(), Accum::Add, vb, w2.as_ref(), -1.0, Par::Seq);
        }
        j0 = j1;
    }
    true
}

/// Zero `k` rows into an upper-triangular factor with one Householder reflection per column,
/// in place: `w` is column-major with leading dimension `ld ≥ n1 + k`, rows `0..n1` hold the
/// upper-triangular `T` and rows `n1..n1+k` the rows `B` (rows below are not read). Afterwards rows `0..n1` hold the
/// upper-triangular factor of `[T; B]` (the rows of `B` are left as Householder vectors).
///
/// The reflection for column `j` acts on row `j` of `T` and on the rows of `B` still non-zero
/// in that column: all `k` of them, or, with `trapezoid` (row `i` of `B` is zero left of column
/// `i`, as in another block's factor), the first `min(j+1, k)`. No other entry changes: the
/// rows of `T` are never mixed with each other, which is what makes this cheaper than a QR of
/// the stacked matrix (which does not know `T` is already triangular).
///
/// Returns `false` when an entry is outside [`ABSORB_SAFE`] (the caller then uses the
/// dense QR, whose norms are scaled); `w` is then partly updated and must be discarded.
#[inline(always)]
fn absorb_rows_unblocked(w: &mut [f64], n1: usize, ld: usize, k: usize, trapezoid: bool) -> bool {
    debug_assert!(ld >= n1 + k && w.len() == ld * n1);
    for j in 0..n1 {
        let a = if trapezoid { (j + 1).min(k) } else { k };
        if a == 0 {
            continue;
        }
        if absorb_column(w, (n1, ld, a), j, n1 - j - 1).is_none() {
            return false;
        }
    }
    true
}
