//! Criterion 1: the noise level index κ of `B = [Θ | x'']` and the calibration of its threshold κ0.
//!
//! κ = log10(λ_max / λ_min) with λ the eigenvalues of the covariance of the mean-centred columns
//! (σ_i²/(m−1)). It is computed from one thin QR of the centred m×p matrix followed by the SVD of
//! the small p×p factor R — never an m×m matrix. Where only κ is needed and it is moderate, the
//! pipeline takes a cheaper route through the Gram matrix of the standardised columns
//! (`kappa_by_gram`, accurate to ~ε·10^κ relative in λ_min).

use faer::{Mat, MatRef};
use serde::{Deserialize, Serialize};

use crate::error::{CriteriaError, Result, invalid};

/// Largest κ reported: λ_min is floored at λ_max·1e-30 so an exactly collinear matrix gives 30.
pub const KAPPA_CAP: f64 = 30.0;

/// κ of a matrix in both variants.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Kappa {
    /// κ of the centred columns as they are. It depends on the units of every column (a
    /// displacement in millimetres instead of metres moves it, up to the cap [`KAPPA_CAP`]):
    /// reported for comparison with the paper; the criteria use `standardised` by default.
    pub raw: f64,
    /// κ after scaling every centred column to unit standard deviation.
    pub standardised: f64,
}

/// The centred copy of `b` and its column standard deviations; errors on non-finite values or a
/// constant column (which has no variance and makes κ meaningless).
pub(crate) fn centre(b: MatRef<'_, f64>, names: Option<&[String]>) -> Result<(Mat<f64>, Vec<f64>)> {
    let (m, p) = (b.nrows(), b.ncols());
    if m < p + 1 || p < 2 {
        return invalid(format!(
            "noise level index: the matrix has {m} rows and {p} columns; it needs at least 2 columns and more rows than columns"
        ));
    }
    let mut c = Mat::<f64>::zeros(m, p);
    let mut sd = vec![0.0; p];
    for j in 0..p {
        let col = b.col(j);
        let mut mean = 0.0;
        for i in 0..m {
            let v = col[i];
            if !v.is_finite() {
                return Err(CriteriaError::Numerics(format!(
                    "column {j} row {i} of the diagnostic matrix is {v}"
                )));
            }
            mean += v;
        }
        mean /= m as f64;
        let mut ss = 0.0;
        for i in 0..m {
            let d = col[i] - mean;
            c[(i, j)] = d;
            ss += d * d;
        }
        sd[j] = (ss / (m as f64 - 1.0)).sqrt();
        let scale = col.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        if sd[j] <= 1e-14 * scale.max(f64::MIN_POSITIVE) {
            let what = names
                .and_then(|n| n.get(j).cloned())
                .unwrap_or_else(|| format!("column {j}"));
            return invalid(format!(
                "noise level index: '{what}' is constant, so it has no variance after centring; drop it from the library"
            ));
        }
    }
    Ok((c, sd))
}

/// The p×p triangular factor of the thin QR of a (centred) m×p matrix.
pub(crate) fn small_factor(c: MatRef<'_, f64>) -> Mat<f64> {
    let qr = c.qr();
    let r = qr.thin_R();
    let mut out = Mat::<f64>::zeros(r.nrows(), r.ncols());
    for j in 0..r.ncols() {
        for i in 0..=j.min(r.nrows() - 1) {
            out[(i, j)] = r[(i, j)];
        }
    }
    out
}

/// κ from singular values (any common scale cancels).
pub(crate) fn kappa_from_singular(s: &[f64]) -> f64 {
    let max = s.iter().fold(0.0f64, |a, &v| a.max(v));
    if max <= 0.0 {
        return 0.0;
    }
    let min = s.iter().fold(f64::INFINITY, |a, &v| a.min(v));
    let ratio = (max * max) / (min * min).max(max * max * 10f64.powf(-KAPPA_CAP));
    ratio.log10()
}

/// κ of the columns `cols` of a small factor `r` (optionally scaled by `scale[j]`).
pub(crate) fn kappa_of_columns(
    r: MatRef<'_, f64>,
    cols: &[usize],
    scale: Option<&[f64]>,
) -> Result<f64> {
    let mut sub = Mat::<f64>::zeros(r.nrows(), cols.len());
    for (k, &j) in cols.iter().enumerate() {
        let f = scale.map_or(1.0, |s| 1.0 / s[j]);
        for i in 0..r.nrows() {
            sub[(i, k)] = r[(i, j)] * f;
        }
    }
    let s = sub
        .singular_values()
        .map_err(|e| CriteriaError::Numerics(format!("SVD of the small factor failed: {e:?}")))?;
    Ok(kappa_from_singular(&s))
}

/// Criterion 1: κ (raw and standardised) of `b` (m×p, the last column the target `x''`).
///
/// ```
/// use faer::Mat;
/// // Two nearly collinear columns give a large κ, two unrelated ones a small κ.
/// let m = 200;
/// let b = Mat::<f64>::from_fn(m, 2, |i, j| {
///     let t = i as f64 / m as f64;
///     if j == 0 { t } else { 2.0 * t + 1e-4 * (37.0 * t).sin() }
/// });
/// let k = tfs_criteria::noise_level_index(b.as_ref()).unwrap();
/// assert!(k.raw > 6.0);
/// ```
pub fn noise_level_index(b: MatRef<'_, f64>) -> Result<Kappa> {
    let (c, sd) = centre(b, None)?;
    let r = small_factor(c.as_ref());
    let all: Vec<usize> = (0..b.ncols()).collect();
    Ok(Kappa {
        raw: kappa_of_columns(r.as_ref(), &all, None)?,
        standardised: kappa_of_columns(r.as_ref(), &all, Some(&sd))?,
    })
}

/// Criterion 1 from the small factor `r` of the centred matrix (`B̄ = QR`): κ raw and
/// standardised (column spreads taken from the column norms of `r`).
pub fn noise_level_index_factor(r: MatRef<'_, f64>) -> Result<Kappa> {
    let sd = column_norms(r);
    if let Some(j) = sd.iter().position(|&v| v.is_nan() || v <= 0.0) {
        return invalid(format!(
            "noise level index: column {j} has no variance after centring; drop it from the library"
        ));
    }
    let all: Vec<usize> = (0..r.ncols()).collect();
    Ok(Kappa {
        raw: kappa_of_columns(r, &all, None)?,
        standardised: kappa_of_columns(r, &all, Some(&sd))?,
    })
}

/// Largest standardised κ for which [`kappa_by_gram`] answers. Forming the Gram matrix of the
/// centred, unit-norm columns costs a relative error of about ε·10^κ in its smallest
/// eigenvalue (1e-8 at this limit, far below the hundredths by which κ scatters between noise
/// draws); above it the caller takes the QR route, whose error is ε·10^(κ/2).
pub(crate) const GRAM_KAPPA_MAX: f64 = 8.0;

/// κ (raw and standardised) of the rows of several blocks stacked, each block `(A, y)` taken as
/// `[A[:, cols] | y]`, centred by the mean over all rows — the same quantity as
/// [`noise_level_index`] of the stacked matrix — from the Gram matrix of the centred,
/// unit-norm columns: one symmetric rank-k product (faer) and a Cholesky factor `R_s` of that
/// Gram, instead of a QR of every row. `R_s` is the QR factor of the standardised matrix, and
/// `R_s·diag(‖c_j‖)` that of the centred one, so both variants come from small SVDs exactly as
/// on the QR route.
///
/// Accurate while the standardised κ stays below [`GRAM_KAPPA_MAX`]; returns `Ok(None)` above
/// it, when the Cholesky factorisation fails, or when a column has no variance (the caller then
/// takes the QR route, which also reports the constant column).
pub(crate) fn kappa_by_gram(
    blocks: &[(Mat<f64>, Vec<f64>)],
    cols: &[usize],
) -> Result<Option<Kappa>> {
    use faer::linalg::matmul::triangular::{BlockStructure, matmul};
    let m: usize = blocks.iter().map(|(a, _)| a.nrows()).sum();
    let p = cols.len() + 1;
    if m < p + 1 || p < 2 {
        return Ok(None);
    }
    // Column j < p−1 is library column cols[j] of every block; the last is the target.
    let source = |j: usize| {
        blocks.iter().map(move |(a, y)| {
            if j + 1 == p {
                y.as_slice()
            } else {
                a.col_as_slice(cols[j])
            }
        })
    };
    let mut c = Mat::<f64>::zeros(m, p);
    let mut norms = vec![0.0; p];
    for (j, nj) in norms.iter_mut().enumerate() {
        // One pass for the sum and the largest magnitude, one for the centred copy and its
        // sum of squares, each with independent accumulators (vectorised).
        let mut stats = Lanes::default();
        for v in source(j) {
            stats.sum_and_max(v);
        }
        let (sum, size) = stats.totals();
        if !(sum.is_finite() && size.is_finite()) {
            for (b, v) in source(j).enumerate() {
                if let Some(i) = v.iter().position(|v| !v.is_finite()) {
                    let row = blocks[..b].iter().map(|(a, _)| a.nrows()).sum::<usize>() + i;
                    return Err(CriteriaError::Numerics(format!(
                        "column {j} row {row} of the diagnostic matrix is {}",
                        v[i]
                    )));
                }
            }
            // Finite entries whose sum overflows: the QR route scales before it sums.
            return Ok(None);
        }
        let mean = sum / m as f64;
        let out = c
            .col_mut(j)
            .try_as_col_major_mut()
            .expect("faer columns are contiguous")
            .as_slice_mut();
        let mut sq = Lanes::default();
        let mut row = 0;
        for v in source(j) {
            sq.centre_into(v, mean, &mut out[row..row + v.len()]);
            row += v.len();
        }
        let ss = sq.totals().0;
        *nj = ss.sqrt();
        // A column constant up to rounding (the test of `centre`) has no variance to speak of.
        let sd = (ss / (m as f64 - 1.0)).sqrt();
        if sd <= 1e-14 * size.max(f64::MIN_POSITIVE) || !nj.is_finite() {
            return Ok(None);
        }
    }
    // The Gram matrix of the centred columns, scaled to unit-norm columns afterwards.
    let mut g = Mat::<f64>::zeros(p, p);
    matmul(
        g.as_mut(),
        BlockStructure::TriangularLower,
        faer::Accum::Replace,
        c.transpose(),
        BlockStructure::Rectangular,
        c.as_ref(),
        BlockStructure::Rectangular,
        1.0,
        faer::Par::Seq,
    );
    drop(c);
    for k in 0..p {
        for i in k..p {
            g[(i, k)] /= norms[i] * norms[k];
        }
    }
    let Ok(llt) = g.as_ref().llt(faer::Side::Lower) else {
        return Ok(None);
    };
    let rs = llt.L().transpose().to_owned();
    let all: Vec<usize> = (0..p).collect();
    let standardised = kappa_of_columns(rs.as_ref(), &all, None)?;
    if standardised >= GRAM_KAPPA_MAX {
        return Ok(None);
    }
    let inv: Vec<f64> = norms.iter().map(|v| 1.0 / v).collect();
    Ok(Some(Kappa {
        raw: kappa_of_columns(rs.as_ref(), &all, Some(&inv))?,
        standardised,
    }))
}

/// Eight independent accumulators for column sums, sums of squares and magnitudes: a single
/// running sum waits on every addition, eight let the compiler vectorise. (The lane loops index
/// by lane on purpose: `l` picks the accumulator and the element alike.)
#[derive(Default)]
struct Lanes {
    sum: [f64; 8],
    max: [f64; 8],
}

impl Lanes {
    /// Adds `v` to the sums and the largest magnitudes (a NaN leaves the magnitudes alone and
    /// makes the sum NaN).
    #[allow(clippy::needless_range_loop)]
    fn sum_and_max(&mut self, v: &[f64]) {
        let mut chunks = v.chunks_exact(8);
        for ch in &mut chunks {
            for l in 0..8 {
                self.sum[l] += ch[l];
                let a = ch[l].abs();
                self.max[l] = if a > self.max[l] { a } else { self.max[l] };
            }
        }
        for (l, &x) in chunks.remainder().iter().enumerate() {
            self.sum[l] += x;
            self.max[l] = self.max[l].max(x.abs());
        }
    }

    /// Writes `v − mean` into `out` and adds its squares to the sums.
    #[allow(clippy::needless_range_loop)]
    fn centre_into(&mut self, v: &[f64], mean: f64, out: &mut [f64]) {
        let mut src = v.chunks_exact(8);
        let mut dst = out.chunks_exact_mut(8);
        for (s, o) in (&mut src).zip(&mut dst) {
            for l in 0..8 {
                let d = s[l] - mean;
                o[l] = d;
                self.sum[l] += d * d;
            }
        }
        for (l, (&x, o)) in src.remainder().iter().zip(dst.into_remainder()).enumerate() {
            let d = x - mean;
            *o = d;
            self.sum[l] += d * d;
        }
    }

    /// The sum over the lanes and the largest magnitude.
    fn totals(&self) -> (f64, f64) {
        let sum = ((self.sum[0] + self.sum[4]) + (self.sum[1] + self.sum[5]))
            + ((self.sum[2] + self.sum[6]) + (self.sum[3] + self.sum[7]));
        (sum, self.max.iter().fold(0.0f64, |a, &v| a.max(v)))
    }
}

/// Euclidean norms of the columns of `r`.
pub(crate) fn column_norms(r: MatRef<'_, f64>) -> Vec<f64> {
    (0..r.ncols())
        .map(|j| {
            (0..r.nrows())
                .map(|i| r[(i, j)] * r[(i, j)])
                .sum::<f64>()
                .sqrt()
        })
        .collect()
}

/// Which κ variant drives the criteria.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum KappaVariant {
    /// κ of the centred columns as they are (the paper's definition); it depends on the units
    /// the record is written in, so a decision taken on it does too.
    Raw,
    /// κ of unit-variance columns (insensitive to the units of each term).
    #[default]
    Standardised,
}

impl Kappa {
    /// The value of the chosen variant.
    pub fn get(&self, v: KappaVariant) -> f64 {
        match v {
            KappaVariant::Raw => self.raw,
            KappaVariant::Standardised => self.standardised,
        }
    }
}

/// One point of the κ-versus-added-noise calibration curve (paper Fig. 3c).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CalibrationPoint {
    /// SNR (dB, mean-square power) of the noise added to the user's data; `None` for the data as given.
    pub added_snr_db: Option<f64>,
    /// κ of the data with that noise added.
    pub kappa: Kappa,
}

/// How κ0 was obtained.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Kappa0Source {
    /// Given by the user.
    Given,
    /// Calibrated, but κ fell by only `drop` decades down to the weakest added SNR: `x''` is
    /// already about as far off the library's span as that noise would put it (noise or model
    /// error: [`SnrVerdict`](super::cause::SnrVerdict) says which), and κ0 sits a margin above
    /// the data's κ.
    LowSnr {
        /// κ's fall (decades).
        drop: f64,
        /// The weakest added SNR (dB).
        weakest_db: f64,
    },
    /// Calibrated: κ at the knee of κ(added SNR) plus a margin.
    Knee {
        /// The knee's added SNR (dB).
        snr_db: f64,
        /// κ there.
        kappa: f64,
    },
    /// Calibrated, but κ never dropped: κ0 is the lowest κ seen.
    NeverDropped,
}

impl std::fmt::Display for Kappa0Source {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        use super::calibration::MIN_CALIBRATION_DROP as M;
        match self {
            Kappa0Source::Given => f.write_str("given by the user"),
            Kappa0Source::LowSnr { drop, weakest_db } => write!(
                f,
                "calibrated: κ fell by only {drop:.2} decades when noise down to {weakest_db} dB SNR was added, so x'' is already about as far off the library's span as that noise would put it; κ0 set {M} decades above the data's κ"
            ),
            Kappa0Source::Knee { snr_db, kappa } => write!(
                f,
                "calibrated: κ at the knee of κ vs added-noise SNR (knee at {snr_db} dB, κ there {kappa:.3}) plus a {M}-decade margin"
            ),
            Kappa0Source::NeverDropped => {
                f.write_str("calibrated: κ never dropped with added noise, κ0 = lowest κ seen")
            }
        }
    }
}

impl Serialize for Kappa0Source {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        s.serialize_str(&self.to_string())
    }
}

/// The outcome of Criterion 1, and the support verdict of the identified model.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Criterion1 {
    /// κ of the data as given.
    pub kappa: Kappa,
    /// The variant compared with κ0.
    pub variant: KappaVariant,
    /// The threshold.
    pub kappa0: f64,
    /// How κ0 was obtained.
    pub kappa0_source: Kappa0Source,
    /// True if κ ≥ κ0 (high SNR: time-domain library selection is allowed).
    pub high_snr: bool,
    /// The verdict: high SNR, or below κ0 whether noise or model error is the cause (from the
    /// records' own noise estimate; in JSON `snr_verdict`).
    #[serde(rename = "snr_verdict")]
    pub snr: super::cause::SnrVerdict,
    /// The calibration curve, if κ0 was calibrated.
    pub curve: Vec<CalibrationPoint>,
    /// The added-noise SNR at the knee of the curve, if calibrated.
    pub knee_snr_db: Option<f64>,
    /// SNR (dB) of the displacement estimated from the fitted noise floors of the records (a
    /// lower bound when they show no noise floor).
    pub estimated_snr_db: Option<crate::trace::SnrEstimate>,
    /// Does the identified model show that the data support the library (in JSON:
    /// `supported` and `support_note`)?
    #[serde(flatten)]
    pub support: crate::trace::Support,
}

/// The knee of a κ-versus-added-SNR curve: `snr` strictly decreasing, `kappa` the matching κ, and
/// `kappa_top` the κ of the data as given. The curve is normalised to the unit square (x: how much
/// noise was added, y: how far κ has fallen) and the knee is the point furthest below the diagonal
/// (the "Kneedle" rule): the last point of the plateau before κ drops. Returns its index, or `None`
/// when κ never falls (a flat curve has no knee).
pub fn knee_index(snr: &[f64], kappa: &[f64], kappa_top: f64) -> Option<usize> {
    let n = snr.len();
    if n < 3 || kappa.len() != n {
        return None;
    }
    let kmin = kappa.iter().fold(f64::INFINITY, |a, &v| a.min(v));
    let range = kappa_top - kmin;
    if range.is_nan() || range <= 0.0 {
        return None;
    }
    let (s0, s1) = (snr[0], snr[n - 1]);
    let mut best = (None, 0.0);
    for i in 0..n {
        let x = (s0 - snr[i]) / (s0 - s1);
        let y = (kappa_top - kappa[i]) / range;
        let d = x - y;
        if d > best.1 {
            best = (Some(i), d);
        }
    }
    best.0
}

/// κ0 from a calibration curve (see [`knee_index`]); `None` if the curve has no knee.
pub fn kappa0_from_curve(curve: &[CalibrationPoint], variant: KappaVariant) -> Option<(f64, f64)> {
    let top = curve
        .iter()
        .find(|p| p.added_snr_db.is_none())?
        .kappa
        .get(variant);
    let pts: Vec<(f64, f64)> = curve
        .iter()
        .filter_map(|p| p.added_snr_db.map(|s| (s, p.kappa.get(variant))))
        .collect();
    let snr: Vec<f64> = pts.iter().map(|p| p.0).collect();
    let kap: Vec<f64> = pts.iter().map(|p| p.1).collect();
    let i = knee_index(&snr, &kap, top)?;
    Some((kap[i], snr[i]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_util::lcg;

    /// κ from the small factor equals κ from the eigenvalues of the explicit covariance.
    #[test]
    fn kappa_matches_covariance_eigenvalues() {
        let mut s = 7u64;
        let (m, p) = (300, 5);
        let mut b = Mat::<f64>::from_fn(m, p, |_, _| lcg(&mut s));
        for i in 0..m {
            b[(i, 4)] = 3.0 * b[(i, 0)] - b[(i, 2)] + 0.01 * lcg(&mut s) + 5.0;
            b[(i, 1)] *= 100.0;
        }
        let k = noise_level_index(b.as_ref()).unwrap();
        let (c, sd) = centre(b.as_ref(), None).unwrap();
        let cov = c.transpose() * &c * (1.0 / (m as f64 - 1.0));
        let ev = cov.self_adjoint_eigenvalues(faer::Side::Lower).unwrap();
        let want = (ev[p - 1] / ev[0]).log10();
        assert!((k.raw - want).abs() < 1e-8, "{} vs {want}", k.raw);
        let d = Mat::<f64>::from_fn(p, p, |i, j| if i == j { 1.0 / sd[i] } else { 0.0 });
        let corr = &d * &cov * &d;
        let ev = corr.self_adjoint_eigenvalues(faer::Side::Lower).unwrap();
        let want = (ev[p - 1] / ev[0]).log10();
        assert!((k.standardised - want).abs() < 1e-8);
    }

    /// The Gram route gives the κ of the stacked, centred blocks that the QR route gives, and
    /// declines ill-conditioned or constant columns.
    #[test]
    fn gram_route_matches_qr_route() {
        let mut s = 3u64;
        let (p, rows) = (6, [250usize, 180]);
        let blocks: Vec<(Mat<f64>, Vec<f64>)> = rows
            .iter()
            .map(|&m| {
                let a = Mat::<f64>::from_fn(m, p, |_, j| {
                    10f64.powi(j as i32 - 2) * lcg(&mut s) + 3.0 * j as f64
                });
                let y = (0..m)
                    .map(|i| a[(i, 1)] - 40.0 * a[(i, 3)] + 0.1 * lcg(&mut s))
                    .collect();
                (a, y)
            })
            .collect();
        let cols = [0, 1, 3, 5];
        let stacked = Mat::<f64>::from_fn(rows[0] + rows[1], cols.len() + 1, |i, j| {
            let (b, i) = if i < rows[0] {
                (0, i)
            } else {
                (1, i - rows[0])
            };
            if j < cols.len() {
                blocks[b].0[(i, cols[j])]
            } else {
                blocks[b].1[i]
            }
        });
        let want = noise_level_index(stacked.as_ref()).unwrap();
        let got = kappa_by_gram(&blocks, &cols)
            .unwrap()
            .expect("well conditioned");
        assert!((got.raw - want.raw).abs() < 1e-7, "{got:?} vs {want:?}");
        assert!((got.standardised - want.standardised).abs() < 1e-7);
        // y nearly in the span of the columns: standardised κ above the limit, declined.
        let tight: Vec<(Mat<f64>, Vec<f64>)> = blocks
            .iter()
            .map(|(a, _)| {
                let y = (0..a.nrows())
                    .map(|i| a[(i, 1)] + 1e-6 * lcg(&mut s))
                    .collect();
                (a.clone(), y)
            })
            .collect();
        assert!(kappa_by_gram(&tight, &cols).unwrap().is_none());
        // A constant column: declined (the QR route names it).
        let flat: Vec<(Mat<f64>, Vec<f64>)> = blocks
            .iter()
            .map(|(a, y)| {
                let mut a = a.clone();
                a.col_mut(5).fill(0.1);
                (a, y.clone())
            })
            .collect();
        assert!(kappa_by_gram(&flat, &cols).unwrap().is_none());
    }

    #[test]
    fn constant_column_is_an_error_naming_it() {
        let b = Mat::<f64>::from_fn(
            10,
            3,
            |i, j| if j == 1 { 2.0 } else { (i * (j + 1)) as f64 },
        );
        let e = noise_level_index(b.as_ref()).unwrap_err().to_string();
        assert!(e.contains("column 1") && e.contains("constant"), "{e}");
    }

    #[test]
    fn knee_is_the_end_of_the_plateau() {
        // Flat at 8 down to 40 dB, then a steep fall.
        let snr: Vec<f64> = (0..11).map(|i| 100.0 - 10.0 * i as f64).collect();
        let kap: Vec<f64> = snr
            .iter()
            .map(|&s| {
                if s >= 40.0 {
                    8.0 - 0.01 * (100.0 - s) / 10.0
                } else {
                    8.0 - (40.0 - s) / 8.0
                }
            })
            .collect();
        assert_eq!(knee_index(&snr, &kap, 8.0), Some(6));
        assert_eq!(knee_index(&snr, &[1.0; 11], 1.0), None);
    }
}
