//! `--offsets auto` with force-like inputs: the records decide between removing each record's
//! means and keeping the data with a constant term in the library.
//!
//! Neither is right for every record. A rig in raw units has sensor offsets on its channels;
//! the displacement's offset sits inside every nonlinear term (`(x − c)³` needs `x²` and `x`
//! terms the library may lack), and only its removal identifies the law. A short or transient
//! record of a structure without offsets has a mean that is motion, not offset; removing it
//! puts a constant force into the law that the library has no column for, and the selection
//! turns `x³` into `x²` and `x` terms.
//!
//! The two treatments are two models of the same accelerations (which no offset touches), so
//! the records tell them apart — by the sparse laws the identification finds under each, not
//! by the full library: a library closed under shifts (every lower power present) fits both
//! treatments' accelerations alike, and only the selected law shows which coordinate it is
//! simple in. [`compare_sparse`] weighs each law's held-out equation error against its number of
//! terms. The full-library score ([`score_treatment`]) decides where no sparse law is scored
//! (classical SINDy, or no term kept).

use faer::Mat;
use tfs_data::{Columns, Record};
use tfs_library::Library;
use tfs_signal::band::reconstruct_guarded;

use crate::error::Result;
use tfs_criteria::Trace;
use tfs_library::Model;

/// What a treatment's sparse law scores on one DOF (see [`sparse_scores`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SparseScore {
    /// Held-out relative residual energy of least squares on the law's own terms.
    pub held_out: f64,
    /// Terms the law keeps (the constant included).
    pub terms: usize,
    /// Frequency bins the fit kept over every record.
    pub bins: usize,
}

/// Per DOF, what an identified model's sparse law scores: the held-out relative residual energy
/// of least squares on the law's own terms at its coefficients' setting (each record left out in
/// turn, as the identification chooses its settings), its terms and the bins the fit kept.
/// `None` when a DOF has no held-out score or no bins.
pub fn sparse_scores(trace: &Trace, model: &Model) -> Option<Vec<SparseScore>> {
    trace
        .dofs
        .iter()
        .map(|d| {
            let s = &d.settings;
            let list = if s.coefficient_candidates.is_empty() {
                &s.candidates
            } else {
                &s.coefficient_candidates
            };
            let e = list
                .iter()
                .map(|c| c.held_out_error)
                .filter(|v| v.is_finite())
                .fold(f64::INFINITY, f64::min);
            let m: usize = d.bins.iter().map(|b| b.kept_bins).sum();
            let k = model.equation(&d.dof).ok()?.terms.len();
            (e.is_finite() && m > 0).then_some(SparseScore {
                held_out: e,
                terms: k,
                bins: m,
            })
        })
        .collect()
}

/// Compares two treatments' sparse laws DOF by DOF: `Σ_d m_d·ln(e_d) + k_d·ln(m_d)` for each,
/// with `e` the held-out error, `k` the terms and `m` the fewer of the two fits' kept bins on
/// that DOF — the independent values a band-limited record holds (its time samples are far from
/// independent), counted alike for both so that neither gains from keeping more bins. Returns
/// the two criteria (lower is better); `None` when the DOFs do not match.
pub fn compare_sparse(a: &[SparseScore], b: &[SparseScore]) -> Option<(f64, f64)> {
    if a.len() != b.len() || a.is_empty() {
        return None;
    }
    let (mut sa, mut sb) = (0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        let m = x.bins.min(y.bins) as f64;
        let crit = |s: &SparseScore| m * s.held_out.max(1e-300).ln() + s.terms as f64 * m.ln();
        sa += crit(x);
        sb += crit(y);
    }
    Some((sa, sb))
}

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

#[cfg(test)]
mod tests {
    use super::*;

    fn s(held_out: f64, terms: usize, bins: usize) -> SparseScore {
        SparseScore {
            held_out,
            terms,
            bins,
        }
    }

    /// Both laws are counted on the fewer of the two fits' bins: a fit that kept more bins (41
    /// against 19) does not win by multiplying its worse log error by more rows.
    #[test]
    fn both_treatments_are_counted_on_the_same_bins() {
        let keep = [s(0.0017, 3, 19)];
        let remove = [s(0.0035, 4, 47)];
        let (k, r) = compare_sparse(&keep, &remove).unwrap();
        let m = 19.0_f64;
        assert!((k - (m * 0.0017_f64.ln() + 3.0 * m.ln())).abs() < 1e-9);
        assert!((r - (m * 0.0035_f64.ln() + 4.0 * m.ln())).abs() < 1e-9);
        assert!(k < r, "{k} {r}");
    }

    /// Equal held-out errors: the law with fewer terms wins (the rig's linear law without its
    /// constant once the offsets are removed).
    #[test]
    fn equal_errors_go_to_the_sparser_law() {
        let (k, r) = compare_sparse(&[s(0.02, 4, 60)], &[s(0.02, 3, 60)]).unwrap();
        assert!(r < k, "{k} {r}");
        assert!(compare_sparse(&[s(0.02, 4, 60)], &[]).is_none());
    }
}
