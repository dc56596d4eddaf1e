//! Criterion 4 with data assembly: the model is fitted on the first `k` records (`k = 1, 2, …`),
//! scored on the held-out last record, and the assembly stops once the residual there is small
//! (mean `μ ≤ μ0`) and has converged (spread `σ` no longer falling, or `σ ≤ σ0`). Shared by the
//! single-DOF and the tied chain fits; each says what it does once the criterion is met.

use faer::MatRef;
use rayon::prelude::*;

use crate::error::Result;
use crate::trace::AssemblyStep;

/// Criterion 4 statistics of a model on time-domain data: (μ, σ) relative to the spread of y.
pub fn residual_stats(a: MatRef<'_, f64>, y: &[f64], coef: &[f64]) -> (f64, f64) {
    let m = y.len() as f64;
    let ym = y.iter().sum::<f64>() / m;
    let ysd = (y.iter().map(|v| (v - ym).powi(2)).sum::<f64>() / m)
        .sqrt()
        .max(f64::MIN_POSITIVE);
    let mut e = vec![0.0; y.len()];
    for (i, ei) in e.iter_mut().enumerate() {
        let mut s = y[i];
        for (j, c) in coef.iter().enumerate() {
            if *c != 0.0 {
                s -= c * a[(i, j)];
            }
        }
        *ei = s;
    }
    let em = e.iter().sum::<f64>() / m;
    let esd = (e.iter().map(|v| (v - em).powi(2)).sum::<f64>() / m).sqrt();
    (em.abs() / ysd, esd / ysd)
}

/// When an assembly step meets Criterion 4.
#[derive(Debug, Clone, Copy)]
pub(crate) struct StopRule {
    /// Bound on μ (relative to the spread of x''); `None`: 0.05.
    pub mu0: Option<f64>,
    /// Bound on σ; `None`: σ has converged (at least 99 % of the previous step's).
    pub sigma0: Option<f64>,
    /// Whether σ's convergence also needs the previous step's model to be non-empty. The
    /// single-DOF fit asks for it; the tied fit does not (see `docs/DECISIONS.md`).
    pub previous_nonempty: bool,
}

impl StopRule {
    /// Does step `k` (1-based) of one equation's trajectory `steps` meet the criterion? An empty
    /// model explains nothing: it never meets it, and a σ that stays at the spread of x''
    /// because both steps are empty is not convergence.
    fn met(&self, k: usize, steps: &[AssemblyStep]) -> bool {
        let nonempty = |st: &AssemblyStep| st.n_terms > 0;
        let cur = &steps[k - 1];
        let (mu, sigma) = (cur.mu, cur.sigma);
        nonempty(cur)
            && match (self.mu0, self.sigma0) {
                (Some(m0), Some(s0)) => mu <= m0 && sigma <= s0,
                (m0, s0) => {
                    let m_ok = mu <= m0.unwrap_or(0.05);
                    let s_ok = match s0 {
                        Some(s0) => sigma <= s0,
                        None => {
                            k >= 2
                                && (!self.previous_nonempty || nonempty(&steps[k - 2]))
                                && sigma >= 0.99 * steps[k - 2].sigma
                        }
                    };
                    m_ok && s_ok
                }
            }
    }
}

/// What an assembly step gives: its fit and each equation's statistics on the held-out record.
pub(crate) type StepResult<F> = Result<(F, Vec<AssemblyStep>)>;

/// The trajectory of the data assembly: per equation its steps, the fit of every step, and the
/// step at which Criterion 4 was met by every equation (`None`: the records ran out).
pub(crate) struct Assembly<F> {
    /// Per equation, the statistics of every step taken.
    pub steps: Vec<Vec<AssemblyStep>>,
    /// The fit of every step taken.
    pub fits: Vec<F>,
    /// The step (number of records) that met the criterion.
    pub stop: Option<usize>,
}

impl<F: Clone> Assembly<F> {
    /// The fit of the step that met the criterion, with that step's number (records used).
    pub fn accepted(&self) -> Option<(usize, F)> {
        self.stop.map(|k| (k, self.fits[k - 1].clone()))
    }

    /// The last step's fit (the records ran out), or `empty` when no step was taken.
    pub fn last_or(&self, empty: F) -> F {
        self.fits.last().cloned().unwrap_or(empty)
    }
}

/// Runs the assembly over `1..=hold` records: `step(k)` fits on the first `k` records and returns
/// the fit and each equation's statistics on the held-out record. Steps are computed as many at
/// a time as there are threads (they do not depend on each other; only the stopping rule is
/// sequential), then walked in order until every equation meets `rule`.
pub(crate) fn assemble<F: Send>(
    hold: usize,
    equations: usize,
    rule: &StopRule,
    step: impl Fn(usize) -> StepResult<F> + Sync,
) -> Result<Assembly<F>> {
    let mut out = Assembly {
        steps: vec![Vec::new(); equations],
        fits: Vec::new(),
        stop: None,
    };
    let width = rayon::current_num_threads().max(1);
    let mut next = 1;
    'assembly: while next <= hold {
        let end = (next + width - 1).min(hold);
        let batch: Vec<Result<_>> = (next..=end).into_par_iter().map(&step).collect();
        for (k, r) in (next..=end).zip(batch) {
            let (fit, stats) = r?;
            for (traj, st) in out.steps.iter_mut().zip(stats) {
                traj.push(st);
            }
            out.fits.push(fit);
            if out.steps.iter().all(|traj| rule.met(k, traj)) {
                out.stop = Some(k);
                break 'assembly;
            }
        }
        next = end + 1;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn step(n_terms: usize, sigma: f64) -> AssemblyStep {
        AssemblyStep {
            records: Vec::new(),
            rows: 0,
            n_terms,
            mu: 0.0,
            sigma,
        }
    }

    /// σ has converged when it stops falling; an empty model never meets the criterion, and the
    /// single-DOF rule also refuses convergence from an empty previous step (σ = 1 to σ = 1),
    /// which the tied fit's rule accepts.
    #[test]
    fn stop_rules_of_the_two_fits() {
        let single = StopRule {
            mu0: None,
            sigma0: None,
            previous_nonempty: true,
        };
        let tied = StopRule {
            previous_nonempty: false,
            ..single
        };
        let falling = [step(3, 0.5), step(3, 0.2)];
        let flat = [step(3, 0.2), step(3, 0.199)];
        let from_empty = [step(0, 1.0), step(2, 0.995)];
        for rule in [&single, &tied] {
            assert!(!rule.met(1, &falling) && !rule.met(2, &falling));
            assert!(rule.met(2, &flat));
            assert!(!rule.met(1, &[step(0, 1.0)]));
        }
        assert!(!single.met(2, &from_empty) && tied.met(2, &from_empty));
        let bounded = StopRule {
            sigma0: Some(0.3),
            ..single
        };
        assert!(bounded.met(2, &falling) && !bounded.met(1, &falling));
    }

    /// The assembly stops at the first step every equation meets, whatever the batch width.
    #[test]
    fn assembly_stops_where_every_equation_meets_the_rule() {
        let rule = StopRule {
            mu0: None,
            sigma0: Some(0.1),
            previous_nonempty: true,
        };
        // Equation 0 meets it from step 2, equation 1 from step 4.
        let run = assemble(6, 2, &rule, |k| {
            let s0 = if k >= 2 { 0.05 } else { 0.5 };
            let s1 = if k >= 4 { 0.05 } else { 0.5 };
            Ok((k, vec![step(1, s0), step(1, s1)]))
        })
        .unwrap();
        assert_eq!(run.stop, Some(4));
        assert_eq!(run.fits, vec![1, 2, 3, 4]);
        assert!(run.steps.iter().all(|t| t.len() == 4));
    }
}
