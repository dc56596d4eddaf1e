//! Compression of a tall least-squares problem into its small triangular factor.
//!
//! For `A` (m×n) and `b` (m), one thin QR of the augmented matrix `[A | b]` gives an
//! upper-triangular `(n+1)×(n+1)` factor
//! `[[R, c], [0, ρ]]` with `‖Aξ − b‖² = ‖Rξ − c‖² + ρ²` for every `ξ`.
//! Everything in this crate works on that small factor, so the m-row decomposition is done once.
//! New rows and other blocks' factors are zeroed into an existing factor by Householder
//! reflections that keep its triangular structure (see [`Compressed::append`]).

use crate::absorb::absorb_rows;
use crate::error::{RegressError, Result};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::qr::no_pivoting::factor as qr_factor;
use faer::{ColRef, Mat, MatMut, MatRef, Par};

/// Rows per chunk when compressing (keeps each QR's working set in cache).
pub(crate) const CHUNK_ROWS: usize = 2048;

/// A least-squares problem `min ‖Aξ − b‖²` reduced to its triangular factor.
///
/// Invariant: `‖Aξ − b‖² = ‖Rξ − c‖² + rss0` for every `ξ`, where `A`, `b` are all rows
/// ever added. `R` is `n×n` upper triangular, `c = Qᵀb` (length `n`), `rss0 ≥ 0` is the
/// residual sum of squares of the full least-squares solution and `m` the number of rows.
#[derive(Debug, Clone, PartialEq)]
pub struct Compressed {
    r: Mat<f64>,
    c: Vec<f64>,
    rss0: f64,
    m: usize,
}

/// Whether every value is finite: a fold without early exit, which vectorises (the common case
/// is a clean column; where it is not, the caller looks for the entry).
fn all_finite(v: &[f64]) -> bool {
    v.iter().fold(true, |ok, x| ok & x.is_finite())
}

/// Check every entry of `a` and `b` is finite and sizes agree.
pub(crate) fn check_rows(a: MatRef<'_, f64>, b: &[f64]) -> Result<()> {
    if a.nrows() != b.len() {
        return Err(RegressError::DimensionMismatch {
            what: "length of b (right-hand side) vs rows of A".into(),
            expected: a.nrows(),
            found: b.len(),
        });
    }
    for j in 0..a.ncols() {
        let col = a.col(j);
        // A contiguous column is scanned as a slice (vectorised); a strided one entry by entry.
        let bad = match col.try_as_col_major() {
            Some(c) if all_finite(c.as_slice()) => None,
            Some(c) => c.as_slice().iter().position(|v| !v.is_finite()),
            None => (0..a.nrows()).find(|&i| !col[i].is_finite()),
        };
        if let Some(i) = bad {
            return Err(RegressError::NonFinite {
                what: "A",
                row: i,
                col: j,
                value: col[i],
            });
        }
    }
    if let Some((i, &v)) = b.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(RegressError::NonFinite {
            what: "b",
            row: i,
            col: 0,
            value: v,
        });
    }
    Ok(())
}

/// Checks that every entry of a chunk `[A | b]` of rows `start..` is finite (the last column is
/// `b`); the error counts rows from the first row of the whole problem.
fn check_chunk(chunk: MatRef<'_, f64>, start: usize) -> Result<()> {
    let n = chunk.ncols() - 1;
    for j in 0..=n {
        let col = chunk.col(j);
        if col
            .try_as_col_major()
            .is_some_and(|c| all_finite(c.as_slice()))
        {
            continue;
        }
        if let Some(i) = (0..chunk.nrows()).find(|&i| !col[i].is_finite()) {
            return Err(RegressError::NonFinite {
                what: if j < n { "A" } else { "b" },
                row: start + i,
                col: if j < n { j } else { 0 },
                value: col[i],
            });
        }
    }
    Ok(())
}

/// QR of an augmented `k×(n+1)` matrix in place; returns the `(n+1)×(n+1)` upper factor.
fn triangular_factor(mut aug: Mat<f64>) -> Mat<f64> {
    let (k, n1) = aug.shape();
    let mut out = Mat::<f64>::zeros(n1, n1);
    let size = k.min(n1);
    if size == 0 {
        return out;
    }
    let par = Par::Seq;
    let bs = qr_factor::recommended_block_size::<f64>(k, n1);
    let mut q_coeff = Mat::<f64>::zeros(bs, size);
    let mut buf = MemBuffer::new(qr_factor::qr_in_place_scratch::<f64>(
        k,
        n1,
        bs,
        par,
        Default::default(),
    ));
    qr_factor::qr_in_place(
        aug.as_mut(),
        q_coeff.as_mut(),
        par,
        MemStack::new(&mut buf),
        Default::default(),
    );
    for j in 0..n1 {
        for i in 0..=j.min(size - 1) {
            out[(i, j)] = aug[(i, j)];
        }
    }
    out
}

/// Rows per chunk up to which [`Compressed::append`] zeroes new rows into the current factor
/// with [`absorb_rows`](crate::absorb::absorb_rows) (~2(k+1)n² flops for `k` rows) instead of one dense QR of the stacked
/// `(n+1+k)×(n+1)` matrix (~2(n+k)n² − ⅔n³, blocked): every chunk. Measured for 39 columns: the
/// structured update is 10× faster for 2 rows, 2.5× for 64 and 1.2× for 512; from 96 rows it
/// applies its reflections a panel at a time (a panel of reflections at a time), and faer's dense QR
/// spent three quarters of its time in its overflow-safe Householder norms.
const ABSORB_MAX_ROWS: usize = CHUNK_ROWS;

impl Compressed {
    /// The compression of zero rows with `n` columns (the neutral element of [`Compressed::merge`]).
    pub fn empty(n: usize) -> Self {
        Self {
            r: Mat::zeros(n, n),
            c: vec![0.0; n],
            rss0: 0.0,
            m: 0,
        }
    }

    /// Compress the rows `(A, b)` with one thin QR of `[A | b]`.
    ///
    /// Errors: `b.len() != A.nrows()`, `A` with no columns, or any non-finite entry (the
    /// error names the row and column).
    pub fn from_rows(a: MatRef<'_, f64>, b: &[f64]) -> Result<Self> {
        if a.ncols() == 0 {
            return Err(RegressError::Empty {
                what: "A has no columns; give at least one library column",
            });
        }
        check_rows(a, b)?;
        let mut out = Self::empty(a.ncols());
        out.append_unchecked(a, b);
        Ok(out)
    }

    /// Build from an `(n+1)×(n+1)` upper factor of `[A | b]`.
    fn from_factor(f: Mat<f64>, m: usize) -> Self {
        let n = f.nrows() - 1;
        let r = f.as_ref().get(..n, ..n).to_owned();
        let c = (0..n).map(|i| f[(i, n)]).collect();
        let rho = f[(n, n)];
        Self {
            r,
            c,
            rss0: rho * rho,
            m,
        }
    }

    /// The `(n+1)×(n+1)` augmented factor `[[R, c], [0, √rss0]]`, scaled by `w`.
    fn augmented(&self, w: f64) -> Mat<f64> {
        let n = self.ncols();
        let mut f = Mat::<f64>::zeros(n + 1, n + 1);
        for j in 0..n {
            for i in 0..=j {
                f[(i, j)] = w * self.r[(i, j)];
            }
        }
        for i in 0..n {
            f[(i, n)] = w * self.c[i];
        }
        f[(n, n)] = w * self.rss0.sqrt();
        f
    }

    /// Write the top `h` rows of [`Compressed::augmented`]`(w)` into the column-major buffer
    /// `buf` (leading dimension `ld`) starting at row `row0`.
    fn write_augmented(&self, w: f64, h: usize, buf: &mut [f64], ld: usize, row0: usize) {
        let n = self.ncols();
        for j in 0..n {
            let col = &mut buf[j * ld + row0..j * ld + row0 + h];
            for (i, v) in col.iter_mut().enumerate() {
                *v = if i <= j { w * self.r[(i, j)] } else { 0.0 };
            }
        }
        let col = &mut buf[n * ld + row0..n * ld + row0 + h];
        for (i, v) in col.iter_mut().enumerate() {
            *v = if i < n {
                w * self.c[i]
            } else {
                w * self.rss0.sqrt()
            };
        }
    }

    /// The compression whose augmented factor is rows `0..n1` of the column-major buffer `buf`
    /// (leading dimension `ld`), of `m` original rows.
    fn from_buffer(buf: &[f64], n1: usize, ld: usize, m: usize) -> Self {
        let n = n1 - 1;
        let r = Mat::from_fn(n, n, |i, j| if i <= j { buf[j * ld + i] } else { 0.0 });
        let c = (0..n).map(|i| buf[n * ld + i]).collect();
        let rho = buf[n * ld + n];
        Self {
            r,
            c,
            rss0: rho * rho,
            m,
        }
    }

    /// Add more rows `(A, b)` without revisiting the rows already compressed.
    ///
    /// Up to 2,048 rows at a time are zeroed into the current factor with one Householder
    /// reflection per column (~2(k+1)n² flops for `k` rows), applied a panel of columns at a
    /// time for tall chunks; input whose sums of squares could overflow goes through a dense QR
    /// of the factor stacked on the chunk.
    pub fn append(&mut self, a: MatRef<'_, f64>, b: &[f64]) -> Result<()> {
        let n = self.ncols();
        if a.ncols() != n {
            return Err(RegressError::DimensionMismatch {
                what: "columns of appended A vs columns of the compressed problem".into(),
                expected: n,
                found: a.ncols(),
            });
        }
        check_rows(a, b)?;
        self.append_unchecked(a, b);
        Ok(())
    }

    /// Append rows in cache-sized chunks (see [`Compressed::append_with`]), copied from `(A, b)`.
    fn append_unchecked(&mut self, a: MatRef<'_, f64>, b: &[f64]) {
        let n = self.ncols();
        let fill = |start: usize, mut chunk: MatMut<'_, f64>| -> Result<()> {
            let k = chunk.nrows();
            chunk
                .as_mut()
                .get_mut(.., ..n)
                .copy_from(a.subrows(start, k));
            chunk
                .col_mut(n)
                .copy_from(ColRef::from_slice(&b[start..start + k]));
            Ok(())
        };
        // The rows were checked by the caller; a copy cannot fail.
        let _ = self.append_with(a.nrows(), false, fill);
    }

    /// Compresses `m` rows that `fill` writes a chunk at a time, so that the rows never exist
    /// all at once (a library built straight into its compression): `fill(start, chunk)` writes
    /// rows `start..start + k` of `[A | b]` into the `k × (n+1)` view `chunk` (columns `0..n`
    /// of `A`, then `b`). A chunk may be asked for twice (when its entries are too large or
    /// too small for the structured update, it is stacked and factored again), and must then
    /// be written the same. Same factor, to the bit, as [`Compressed::from_rows`] of the rows
    /// stacked.
    ///
    /// Errors: `n = 0`; an error of `fill`; a non-finite entry (row counted from the first
    /// row, column `n` meaning `b`), found chunk by chunk before that chunk is compressed.
    pub fn from_chunks<E: From<RegressError>>(
        n: usize,
        m: usize,
        fill: impl FnMut(usize, MatMut<'_, f64>) -> std::result::Result<(), E>,
    ) -> std::result::Result<Self, E> {
        if n == 0 {
            return Err(RegressError::Empty {
                what: "A has no columns; give at least one library column",
            }
            .into());
        }
        let mut out = Self::empty(n);
        out.append_with(m, true, fill)?;
        Ok(out)
    }

    /// Appends `total` rows in cache-sized chunks written by `fill` (as in
    /// [`Compressed::from_chunks`]; a sequential TSQR, so the m-row data is read once and every
    /// update works in cache): each chunk is zeroed into the current factor by [`absorb_rows`],
    /// or (entries it declines, or fewer rows in all than columns) stacked under it and
    /// re-factored by a dense QR. With `check`, each chunk's entries must be finite.
    fn append_with<E: From<RegressError>>(
        &mut self,
        total: usize,
        check: bool,
        mut fill: impl FnMut(usize, MatMut<'_, f64>) -> std::result::Result<(), E>,
    ) -> std::result::Result<(), E> {
        let n = self.ncols();
        let n1 = n + 1;
        // One buffer for every chunk: a fresh one each time (600 kB for 36 columns) cost more
        // in page faults and zeroing than the chunk's reflections.
        let mut buf: Vec<f64> = Vec::new();
        let mut start = 0;
        while start < total {
            let k = CHUNK_ROWS.min(total - start);
            // Fewer rows in all than n+1: the factor has only that many rows, which the dense
            // QR gives directly (the reflections of the later columns would scatter rounding —
            // or, for rank-deficient rows, more — into rows that `merge` then drops).
            let mut checked = false;
            if k <= ABSORB_MAX_ROWS && self.m + k > n {
                let ld = n1 + k;
                if buf.len() < ld * n1 {
                    buf.resize(ld * n1, 0.0);
                }
                let w = &mut buf[..ld * n1];
                self.write_augmented(1.0, n1, w, ld, 0);
                let chunk =
                    MatMut::from_column_major_slice_with_stride_mut(&mut w[n1..], k, n1, ld);
                fill(start, chunk)?;
                if check {
                    let chunk = MatRef::from_column_major_slice_with_stride(&w[n1..], k, n1, ld);
                    check_chunk(chunk, start)?;
                    checked = true;
                }
                if absorb_rows(w, n1, ld, k, false) {
                    *self = Self::from_buffer(w, n1, ld, self.m + k);
                    start += k;
                    continue;
                }
            }
            let mut aug = Mat::<f64>::zeros(n1 + k, n1);
            aug.as_mut()
                .get_mut(..n1, ..)
                .copy_from(self.augmented(1.0));
            fill(start, aug.as_mut().get_mut(n1.., ..))?;
            if check && !checked {
                check_chunk(aug.as_ref().get(n1.., ..), start)?;
            }
            *self = Self::from_factor(triangular_factor(aug), self.m + k);
            start += k;
        }
        Ok(())
    }

    /// The compression of all rows of several blocks stacked (blocks with equal column counts).
    ///
    /// Equal to `from_rows` of the stacked rows up to the signs of R's rows.
    pub fn merge(blocks: &[Compressed]) -> Result<Self> {
        let weighted: Vec<(&Compressed, usize)> = blocks.iter().map(|b| (b, 1)).collect();
        Self::merge_counted(&weighted)
    }

    /// Merge blocks where block `i` is counted `k_i` times (its rows repeated `k_i` times).
    /// This is what a bootstrap resample of blocks needs; blocks with count 0 are skipped.
    pub fn merge_counted(blocks: &[(&Compressed, usize)]) -> Result<Self> {
        let Some((first, _)) = blocks.first() else {
            return Err(RegressError::Empty {
                what: "no blocks to merge; pass at least one compressed block",
            });
        };
        let n = first.ncols();
        for (b, _) in blocks {
            if b.ncols() != n {
                return Err(RegressError::DimensionMismatch {
                    what: "columns of a merged block vs the first block".into(),
                    expected: n,
                    found: b.ncols(),
                });
            }
        }
        let used: Vec<_> = blocks.iter().filter(|(_, k)| *k > 0).collect();
        if used.is_empty() {
            return Ok(Self::empty(n));
        }
        if let Some(f) = Self::merge_structured(&used, n) {
            return Ok(f);
        }
        // Only each block's `factor_rows` are stacked: the rest are zero.
        let total: usize = used.iter().map(|(b, _)| b.factor_rows()).sum();
        let mut aug = Mat::<f64>::zeros(total.max(1), n + 1);
        let mut m = 0;
        let mut row = 0;
        for (b, k) in &used {
            let h = b.factor_rows();
            aug.as_mut()
                .get_mut(row..row + h, ..)
                .copy_from(b.augmented((*k as f64).sqrt()).get(..h, ..));
            row += h;
            m += b.m * k;
        }
        Ok(Self::from_factor(triangular_factor(aug), m))
    }

    /// [`Compressed::merge_counted`] by absorbing each further block's factor into the first
    /// one's with [`absorb_rows`] (the blocks' triangular structure kept: ~⅔n³ per block instead
    /// of a dense QR of every factor stacked). `None` where [`absorb_rows`] declines.
    fn merge_structured(used: &[&(&Compressed, usize)], n: usize) -> Option<Self> {
        let n1 = n + 1;
        let (first, k0) = used[0];
        // As in `append_unchecked`: fewer rows than n+1 in all go to the dense QR.
        if used.iter().map(|(b, k)| b.m * k).sum::<usize>() < n1 {
            return None;
        }
        let hmax = used[1..]
            .iter()
            .map(|(b, _)| b.factor_rows())
            .max()
            .unwrap_or(0);
        let ld = n1 + hmax;
        let mut buf = vec![0.0; ld * n1];
        first.write_augmented((*k0 as f64).sqrt(), n1, &mut buf, ld, 0);
        let mut m = first.m * k0;
        for (b, k) in &used[1..] {
            let h = b.factor_rows();
            b.write_augmented((*k as f64).sqrt(), h, &mut buf, ld, n1);
            if !absorb_rows(&mut buf, n1, ld, h, true) {
                return None;
            }
            m += b.m * k;
        }
        Some(Self::from_buffer(&buf, n1, ld, m))
    }

    /// Rows of the augmented factor that can be non-zero: a block of fewer than n+1 rows has a
    /// factor with only that many, so merging stacks just those.
    fn factor_rows(&self) -> usize {
        self.m.min(self.ncols() + 1)
    }

    /// Number of columns `n`.
    pub fn ncols(&self) -> usize {
        self.c.len()
    }

    /// Number of original rows `m` compressed so far.
    pub fn nrows(&self) -> usize {
        self.m
    }

    /// The `n×n` upper-triangular factor `R`.
    pub fn r(&self) -> MatRef<'_, f64> {
        self.r.as_ref()
    }

    /// `c = Qᵀb` (length `n`).
    pub fn c(&self) -> &[f64] {
        &self.c
    }

    /// Residual sum of squares of the full least-squares fit (`‖Aξ − b‖²` at its minimum).
    pub fn rss0(&self) -> f64 {
        self.rss0
    }

    /// `‖b‖² = ‖c‖² + rss0`.
    pub fn b_norm2(&self) -> f64 {
        self.c.iter().map(|v| v * v).sum::<f64>() + self.rss0
    }

    /// Euclidean norms of the columns of `A` (`‖A[:,j]‖ = ‖R[:,j]‖`).
    pub fn column_norms(&self) -> Vec<f64> {
        (0..self.ncols())
            .map(|j| (0..=j).map(|i| self.r[(i, j)].powi(2)).sum::<f64>().sqrt())
            .collect()
    }

    /// `‖Aξ − b‖²` for a coefficient vector `ξ`, evaluated on the small factor.
    pub fn rss(&self, coef: &[f64]) -> Result<f64> {
        let n = self.ncols();
        if coef.len() != n {
            return Err(RegressError::DimensionMismatch {
                what: "length of coef vs columns of the compressed problem".into(),
                expected: n,
                found: coef.len(),
            });
        }
        if let Some((i, &v)) = coef.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(RegressError::NonFinite {
                what: "coef",
                row: i,
                col: 0,
                value: v,
            });
        }
        let mut s = self.rss0;
        for i in 0..n {
            let mut ri = -self.c[i];
            for (j, &x) in coef.iter().enumerate().skip(i) {
                ri += self.r[(i, j)] * x;
            }
            s += ri * ri;
        }
        Ok(s)
    }

    /// Gram matrix `G = AᵀA = RᵀR` and `q = Aᵀb = Rᵀc`.
    pub fn gram(&self) -> (Mat<f64>, Vec<f64>) {
        let n = self.ncols();
        let g = self.r.transpose() * &self.r;
        let q = (0..n)
            .map(|j| (0..=j).map(|i| self.r[(i, j)] * self.c[i]).sum())
            .collect();
        (g, q)
    }
}

/// Many [`Compressed::merge_counted`] calls over the same blocks with different counts (a
/// bootstrap), each at the cost of a weighted sum of small matrices and one Cholesky
/// factorisation instead of a QR of every stacked block.
///
/// With `F` the augmented factor of all blocks merged once and `B_g` that of block `g`, the
/// blocks are mapped into the coordinates where the merged problem is the identity:
/// `H_g = F⁻ᵀ B_gᵀ B_g F⁻¹`, `Σ_g H_g = I`. A resample with counts `k_g` has the Gram matrix
/// `Fᵀ (Σ_g k_g H_g) F`; `Σ k_g H_g` is well conditioned whenever the resample determines every
/// coefficient (its eigenvalues are the resample's weight on each direction relative to the
/// whole), so its Cholesky factor `L` is accurate and `Lᵀ F` is the resample's factor, a
/// left-multiplicative perturbation of the exact one of relative size ~ε·cond(Σ k_g H_g).
/// Where `F` is (numerically) singular, or `Σ k_g H_g` is not positive definite or has a
/// condition number beyond ~1e8, the exact stacked QR is used instead.
pub(crate) struct CountedMerge<'a> {
    blocks: &'a [Compressed],
    /// `F` and every `H_g`; `None` when `F` cannot be inverted safely.
    whitened: Option<(Mat<f64>, Vec<Mat<f64>>)>,
}

impl<'a> CountedMerge<'a> {
    /// Prepare for resampling `blocks` (equal column counts, at least one block).
    #[cfg(test)]
    pub(crate) fn new(blocks: &'a [Compressed]) -> Result<Self> {
        Self::with_total(blocks, &Compressed::merge(blocks)?)
    }

    /// Prepare for resampling `blocks` (equal column counts, at least one block) whose merge
    /// `full` (`Compressed::merge(blocks)`) is already at hand. The blocks are whitened in
    /// parallel (a triangular solve and a product each, tens of blocks).
    pub(crate) fn with_total(blocks: &'a [Compressed], full: &Compressed) -> Result<Self> {
        use rayon::prelude::*;
        if let Some(b) = blocks.iter().find(|b| b.ncols() != full.ncols()) {
            return Err(RegressError::DimensionMismatch {
                what: "columns of a resampled block vs the merge of all blocks".into(),
                expected: full.ncols(),
                found: b.ncols(),
            });
        }
        let n1 = full.ncols() + 1;
        let f = full.augmented(1.0);
        // Each column must add a direction of its own: |F_jj| against the column's norm.
        let invertible = (0..n1).all(|j| {
            let norm = (0..=j).map(|i| f[(i, j)].powi(2)).sum::<f64>().sqrt();
            f[(j, j)].abs() > 1e-10 * norm && norm > 0.0
        });
        let whitened = invertible.then(|| {
            let h = blocks
                .par_iter()
                .with_max_len(1)
                .map(|b| {
                    let rows = b.factor_rows();
                    // Xᵀ = F⁻ᵀ B_gᵀ, then H_g = XᵀX.
                    let mut xt = b.augmented(1.0).get(..rows, ..).transpose().to_owned();
                    faer::linalg::triangular_solve::solve_lower_triangular_in_place(
                        f.transpose(),
                        xt.as_mut(),
                        Par::Seq,
                    );
                    &xt * xt.transpose()
                })
                .collect();
            (f, h)
        });
        Ok(Self { blocks, whitened })
    }

    /// The blocks merged with block `g` counted `counts[g]` times (see
    /// [`Compressed::merge_counted`]).
    pub(crate) fn merge(&self, counts: &[usize]) -> Result<Compressed> {
        match self.whitened_merge(counts) {
            Some(c) => Ok(c),
            None => {
                let pairs: Vec<(&Compressed, usize)> =
                    self.blocks.iter().zip(counts.iter().copied()).collect();
                Compressed::merge_counted(&pairs)
            }
        }
    }

    /// The fast path of [`CountedMerge::merge`]; `None` where it would not be accurate.
    fn whitened_merge(&self, counts: &[usize]) -> Option<Compressed> {
        let m: usize = self.blocks.iter().zip(counts).map(|(b, &k)| b.m * k).sum();
        let (f, h) = self.whitened.as_ref()?;
        let n1 = f.nrows();
        // Σ k_g H_g entry by entry: the blocks are many and small, and a matrix expression per
        // block (a temporary and a dispatch each) cost more than the sums themselves.
        let mut g = Mat::<f64>::zeros(n1, n1);
        for (hg, &k) in h.iter().zip(counts) {
            if k > 0 {
                let kf = k as f64;
                for j in 0..n1 {
                    for (gv, hv) in g.col_as_slice_mut(j).iter_mut().zip(hg.col_as_slice(j)) {
                        *gv += kf * hv;
                    }
                }
            }
        }
        // The diagonal of L bounds cond(Σ k_g H_g) from below; beyond 1e8 the perturbation
        // ε·cond would start to show, and the exact QR is used.
        let llt = g.llt(faer::Side::Lower).ok()?;
        let d: Vec<f64> = (0..n1).map(|j| llt.L()[(j, j)].powi(2)).collect();
        let (lo, hi) = d.iter().fold((f64::INFINITY, 0.0_f64), |(lo, hi), &v| {
            (lo.min(v), hi.max(v))
        });
        if lo <= 1e-8 * hi {
            return None;
        }
        let mut fb = llt.L().transpose() * f;
        // Exactly upper triangular (the product of two upper-triangular factors).
        for j in 0..n1 {
            for i in j + 1..n1 {
                fb[(i, j)] = 0.0;
            }
        }
        Some(Compressed::from_factor(fb, m))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::lstsq_support;

    /// Blocks of 12 rows of an ill-conditioned monomial design (1, x, …, x⁷ on x ∈ [0, 2]);
    /// block `g` covers its own stretch of x, so a resample that leaves out many blocks
    /// changes the conditioning a lot.
    fn monomial_blocks(nblocks: usize) -> Vec<Compressed> {
        (0..nblocks)
            .map(|g| {
                let rows = 12;
                let a = Mat::<f64>::from_fn(rows, 8, |i, j| {
                    let x = 2.0 * (g * rows + i) as f64 / (nblocks * rows) as f64;
                    x.powi(j as i32)
                });
                // A smooth right-hand side plus a deterministic "noise".
                let b: Vec<f64> = (0..rows)
                    .map(|i| {
                        let x = a[(i, 1)];
                        (3.0 * x).sin() + 1e-3 * ((7 * (g * rows + i)) as f64).cos()
                    })
                    .collect();
                Compressed::from_rows(a.as_ref(), &b).unwrap()
            })
            .collect()
    }

    fn coef(p: &Compressed) -> Vec<f64> {
        lstsq_support(p, &vec![true; p.ncols()]).unwrap().coef
    }

    /// The whitened resampling agrees with the exact stacked QR to far better than any
    /// bootstrap needs, on a design whose condition number is ~1e7.
    #[test]
    fn counted_merge_matches_stacked_qr() {
        let blocks = monomial_blocks(40);
        let merger = CountedMerge::new(&blocks).unwrap();
        assert!(merger.whitened.is_some(), "the fast path must be taken");
        let mut state = 12345u64;
        for _ in 0..20 {
            let mut counts = vec![0usize; blocks.len()];
            for _ in 0..blocks.len() {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                counts[(state >> 33) as usize % blocks.len()] += 1;
            }
            let fast = merger
                .whitened_merge(&counts)
                .expect("a resample of 40 blocks is well conditioned: the fast path answers");
            let pairs: Vec<(&Compressed, usize)> =
                blocks.iter().zip(counts.iter().copied()).collect();
            let exact = Compressed::merge_counted(&pairs).unwrap();
            assert_eq!(fast.nrows(), exact.nrows());
            assert!((fast.rss0() - exact.rss0()).abs() <= 1e-8 * exact.b_norm2());
            let (cf, ce) = (coef(&fast), coef(&exact));
            let scale = ce.iter().map(|v| v.abs()).fold(0.0, f64::max);
            for (a, b) in cf.iter().zip(&ce) {
                assert!((a - b).abs() <= 1e-6 * scale, "{cf:?} vs {ce:?}");
            }
        }
    }

    /// A resample that keeps too few blocks to determine the coefficients falls back to the
    /// exact QR instead of returning a wrong factor.
    #[test]
    fn counted_merge_falls_back_when_the_resample_is_rank_deficient() {
        let blocks = monomial_blocks(10);
        let merger = CountedMerge::new(&blocks).unwrap();
        let mut counts = vec![0usize; blocks.len()];
        counts[3] = 10;
        // One block of 12 rows over a tenth of the x range: the whitened Gram matrix of this
        // resample is far too ill-conditioned for the fast path.
        let (_, h) = merger.whitened.as_ref().unwrap();
        let mut g = Mat::<f64>::zeros(9, 9);
        g += faer::Scale(10.0) * &h[3];
        let ev = g.self_adjoint_eigenvalues(faer::Side::Lower).unwrap();
        assert!(ev[0] < 1e-8 * ev[8], "{ev:?}");
        assert!(merger.whitened_merge(&counts).is_none());
        let fast = merger.merge(&counts).unwrap();
        let exact = Compressed::merge_counted(&[(&blocks[3], 10)]).unwrap();
        assert_eq!(coef(&fast), coef(&exact));
        assert_eq!(fast.nrows(), exact.nrows());
        let (gf, _) = fast.gram();
        let (ge, _) = exact.gram();
        let scale = ge[(7, 7)].abs();
        for i in 0..8 {
            for j in 0..8 {
                assert!((gf[(i, j)] - ge[(i, j)]).abs() <= 1e-9 * scale);
            }
        }
    }

    /// Entries whose squares could overflow make the structured update decline, and `append`
    /// and `merge` then take the dense QR (norms scaled) and stay exact.
    #[test]
    fn huge_entries_take_the_dense_qr() {
        let big = 1e150;
        let a = Mat::<f64>::from_fn(12, 3, |i, j| {
            let v = ((i * 3 + j) as f64 * 0.71).sin() + if i == j { 2.0 } else { 0.0 };
            if j == 2 { big * v } else { v }
        });
        let b: Vec<f64> = (0..12).map(|i| (i as f64 * 0.3).cos()).collect();
        let mut buf = vec![0.0; 16 * 4];
        for j in 0..3 {
            for i in 0..12 {
                buf[j * 16 + 4 + i] = a[(i, j)];
            }
        }
        assert!(!absorb_rows(&mut buf, 4, 16, 12, false));
        let mut p = Compressed::from_rows(a.as_ref().subrows(0, 6), &b[..6]).unwrap();
        p.append(a.as_ref().subrows(6, 6), &b[6..]).unwrap();
        let q = Compressed::merge(&[
            Compressed::from_rows(a.as_ref().subrows(0, 6), &b[..6]).unwrap(),
            Compressed::from_rows(a.as_ref().subrows(6, 6), &b[6..]).unwrap(),
        ])
        .unwrap();
        let x = [0.5, -1.0, 2.0 / big];
        let direct: f64 = (0..12)
            .map(|i| {
                let r: f64 = (0..3).map(|j| a[(i, j)] * x[j]).sum::<f64>() - b[i];
                r * r
            })
            .sum();
        for c in [&p, &q] {
            assert!((c.rss(&x).unwrap() - direct).abs() <= 1e-10 * direct);
        }
    }

    /// Blocks with fewer rows than columns are stacked by their non-zero rows only.
    #[test]
    fn merge_of_short_blocks_equals_stacked_rows() {
        let a = Mat::<f64>::from_fn(9, 5, |i, j| ((i * 5 + j) as f64 * 0.37).sin());
        let b: Vec<f64> = (0..9).map(|i| (i as f64).cos()).collect();
        let all = Compressed::from_rows(a.as_ref(), &b).unwrap();
        let parts: Vec<Compressed> = (0..3)
            .map(|k| {
                Compressed::from_rows(a.as_ref().subrows(3 * k, 3), &b[3 * k..3 * k + 3]).unwrap()
            })
            .collect();
        let merged = Compressed::merge(&parts).unwrap();
        assert_eq!(merged.nrows(), 9);
        let x = [0.3, -1.0, 2.0, 0.5, -0.25];
        assert!((merged.rss(&x).unwrap() - all.rss(&x).unwrap()).abs() < 1e-12);
    }
}
