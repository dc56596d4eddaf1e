//! Criterion 2: library pruning by backward elimination on κ, run entirely on the small
//! (n+1)×(n+1) factor of one thin QR of the centred diagnostic matrix.
//!
//! Removing a column of `B = QR` leaves `B' = Q R'` with `R'` the factor without that column, so
//! the singular values (and κ) of every candidate library come from `R'` alone.

use faer::MatRef;
use serde::Serialize;

use crate::criterion1::Criterion1Out;
use crate::criterion1::kappa::{
    KappaVariant, centre, column_norms, kappa_of_columns, small_factor,
};
use crate::error::{Result, invalid};
use crate::options::TfsOptions;

/// One step of the elimination.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PruneStep {
    /// Index (into the original library) of the column removed.
    pub removed: usize,
    /// Its name.
    pub name: String,
    /// κ of the remaining library with the target after the removal.
    pub kappa_after: f64,
}

/// The outcome of Criterion 2.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Criterion2 {
    /// κ of the full matrix before any removal.
    pub kappa_start: f64,
    /// The whole elimination (down to the target alone), for a Fig. 3d plot.
    pub trace: Vec<PruneStep>,
    /// The threshold κ1: the κ just before the largest single drop of the trace.
    pub kappa1: f64,
    /// How κ1 was chosen.
    pub kappa1_reason: Kappa1Reason,
    /// Library columns kept (indices into the original library, in original order).
    pub kept: Vec<usize>,
}

/// How κ1 was chosen.
#[derive(Debug, Clone, PartialEq)]
pub enum Kappa1Reason {
    /// Given by the user: columns removed while κ ≥ κ1.
    Given {
        /// κ1.
        kappa1: f64,
    },
    /// The library had no column to remove.
    NothingToRemove,
    /// The value before the largest drop, at removing `term`.
    AbruptDrop {
        /// κ1.
        kappa1: f64,
        /// The drop (decades).
        drop: f64,
        /// The term whose removal dropped κ.
        term: String,
        /// The median drop.
        median: f64,
    },
    /// No drop is abrupt enough: nothing pruned.
    NoAbruptDrop {
        /// The largest drop (decades).
        largest: f64,
        /// The smallest drop that counts.
        min_drop: f64,
        /// The median drop.
        median: f64,
    },
}

impl std::fmt::Display for Kappa1Reason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Kappa1Reason::Given { kappa1 } => {
                write!(f, "given by the user: remove while κ ≥ {kappa1:.3}")
            }
            Kappa1Reason::NothingToRemove => f.write_str("nothing to remove"),
            Kappa1Reason::AbruptDrop {
                kappa1,
                drop,
                term,
                median,
            } => write!(
                f,
                "κ1 = {kappa1:.3}: the value before the largest drop ({drop:.2} decades, at removing '{term}'; median drop {median:.2})"
            ),
            Kappa1Reason::NoAbruptDrop {
                largest,
                min_drop,
                median,
            } => write!(
                f,
                "no abrupt drop (largest {largest:.2} decades, needs ≥ {min_drop:.2} and ≥ 3× the median {median:.2}): nothing pruned"
            ),
        }
    }
}

impl Serialize for Kappa1Reason {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        s.serialize_str(&self.to_string())
    }
}

/// Criterion 2 on `b` (m×(n+1), columns = library then the target `x''` last).
///
/// The elimination runs to the end (only the target left, κ = 0) so the whole trace is available;
/// the kept set is the library before the *abrupt drop*: the step whose κ decrease is the largest
/// of the trace, provided it is at least `min_drop` decades and at least three times the median
/// decrease (otherwise nothing is pruned). `kappa1` overrides the automatic threshold: columns are
/// removed while the best remaining κ stays ≥ `kappa1`. The target column is never removed.
pub fn prune_library(
    b: MatRef<'_, f64>,
    names: &[String],
    variant: KappaVariant,
    kappa1: Option<f64>,
    min_drop: f64,
) -> Result<Criterion2> {
    let p = b.ncols();
    if names.len() + 1 != p {
        return invalid(format!(
            "library pruning: {} names for {} library columns; give one name per column",
            names.len(),
            p.saturating_sub(1)
        ));
    }
    let (c, sd) = centre(b, None)?;
    let r = small_factor(c.as_ref());
    prune_factor(r.as_ref(), &sd, names, variant, kappa1, min_drop)
}

/// Criterion 2 on the small factor `r` ((n+1)×(n+1), of the centred `[Θ | x'']`) with column
/// spreads `sd` (any common scale; used by the standardised variant). See [`prune_library`].
pub fn prune_factor(
    r: MatRef<'_, f64>,
    sd: &[f64],
    names: &[String],
    variant: KappaVariant,
    kappa1: Option<f64>,
    min_drop: f64,
) -> Result<Criterion2> {
    let p = r.ncols();
    if names.len() + 1 != p || sd.len() != p {
        return invalid(format!(
            "library pruning: {} names and {} spreads for a factor with {p} columns; give one per library column (and a spread for the target)",
            names.len(),
            sd.len()
        ));
    }
    let scale = match variant {
        KappaVariant::Raw => None,
        KappaVariant::Standardised => Some(sd),
    };
    let target = p - 1;
    let mut active: Vec<usize> = (0..target).collect();
    let all: Vec<usize> = (0..p).collect();
    let kappa_start = kappa_of_columns(r, &all, scale)?;
    let mut trace = Vec::new();
    while !active.is_empty() {
        let mut best: Option<(usize, f64)> = None;
        for (pos, _) in active.iter().enumerate() {
            let mut cols: Vec<usize> = active.clone();
            cols.remove(pos);
            cols.push(target);
            let k = kappa_of_columns(r, &cols, scale)?;
            if best.is_none_or(|(_, bk)| k > bk) {
                best = Some((pos, k));
            }
        }
        let (pos, k) = best.expect("active is non-empty");
        let removed = active.remove(pos);
        trace.push(PruneStep {
            removed,
            name: names[removed].clone(),
            kappa_after: k,
        });
    }
    let (kappa1, reason, n_removed) = match kappa1 {
        Some(k1) => {
            let n = trace.iter().take_while(|s| s.kappa_after >= k1).count();
            (k1, Kappa1Reason::Given { kappa1: k1 }, n)
        }
        None => choose_kappa1(kappa_start, &trace, min_drop),
    };
    let removed: Vec<usize> = trace[..n_removed].iter().map(|s| s.removed).collect();
    let kept = (0..target).filter(|j| !removed.contains(j)).collect();
    Ok(Criterion2 {
        kappa_start,
        trace,
        kappa1,
        kappa1_reason: reason,
        kept,
    })
}

/// The automatic κ1 rule (see [`prune_library`]); returns (κ1, reason, number of removals).
fn choose_kappa1(
    kappa_start: f64,
    trace: &[PruneStep],
    min_drop: f64,
) -> (f64, Kappa1Reason, usize) {
    let mut seq = vec![kappa_start];
    seq.extend(trace.iter().map(|s| s.kappa_after));
    let drops: Vec<f64> = seq.windows(2).map(|w| w[0] - w[1]).collect();
    if drops.is_empty() {
        return (kappa_start, Kappa1Reason::NothingToRemove, 0);
    }
    let (imax, dmax) =
        drops.iter().enumerate().fold(
            (0, f64::NEG_INFINITY),
            |a, (i, &d)| if d > a.1 { (i, d) } else { a },
        );
    let mut sorted: Vec<f64> = drops.iter().map(|d| d.max(0.0)).collect();
    sorted.sort_by(f64::total_cmp);
    let median = sorted[sorted.len() / 2];
    if dmax >= min_drop && dmax >= 3.0 * median {
        (
            seq[imax],
            Kappa1Reason::AbruptDrop {
                kappa1: seq[imax],
                drop: dmax,
                term: trace[imax].name.clone(),
                median,
            },
            imax,
        )
    } else {
        (
            kappa_start,
            Kappa1Reason::NoAbruptDrop {
                largest: dmax,
                min_drop,
                median,
            },
            0,
        )
    }
}

/// Criterion 2 as the pipeline runs it: when pruning is asked for, Criterion 1 says the SNR is
/// high and there is more than one non-constant term, backward elimination on the centred factor
/// of Criterion 1 (`c1`). Returns the library columns the regression keeps (constant terms are
/// never pruned) and the elimination, if it ran.
pub(crate) fn criterion2_stage(
    c1: &Criterion1Out,
    names: &[String],
    opt: &TfsOptions,
) -> Result<(Vec<usize>, Option<Criterion2>)> {
    let all: Vec<usize> = (0..names.len()).collect();
    let nonconst = &c1.nonconst;
    if !(opt.criterion2.prune && c1.verdict.high_snr && nonconst.len() > 1) {
        return Ok((all, None));
    }
    let sd = column_norms(c1.factor.as_ref());
    let nn: Vec<String> = nonconst.iter().map(|&j| names[j].clone()).collect();
    let res = prune_factor(
        c1.factor.as_ref(),
        &sd,
        &nn,
        opt.criterion1.kappa_variant,
        opt.criterion2.kappa1,
        opt.criterion2.min_abrupt_drop,
    )?;
    let kept_nc: Vec<usize> = res.kept.iter().map(|&k| nonconst[k]).collect();
    let keep = all
        .into_iter()
        .filter(|j| !nonconst.contains(j) || kept_nc.contains(j))
        .collect();
    Ok((keep, Some(res)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_util::lcg;
    use faer::Mat;

    /// The κ after each removal equals κ recomputed from scratch on the m-row matrix.
    #[test]
    fn small_factor_elimination_matches_full_recomputation() {
        let mut s = 3u64;
        let (m, n) = (400, 6);
        let mut b = Mat::<f64>::from_fn(m, n + 1, |_, _| lcg(&mut s));
        for i in 0..m {
            b[(i, n)] = 2.0 * b[(i, 1)] - 0.5 * b[(i, 4)] + 1e-3 * lcg(&mut s);
        }
        let names: Vec<String> = (0..n).map(|j| format!("t{j}")).collect();
        let c2 = prune_library(b.as_ref(), &names, KappaVariant::Raw, None, 1.0).unwrap();
        let mut active: Vec<usize> = (0..n).collect();
        for st in &c2.trace {
            active.retain(|&j| j != st.removed);
            if active.is_empty() {
                // The target alone has one eigenvalue: κ = 0.
                assert_eq!(st.kappa_after, 0.0);
                continue;
            }
            let mut cols = active.clone();
            cols.push(n);
            let sub = Mat::<f64>::from_fn(m, cols.len(), |i, k| b[(i, cols[k])]);
            let k = crate::criterion1::kappa::noise_level_index(sub.as_ref())
                .unwrap()
                .raw;
            assert!(
                (k - st.kappa_after).abs() < 1e-7,
                "{k} vs {}",
                st.kappa_after
            );
        }
        // The relevant columns survive, the irrelevant ones go first.
        assert_eq!(c2.kept, vec![1, 4], "{:?}", c2.trace);
    }
}
