//! Compression of a tall least-squares problem into its small triangular factor.
//!
//! For `A` (m×n) and `b` (m), one thin QR of the augmented matrix `[A | b]` gives an
//! upper-triangular `(n+1)×(n+1)` factor
//! `[[R, c], [0, ρ]]` with `‖Aξ − b‖² = ‖Rξ − c‖² + ρ²` for every `ξ`.
//! Everything in this crate works on that small factor, so the m-row decomposition is done once.

use crate::error::{RegressError, Result};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::qr::no_pivoting::factor as qr_factor;
use faer::{Mat, MatRef, Par};

/// Rows per chunk when compressing (keeps each QR's working set in cache).
const CHUNK_ROWS: usize = 2048;

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
        for i in 0..a.nrows() {
            let v = a[(i, j)];
            if !v.is_finite() {
                return Err(RegressError::NonFinite {
                    what: "A",
                    row: i,
                    col: j,
                    value: v,
                });
            }
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

    /// Add more rows `(A, b)` without revisiting the rows already compressed.
    ///
    /// Cost is one QR of an `(n+1+k)×(n+1)` matrix for `k` new rows.
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

    /// Append rows in cache-sized chunks: each chunk is stacked under the current
    /// `(n+1)×(n+1)` factor and re-factored (a sequential TSQR), so the m-row data is read
    /// once and every QR works in cache.
    fn append_unchecked(&mut self, a: MatRef<'_, f64>, b: &[f64]) {
        let n = self.ncols();
        let total = a.nrows();
        let mut start = 0;
        while start < total {
            let k = CHUNK_ROWS.min(total - start);
            let mut aug = Mat::<f64>::zeros(n + 1 + k, n + 1);
            aug.as_mut()
                .get_mut(..n + 1, ..)
                .copy_from(self.augmented(1.0));
            aug.as_mut()
                .get_mut(n + 1.., ..n)
                .copy_from(a.subrows(start, k));
            for (i, &v) in b[start..start + k].iter().enumerate() {
                aug[(n + 1 + i, n)] = v;
            }
            *self = Self::from_factor(triangular_factor(aug), self.m + k);
            start += k;
        }
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
        let mut aug = Mat::<f64>::zeros(used.len() * (n + 1), n + 1);
        let mut m = 0;
        for (idx, (b, k)) in used.iter().enumerate() {
            aug.as_mut()
                .get_mut(idx * (n + 1)..(idx + 1) * (n + 1), ..)
                .copy_from(b.augmented((*k as f64).sqrt()));
            m += b.m * k;
        }
        Ok(Self::from_factor(triangular_factor(aug), m))
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
