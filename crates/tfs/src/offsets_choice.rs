//! `--offsets auto` with force-like inputs: the records decide between removing each record's
//! means and keeping the data with a constant term in the library.
//!
//! Neither is right for every record. A rig in raw units has sensor offsets on its channels;
//! the displacement's offset sits inside every nonlinear term (`(x − c)³` needs `x²` and `x`
//! terms the library may lack), and only its removal identifies the law. A short or transient
//! record of a structure without offsets has a mean that is motion, not offset; removing it
//! puts a constant force into the law that the library has no column for, and the selection
//! turns `x³` into `x²` and `x` terms. The two treatments are two models of the same
//! accelerations (which no offset touches), so the records tell them apart: each is fitted by
//! least squares on the full library over the band-limited reconstruction of every record, and
//! the one with the lower Bayesian information criterion (the extra constant costs its column)
//! is used.

use faer::Mat;
use tfs_data::{Columns, Record};
use tfs_library::Library;
use tfs_signal::band::reconstruct_guarded;

use crate::error::Result;

/// Guard band of the reconstruction, as the identification's default.
const GUARD_OCTAVES: f64 = 0.5;

/// The equation-error score of one treatment: `n·ln(RSS/n) + k·ln(n)` summed over the DOFs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TreatmentScore {
    /// The information criterion (lower is better).
    pub bic: f64,
    /// Residual RMS over the RMS of the band-limited acceleration, all DOFs' rows pooled.
    pub residual_share: f64,
}

/// Scores a treatment: `records` already treated (means removed or kept), every DOF's library
/// (the constant included when the treatment adds it) fitted by least squares on the
/// band-limited reconstruction of every record, ends trimmed.
pub fn score_treatment(
    records: &[Record],
    dofs: &[String],
    libraries: &[Library],
) -> Result<TreatmentScore> {
    let mut bic = 0.0;
    let (mut rss_all, mut ss_all) = (0.0, 0.0);
    for (d, lib) in libraries.iter().enumerate() {
        let mut blocks: Vec<(Mat<f64>, Vec<f64>)> = Vec::with_capacity(records.len());
        for r in records {
            let dt = r.dt();
            let n = r.len();
            let trim = (n / 50).max(4);
            if n <= 2 * trim + lib.len() + 2 {
                continue;
            }
            let stride = (n / 4000).max(1);
            let smooth: Vec<_> = dofs
                .iter()
                .map(|c| {
                    let x = r.column(c).expect("records hold their DOFs");
                    reconstruct_guarded(x, dt, None, GUARD_OCTAVES)
                })
                .collect();
            let sub = |v: &[f64]| -> Vec<f64> {
                v[trim..n - trim].iter().step_by(stride).copied().collect()
            };
            let rows = (n - 2 * trim).div_ceil(stride);
            let mut cols: Vec<(String, Vec<f64>)> = Vec::new();
            for c in lib.required_columns() {
                let v = if let Some(i) = dofs.iter().position(|d| *d == c) {
                    sub(&smooth[i].x)
                } else if let Some(i) = dofs.iter().position(|d| format!("{d}'") == c) {
                    sub(&smooth[i].v)
                } else if let Some(v) = r.column(&c) {
                    sub(v)
                } else {
                    continue;
                };
                cols.push((c, v));
            }
            let a = lib.evaluate(&Owned { rows, cols })?;
            blocks.push((a, sub(&smooth[d].a)));
        }
        let n: usize = blocks.iter().map(|b| b.1.len()).sum();
        let k = lib.len();
        if n <= k + 1 {
            continue;
        }
        let mut a = Mat::<f64>::zeros(n, k);
        let mut y = Vec::with_capacity(n);
        let mut row = 0;
        for (ab, yb) in &blocks {
            for i in 0..ab.nrows() {
                for j in 0..k {
                    a[(row + i, j)] = ab[(i, j)];
                }
            }
            row += ab.nrows();
            y.extend_from_slice(yb);
        }
        // A fit that fails (a degenerate library on these records) leaves the DOF unscored;
        // the identification itself reports such libraries in the user's words.
        let Ok(fit) = tfs_regress::lstsq(a.as_ref(), &y) else {
            continue;
        };
        let ss: f64 = y.iter().map(|v| v * v).sum();
        let rss = fit.rss.max(ss * 1e-30).max(f64::MIN_POSITIVE);
        let nf = n as f64;
        bic += nf * (rss / nf).ln() + k as f64 * nf.ln();
        rss_all += rss;
        ss_all += ss;
    }
    Ok(TreatmentScore {
        bic,
        residual_share: if ss_all > 0.0 {
            (rss_all / ss_all).sqrt()
        } else {
            0.0
        },
    })
}

/// Columns owned by the score (a strided, trimmed copy of a record's).
struct Owned {
    rows: usize,
    cols: Vec<(String, Vec<f64>)>,
}

impl Columns for Owned {
    fn column(&self, name: &str) -> Option<&[f64]> {
        self.cols
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_slice())
    }
    fn rows(&self) -> usize {
        self.rows
    }
}
