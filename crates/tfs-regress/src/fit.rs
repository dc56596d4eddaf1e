//! The common result type [`Fit`], the [`Regressor`] trait, least squares and ridge.

use crate::compress::Compressed;
use crate::error::{Result, check_param};
use crate::kernels::{dot, sub_scaled};
use faer::linalg::triangular_solve::solve_upper_triangular_in_place;
use faer::{Mat, MatRef, Par};

/// Result of one regression.
#[derive(Debug, Clone, PartialEq)]
pub struct Fit {
    /// Coefficients in the original units of the columns of `A` (zero outside the support).
    pub coef: Vec<f64>,
    /// `support[j]` is true when column `j` is in the model.
    pub support: Vec<bool>,
    /// Training residual sum of squares `‖Aξ − b‖²`.
    pub rss: f64,
    /// Columns that were in the candidate set but were found numerically dependent on
    /// earlier (pivoted) columns, or identically zero; their coefficient is 0.
    pub dependent: Vec<usize>,
    /// Iterations used (1 for direct solvers).
    pub iterations: usize,
    /// False when an iterative method stopped at its `max_iter` before converging.
    pub converged: bool,
}

impl Fit {
    /// Number of non-zero terms.
    pub fn n_terms(&self) -> usize {
        self.support.iter().filter(|&&s| s).count()
    }

    pub(crate) fn from_coef(
        p: &Compressed,
        coef: Vec<f64>,
        dependent: Vec<usize>,
        iterations: usize,
        converged: bool,
    ) -> Result<Self> {
        let support = coef.iter().map(|&v| v != 0.0).collect();
        let rss = p.rss(&coef)?;
        Ok(Self {
            coef,
            support,
            rss,
            dependent,
            iterations,
            converged,
        })
    }
}

/// A sparse or dense linear regressor. One required method works on a [`Compressed`]
/// problem; [`Regressor::fit`] compresses raw rows first.
///
/// Convention: `A` is a faer `MatRef<f64>` (rows = samples, columns = library terms) and
/// `b` a slice with one entry per row.
pub trait Regressor {
    /// Fit on a compressed problem.
    fn fit_compressed(&self, p: &Compressed) -> Result<Fit>;

    /// Fit on raw rows `(A, b)`: compresses once, then calls [`Regressor::fit_compressed`].
    fn fit(&self, a: MatRef<'_, f64>, b: &[f64]) -> Result<Fit> {
        self.fit_compressed(&Compressed::from_rows(a, b)?)
    }
}

/// Relative rank tolerance for the small pivoted QR: `|r_kk| ≤ max(rows, cols)·ε·|r_00|`
/// marks column `k` (in pivot order) as dependent.
fn rank_tol(rows: usize, cols: usize) -> f64 {
    rows.max(cols) as f64 * f64::EPSILON
}

/// Least squares on a small dense system `min ‖M x − y‖`: one unpivoted QR where the rank is
/// clearly full ([`unpivoted_lstsq`]), a column-pivoted QR otherwise. Returns `x` (zero for dependent columns) and the dependent column indices. The rank
/// tolerance is that of a system of `tol_rows` rows (see [`rank_tol`]), so trailing zero rows
/// left out of `M` do not change which columns count as dependent.
///
/// Sequential on purpose: it is called thousands of times per identification, from inside
/// rayon tasks, on matrices of a few dozen rows. `Qᵀy` is applied from the Householder factors
/// (no explicit `Q`).
pub(crate) fn small_lstsq(
    mmat: MatRef<'_, f64>,
    y: &[f64],
    tol_rows: usize,
) -> (Vec<f64>, Vec<usize>) {
    use faer::dyn_stack::{MemBuffer, MemStack};
    use faer::linalg::householder::{
        apply_block_householder_sequence_transpose_on_the_left_in_place_scratch,
        apply_block_householder_sequence_transpose_on_the_left_in_place_with_conj,
    };
    use faer::linalg::qr::col_pivoting::factor as cp;
    let (k, p) = mmat.shape();
    if p == 0 {
        return (Vec::new(), Vec::new());
    }
    let size = k.min(p);
    if size == 0 {
        return (vec![0.0; p], (0..p).collect());
    }
    if k >= p
        && let Some(x) = unpivoted_lstsq(mmat, y, tol_rows.max(k))
    {
        return (x, Vec::new());
    }
    let mut qr = mmat.to_owned();
    let bs = faer::linalg::qr::no_pivoting::factor::recommended_block_size::<f64>(k, p);
    let mut h = Mat::<f64>::zeros(bs, size);
    let mut fwd_buf = vec![0usize; p];
    let mut inv_buf = vec![0usize; p];
    let mut mem = MemBuffer::new(
        cp::qr_in_place_scratch::<usize, f64>(k, p, bs, Par::Seq, Default::default()).or(
            apply_block_householder_sequence_transpose_on_the_left_in_place_scratch::<f64>(
                k, bs, 1,
            ),
        ),
    );
    let (_, perm) = cp::qr_in_place(
        qr.as_mut(),
        h.as_mut(),
        &mut fwd_buf,
        &mut inv_buf,
        Par::Seq,
        MemStack::new(&mut mem),
        Default::default(),
    );
    let fwd: Vec<usize> = perm.arrays().0.to_vec();
    let r = qr.as_ref();
    let r00 = r[(0, 0)].abs();
    let tol = rank_tol(tol_rows.max(k), p) * r00;
    let rank = (0..size)
        .take_while(|&i| r00 > 0.0 && r[(i, i)].abs() > tol)
        .count();
    let mut rhs = Mat::<f64>::from_fn(k, 1, |i, _| y[i]);
    apply_block_householder_sequence_transpose_on_the_left_in_place_with_conj(
        r.get(.., ..size),
        h.as_ref(),
        faer::Conj::No,
        rhs.as_mut(),
        Par::Seq,
        MemStack::new(&mut mem),
    );
    let mut sol = rhs.get(..rank, ..).to_owned();
    solve_upper_triangular_in_place(r.get(..rank, ..rank), sol.as_mut(), Par::Seq);
    let mut x = vec![0.0; p];
    for i in 0..rank {
        x[fwd[i]] = sol[(i, 0)];
    }
    let mut dependent: Vec<usize> = fwd[rank..].to_vec();
    dependent.sort_unstable();
    (x, dependent)
}

/// How far above the pivoted QR's rank tolerance every diagonal entry of the unpivoted factor
/// must stay for [`unpivoted_lstsq`] to answer: a margin so wide that the pivoted factorisation
/// would find the same (full) rank.
const UNPIVOTED_MARGIN: f64 = 1e3;

/// The fast path of [`small_lstsq`] for a tall system of clearly full column rank: one
/// unpivoted QR of `[M | y]` gives `R` and `Qᵀy` together. `None` (use the pivoted QR) when some
/// `|R_kk|` comes within [`UNPIVOTED_MARGIN`] of the rank tolerance relative to the largest
/// column norm.
fn unpivoted_lstsq(mmat: MatRef<'_, f64>, y: &[f64], tol_rows: usize) -> Option<Vec<f64>> {
    use faer::dyn_stack::{MemBuffer, MemStack};
    use faer::linalg::qr::no_pivoting::factor as qf;
    let (k, p) = mmat.shape();
    let mut aug = Mat::<f64>::from_fn(k, p + 1, |i, j| if j < p { mmat[(i, j)] } else { y[i] });
    let norm_max = (0..p)
        .map(|j| mmat.col(j).squared_norm_l2())
        .fold(0.0_f64, f64::max)
        .sqrt();
    if norm_max == 0.0 {
        return None;
    }
    let size = k.min(p + 1);
    let bs = qf::recommended_block_size::<f64>(k, p + 1);
    let mut h = Mat::<f64>::zeros(bs, size);
    let mut mem = MemBuffer::new(qf::qr_in_place_scratch::<f64>(
        k,
        p + 1,
        bs,
        Par::Seq,
        Default::default(),
    ));
    qf::qr_in_place(
        aug.as_mut(),
        h.as_mut(),
        Par::Seq,
        MemStack::new(&mut mem),
        Default::default(),
    );
    let tol = UNPIVOTED_MARGIN * rank_tol(tol_rows, p) * norm_max;
    if (0..p).any(|i| aug[(i, i)].abs() <= tol) {
        return None;
    }
    let mut sol = Mat::<f64>::from_fn(p, 1, |i, _| aug[(i, p)]);
    solve_upper_triangular_in_place(aug.get(..p, ..p), sol.as_mut(), Par::Seq);
    Some((0..p).map(|i| sol[(i, 0)]).collect())
}

/// Ridge (λ ≥ 0) least squares on the columns `cols` of a compressed problem whose columns
/// are multiplied by `scale[j]` and right-hand side by `bscale`:
/// `min ‖R D x − c·bscale‖² + λ‖x‖²` with `D = diag(scale)` restricted to `cols`.
/// Returns the full-length `x` in the scaled units and dependent column indices (global).
pub(crate) fn subset_solve(
    p: &Compressed,
    cols: &[usize],
    scale: &[f64],
    bscale: f64,
    lambda: f64,
) -> (Vec<f64>, Vec<usize>) {
    let n = p.ncols();
    let s = cols.len();
    if lambda == 0.0
        && let Some(xs) = staircase_lstsq(p.r(), p.c(), cols, scale, bscale)
    {
        let mut x = vec![0.0; n];
        for (jj, &j) in cols.iter().enumerate() {
            x[j] = xs[jj];
        }
        return (x, Vec::new());
    }
    let extra = if lambda > 0.0 { s } else { 0 };
    // Rows of R below the last chosen column are zero in these columns: they only add
    // `Σ c_i²` to the residual, which does not move the solution.
    let top = cols.iter().map(|&j| j + 1).max().unwrap_or(0);
    let mut m = Mat::<f64>::zeros(top + extra, s);
    let r = p.r();
    for (jj, &j) in cols.iter().enumerate() {
        for i in 0..=j {
            m[(i, jj)] = r[(i, j)] * scale[j];
        }
        if lambda > 0.0 {
            m[(top + jj, jj)] = lambda.sqrt();
        }
    }
    let mut y: Vec<f64> = p.c()[..top].iter().map(|v| v * bscale).collect();
    y.resize(top + extra, 0.0);
    let (xs, dep) = small_lstsq(m.as_ref(), &y, n + extra);
    let mut x = vec![0.0; n];
    for (jj, &j) in cols.iter().enumerate() {
        x[j] = xs[jj];
    }
    (x, dep.into_iter().map(|jj| cols[jj]).collect())
}

/// Least squares on the columns `cols` (strictly increasing) of an upper-triangular `r`,
/// scaled by `scale[j]`, against `c·bscale`, when the subset has clearly full rank; `None` sends
/// the caller to the general [`small_lstsq`].
///
/// Column `j` of `r` is zero below row `j`, so `M = r[:, cols]` is a staircase: its column `k`
/// has only `cols[k] − k` entries below the diagonal, and a Householder reflection over those
/// rows alone triangularises it without fill-in (the reflection for column `k` mixes rows
/// `k..=cols[k]`, all inside the non-zero range of every later column). For the full support
/// `M` is already triangular and the solve is one back-substitution; a dense QR (as
/// `small_lstsq` does) would spend `2·top·s²` flops and an allocation per call re-discovering
/// zeros. This is the same backward-stable Householder QR restricted to the non-zero rows,
/// written out because faer has no structured (column-deleted) QR; the answer agrees with the
/// dense QR to rounding.
///
/// The rank test is [`unpivoted_lstsq`]'s: every `|R_kk|` must stay [`UNPIVOTED_MARGIN`] above
/// the pivoted QR's tolerance for a system of `r.nrows()` rows, relative to the largest scaled
/// column norm.
/// The Householder reflection `I − τ·u·uᵀ`, `u = [1; v]`, that maps the vector `[alpha; v]` to
/// `[beta; 0]` (LAPACK's sign convention: `beta` opposite to `alpha`). Overwrites `v` with the
/// tail of `u` and returns `(beta, τ)`; `None` when `v` is zero (nothing to reflect).
#[inline(always)]
pub(crate) fn householder(alpha: f64, v: &mut [f64]) -> Option<(f64, f64)> {
    let sigma = dot(v, v);
    if sigma == 0.0 {
        return None;
    }
    let norm = (alpha * alpha + sigma).sqrt();
    let beta = if alpha <= 0.0 { norm } else { -norm };
    let v0 = alpha - beta;
    for x in v.iter_mut() {
        *x /= v0;
    }
    Some((beta, -v0 / beta))
}

fn staircase_lstsq(
    r: MatRef<'_, f64>,
    c: &[f64],
    cols: &[usize],
    scale: &[f64],
    bscale: f64,
) -> Option<Vec<f64>> {
    let s = cols.len();
    if s == 0 || cols.windows(2).any(|w| w[1] <= w[0]) {
        return None;
    }
    let top = cols[s - 1] + 1;
    // Column-major working copy of the staircase and the right-hand side.
    let mut w = vec![0.0; top * s];
    let mut norm_max = 0.0_f64;
    for (k, &j) in cols.iter().enumerate() {
        let col = &mut w[k * top..k * top + j + 1];
        for (i, v) in col.iter_mut().enumerate() {
            *v = r[(i, j)] * scale[j];
        }
        norm_max = norm_max.max(col.iter().map(|v| v * v).sum::<f64>());
    }
    let norm_max = norm_max.sqrt();
    if norm_max == 0.0 || !norm_max.is_finite() {
        return None;
    }
    let mut y: Vec<f64> = c[..top].iter().map(|v| v * bscale).collect();
    for k in 0..s {
        let last = cols[k];
        if last == k {
            continue;
        }
        // Householder vector v (v_0 = 1 implicit) over rows k..=last of column k.
        let (head, tail) = w.split_at_mut((k + 1) * top);
        let colk = &mut head[k * top..];
        let alpha = colk[k];
        let Some((beta, tau)) = householder(alpha, &mut colk[k + 1..=last]) else {
            continue;
        };
        colk[k] = beta;
        let vk = &colk[k + 1..=last];
        let reflect = |x: &mut [f64]| {
            let d = x[k] + dot(vk, &x[k + 1..=last]);
            let t = tau * d;
            x[k] -= t;
            sub_scaled(&mut x[k + 1..=last], t, vk);
        };
        for jc in tail.chunks_exact_mut(top) {
            reflect(jc);
        }
        reflect(&mut y);
    }
    let tol = UNPIVOTED_MARGIN * rank_tol(r.nrows(), s) * norm_max;
    if (0..s).any(|k| w[k * top + k].abs() <= tol) {
        return None;
    }
    // Back-substitution on the leading s×s triangle, a column at a time (the column-major
    // triangle is read down its columns, not across them).
    let mut x = y[..s].to_vec();
    for k in (0..s).rev() {
        x[k] /= w[k * top + k];
        let xk = x[k];
        sub_scaled(&mut x[..k], xk, &w[k * top..k * top + k]);
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// Ordinary least squares on all columns (QR of the small factor, column-pivoted where the rank
/// is in doubt), with every column scaled to unit norm for the solve: the answer maps exactly
/// when a column is measured in other units.
///
/// Rank deficiency is not an error: numerically dependent columns get coefficient 0 and are
/// listed in [`Fit::dependent`] (a basic solution).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct LeastSquares;

impl Regressor for LeastSquares {
    fn fit_compressed(&self, p: &Compressed) -> Result<Fit> {
        let (x, dep) = equilibrated_solve(p, &vec![true; p.ncols()]);
        Fit::from_coef(p, x, dep, 1, true)
    }
}

/// Least squares on the columns of `support`, solved with every column and the target scaled
/// to unit norm and mapped back: the rank test then compares each column with its own size, so
/// the columns found dependent (and so the answer) do not change when a column is measured in
/// other units. Unscaled, a column 10¹⁵ times smaller than the largest (`x^7` of a displacement
/// in metres beside an acceleration in m/s²) fell below the rank tolerance and was dropped.
/// Zero columns are dependent.
fn equilibrated_solve(p: &Compressed, support: &[bool]) -> (Vec<f64>, Vec<usize>) {
    let (cs, bs) = crate::stlsq::scales(p, true);
    let cols: Vec<usize> = (0..p.ncols())
        .filter(|&j| support[j] && cs[j] != 0.0)
        .collect();
    let (mut x, mut dep) = subset_solve(p, &cols, &cs, bs, 0.0);
    for (j, v) in x.iter_mut().enumerate() {
        *v *= cs[j] / bs;
    }
    dep.extend((0..p.ncols()).filter(|&j| support[j] && cs[j] == 0.0));
    dep.sort_unstable();
    (x, dep)
}

/// Least squares on raw rows: `LeastSquares.fit(a, b)`.
pub fn lstsq(a: MatRef<'_, f64>, b: &[f64]) -> Result<Fit> {
    LeastSquares.fit(a, b)
}

/// Least squares restricted to a support (columns outside get 0), on a compressed problem, with
/// the columns scaled to unit norm for the solve (as [`LeastSquares`]).
pub fn lstsq_support(p: &Compressed, support: &[bool]) -> Result<Fit> {
    if support.len() != p.ncols() {
        return Err(crate::RegressError::DimensionMismatch {
            what: "length of support vs columns of the compressed problem".into(),
            expected: p.ncols(),
            found: support.len(),
        });
    }
    let (x, dep) = equilibrated_solve(p, support);
    Fit::from_coef(p, x, dep, 1, true)
}

/// Ridge regression `min ‖Aξ − b‖² + λ‖ξ‖²` in the raw column units (no scaling, no intercept),
/// solved as least squares on the stacked small system `[R; √λ I] ξ ≈ [c; 0]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ridge {
    /// Penalty λ ≥ 0 (λ = 0 is least squares).
    pub lambda: f64,
}

impl Regressor for Ridge {
    fn fit_compressed(&self, p: &Compressed) -> Result<Fit> {
        check_param(
            "Ridge.lambda",
            self.lambda,
            self.lambda >= 0.0,
            "must be finite and >= 0",
        )?;
        let n = p.ncols();
        let cols: Vec<usize> = (0..n).collect();
        let (x, dep) = subset_solve(p, &cols, &vec![1.0; n], 1.0, self.lambda);
        Fit::from_coef(p, x, dep, 1, true)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A compressed problem from `m` random rows with column scales spread over `spread`
    /// decades (so the staircase solves see realistic conditioning).
    fn problem(seed: u64, m: usize, n: usize, spread: f64) -> Compressed {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let scale: Vec<f64> = (0..n)
            .map(|j| 10f64.powf(spread * j as f64 / n.max(1) as f64))
            .collect();
        let a = Mat::<f64>::from_fn(m, n, |_, j| scale[j] * rng.random_range(-1.0..1.0));
        let b: Vec<f64> = (0..m).map(|_| rng.random_range(-1.0..1.0)).collect();
        Compressed::from_rows(a.as_ref(), &b).unwrap()
    }

    /// The dense route `subset_solve` takes when the staircase declines: `R[:, cols]` by QR.
    fn dense(p: &Compressed, cols: &[usize], scale: &[f64], bscale: f64) -> Vec<f64> {
        let top = cols.iter().map(|&j| j + 1).max().unwrap();
        let m = Mat::<f64>::from_fn(top, cols.len(), |i, k| p.r()[(i, cols[k])] * scale[cols[k]]);
        let y: Vec<f64> = p.c()[..top].iter().map(|v| v * bscale).collect();
        small_lstsq(m.as_ref(), &y, p.ncols()).0
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]

        /// The staircase Householder solve agrees with the dense QR on every increasing subset,
        /// scaled or not.
        #[test]
        fn staircase_matches_dense_qr(seed in 0u64..10_000, n in 1usize..30, spread in 0.0f64..4.0) {
            let p = problem(seed, 3 * n + 5, n, spread);
            let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5eed);
            let cols: Vec<usize> = (0..n).filter(|_| rng.random_bool(0.6)).collect();
            prop_assume!(!cols.is_empty());
            let scale: Vec<f64> = (0..n).map(|_| rng.random_range(0.1..10.0)).collect();
            let bscale = rng.random_range(0.1..10.0);
            let x = staircase_lstsq(p.r(), p.c(), &cols, &scale, bscale).expect("full rank");
            let want = dense(&p, &cols, &scale, bscale);
            let size = want.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            for (a, b) in x.iter().zip(&want) {
                prop_assert!((a - b).abs() <= 1e-9 * (1.0 + size), "{a} vs {b}");
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(32))]

        /// Least squares maps exactly when the columns and the target are measured in other
        /// units: a column scaled by `k_j` gets coefficient `ξ_j·g/k_j` with the target scaled
        /// by `g`, however far apart the scales (a column 10⁻²¹ the size of the others is not
        /// dependent). Scales outside 10^±40 would take the sums of squares out of range.
        #[test]
        fn least_squares_maps_exactly_under_column_scaling(
            seed in 0u64..10_000, n in 1usize..8, logk in proptest::collection::vec(-25.0f64..25.0, 8),
            logg in -10.0f64..10.0
        ) {
            let m = 4 * n + 10;
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let a = Mat::<f64>::from_fn(m, n, |_, _| rng.random_range(-1.0..1.0));
            let b: Vec<f64> = (0..m).map(|_| rng.random_range(-1.0..1.0)).collect();
            let k: Vec<f64> = logk[..n].iter().map(|l| 10f64.powf(*l)).collect();
            let g = 10f64.powf(logg);
            let scaled = Mat::<f64>::from_fn(m, n, |i, j| a[(i, j)] * k[j]);
            let bs: Vec<f64> = b.iter().map(|v| v * g).collect();
            let want = lstsq(a.as_ref(), &b).unwrap();
            let got = lstsq(scaled.as_ref(), &bs).unwrap();
            prop_assert!(got.dependent.is_empty(), "dependent {:?}", got.dependent);
            for (j, (c, w)) in got.coef.iter().zip(&want.coef).enumerate() {
                let back = c * k[j] / g;
                prop_assert!(
                    (back - w).abs() <= 1e-10 * w.abs().max(1e-3),
                    "column {j}: {back} vs {w}"
                );
            }
            let sup = vec![true; n];
            let c = Compressed::from_rows(scaled.as_ref(), &bs).unwrap();
            prop_assert_eq!(lstsq_support(&c, &sup).unwrap().coef, got.coef);
        }
    }

    /// The full support of a triangular factor needs no reflection: the answer is `R⁻¹c`.
    #[test]
    fn full_support_is_back_substitution() {
        let p = problem(3, 40, 6, 2.0);
        let cols: Vec<usize> = (0..6).collect();
        let x = staircase_lstsq(p.r(), p.c(), &cols, &[1.0; 6], 1.0).unwrap();
        let rx: Vec<f64> = (0..6)
            .map(|i| (i..6).map(|j| p.r()[(i, j)] * x[j]).sum())
            .collect();
        for (a, b) in rx.iter().zip(p.c()) {
            assert!((a - b).abs() < 1e-12 * (1.0 + b.abs()));
        }
    }

    /// A subset with a (numerically) dependent column is left to the pivoted QR, which reports
    /// it; unsorted or repeated columns are declined too.
    #[test]
    fn declines_rank_deficient_and_unsorted_subsets() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let m = 30;
        let a = Mat::<f64>::from_fn(m, 3, |_, _| rng.random_range(-1.0..1.0));
        let a = Mat::<f64>::from_fn(m, 4, |i, j| {
            if j < 3 {
                a[(i, j)]
            } else {
                a[(i, 0)] - 2.0 * a[(i, 2)]
            }
        });
        let b: Vec<f64> = (0..m).map(|_| rng.random_range(-1.0..1.0)).collect();
        let p = Compressed::from_rows(a.as_ref(), &b).unwrap();
        assert!(staircase_lstsq(p.r(), p.c(), &[0, 2, 3], &[1.0; 4], 1.0).is_none());
        let (_, dep) = subset_solve(&p, &[0, 2, 3], &[1.0; 4], 1.0, 0.0);
        assert_eq!(dep.len(), 1, "the pivoted QR names one dependent column");
        assert!(staircase_lstsq(p.r(), p.c(), &[2, 0], &[1.0; 4], 1.0).is_none());
        assert!(staircase_lstsq(p.r(), p.c(), &[0, 0], &[1.0; 4], 1.0).is_none());
        assert!(staircase_lstsq(p.r(), p.c(), &[0, 1], &[1.0; 4], 1.0).is_some());
    }
}
