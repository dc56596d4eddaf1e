//! The common result type [`Fit`], the [`Regressor`] trait, least squares and ridge.

use crate::compress::Compressed;
use crate::error::{Result, check_param};
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

/// Ordinary least squares on all columns (column-pivoted QR of the small factor).
///
/// Rank deficiency is not an error: numerically dependent columns get coefficient 0 and are
/// listed in [`Fit::dependent`] (a basic solution).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct LeastSquares;

impl Regressor for LeastSquares {
    fn fit_compressed(&self, p: &Compressed) -> Result<Fit> {
        let n = p.ncols();
        let cols: Vec<usize> = (0..n).collect();
        let (x, dep) = subset_solve(p, &cols, &vec![1.0; n], 1.0, 0.0);
        Fit::from_coef(p, x, dep, 1, true)
    }
}

/// Least squares on raw rows: `LeastSquares.fit(a, b)`.
pub fn lstsq(a: MatRef<'_, f64>, b: &[f64]) -> Result<Fit> {
    LeastSquares.fit(a, b)
}

/// Least squares restricted to a support (columns outside get 0), on a compressed problem.
pub fn lstsq_support(p: &Compressed, support: &[bool]) -> Result<Fit> {
    if support.len() != p.ncols() {
        return Err(crate::RegressError::DimensionMismatch {
            what: "length of support vs columns of the compressed problem".into(),
            expected: p.ncols(),
            found: support.len(),
        });
    }
    let cols: Vec<usize> = (0..p.ncols()).filter(|&j| support[j]).collect();
    let (x, dep) = subset_solve(p, &cols, &vec![1.0; p.ncols()], 1.0, 0.0);
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
