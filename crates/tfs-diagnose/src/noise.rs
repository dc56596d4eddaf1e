//! What measurement noise can explain of an equation residual. The tool's own noise estimate —
//! the power-law floor that `tfs_signal::band` fits to the upper half of each channel's
//! spectrum, the same one identification uses — is carried through what the diagnosis does to
//! the records by `tfs_signal::estimate`: each displacement's noise through the equation's
//! local gains along the records (its partial derivatives in that displacement and its
//! velocity; the displacement twice differentiated as the target), each input's through the
//! equation's linear terms in it, low-passed at the cut-off. A residual is called noise only
//! when this says it is the size of the noise.

use serde::Serialize;
use tfs_data::Columns;
use tfs_library::{CompiledModel, Factor, LocalGains, Model, Var};
use tfs_signal::band::reconstruct;
use tfs_signal::estimate::{SnrEstimate, derivative_response, residual_noise_var, snr_db};

use crate::prepare::RecordStates;

/// Above this estimated SNR of the displacement (80 dB) the records are called clean.
pub const CLEAN_SNR_DB: f64 = SnrEstimate::CLEAN_DB;

/// The noise estimate of one DOF's equation residual over the records.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct NoiseEstimate {
    /// RMS of the residual that measurement noise alone would leave (units of `x''`).
    pub residual_rms: f64,
    /// Estimated SNR of the displacement over the records (dB; `+∞` without a noise estimate),
    /// as identification states it.
    pub snr_db: f64,
    /// True when some record's spectrum shows no noise floor: `snr_db` is then a lower bound.
    pub snr_is_bound: bool,
    /// True when every channel's floor was fitted on noise alone; otherwise the spectrum of some
    /// channel reaches into the band the floor is fitted on, and the estimate is an upper bound.
    pub noise_only: bool,
    /// The cut-offs the residual's `x''` was low-passed at (Hz, lowest and highest over the
    /// records).
    pub band_hz: [f64; 2],
}

impl NoiseEstimate {
    /// True when the estimated noise is at least 80 dB below the displacement.
    pub fn clean(&self) -> bool {
        self.snr_db >= CLEAN_SNR_DB
    }

    /// The displacement SNR in words, as identification prints it: `29.7 dB`, or `at least
    /// 108.5 dB` when it is a bound.
    pub fn snr_words(&self) -> String {
        let db = self.snr_db.min(999.0);
        if self.snr_is_bound {
            format!("at least {db:.1} dB")
        } else {
            format!("{db:.1} dB")
        }
    }
}

/// The linear terms of equation `idx` of `model` in its inputs, per input, as (input,
/// [(0, coefficient)]). (The DOFs' channels are seen through the equation's local gains.)
fn input_terms(model: &Model, idx: usize) -> Vec<(&str, Vec<(usize, f64)>)> {
    let mut out: Vec<(&str, Vec<(usize, f64)>)> = Vec::new();
    for t in &model.equations[idx].terms {
        let [Factor::Pow(Var::Input(n), 1)] = t.term.factors() else {
            continue;
        };
        match out.iter_mut().find(|(m, _)| *m == n.as_str()) {
            Some((_, v)) => v.push((0, t.coef)),
            None => out.push((n.as_str(), vec![(0, t.coef)])),
        }
    }
    out
}

/// The linear coefficients of equation `idx` of `model` in each DOF's displacement and velocity,
/// as gains with no spread (DOF order): what the local gains are where they cannot be evaluated.
fn linear_dof_terms(model: &Model, idx: usize) -> Vec<LocalGains> {
    let mut out = vec![LocalGains::default(); model.dofs.len()];
    for t in &model.equations[idx].terms {
        let (name, order) = match t.term.factors() {
            [Factor::Pow(Var::Disp(n), 1)] => (n, 0),
            [Factor::Pow(Var::Vel(n), 1)] => (n, 1),
            _ => continue,
        };
        if let Some(k) = model.dofs.iter().position(|d| d == name) {
            let g = if order == 0 {
                &mut out[k].disp
            } else {
                &mut out[k].vel
            };
            g.mean += t.coef;
        }
    }
    out
}

/// The local gains of equation `idx` with respect to every DOF along the usable rows of one
/// record's states (`None` when a column the model reads is missing).
fn record_gains(
    compiled: &CompiledModel,
    model: &Model,
    idx: usize,
    s: &RecordStates,
) -> Option<Vec<LocalGains>> {
    let x: Vec<&[f64]> = model
        .dofs
        .iter()
        .map(|d| s.column(d))
        .collect::<Option<_>>()?;
    let v: Vec<&[f64]> = model
        .dofs
        .iter()
        .map(|d| s.column(&format!("{d}'")))
        .collect::<Option<_>>()?;
    let u: Vec<&[f64]> = compiled
        .input_names()
        .iter()
        .map(|n| s.column(n))
        .collect::<Option<_>>()?;
    let len = x
        .iter()
        .chain(&v)
        .chain(&u)
        .map(|c| c.len())
        .min()
        .unwrap_or(0);
    let rows = s.margin..len.saturating_sub(s.margin);
    (!rows.is_empty()).then(|| compiled.local_gains(idx, &x, &v, &u, rows))
}

/// The noise estimate of the residual of DOF `idx` of `model` on `states` (see the module docs).
/// Each DOF's noise reaches the residual through the equation's local gains along each record
/// (the means as coefficients, their spread added), so a polynomial whose large linear
/// coefficient its higher powers cancel is charged its local stiffness, not that coefficient.
pub(crate) fn estimate(model: &Model, idx: usize, states: &[RecordStates]) -> NoiseEstimate {
    let inputs = input_terms(model, idx);
    let compiled = model.compile().ok();
    let linear = linear_dof_terms(model, idx);
    let (mut var_sum, mut rows) = (0.0, 0usize);
    let mut noise_only = true;
    let mut own: Vec<(&[f64], tfs_signal::Band)> = Vec::new();
    let mut band_hz = [f64::INFINITY, 0.0f64];
    for s in states {
        let dt = s.record.dt();
        let fc = s.cutoff_hz;
        band_hz = [band_hz[0].min(fc), band_hz[1].max(fc)];
        let gains = compiled
            .as_ref()
            .and_then(|c| record_gains(c, model, idx, s))
            .unwrap_or_else(|| linear.clone());
        let mut var = 0.0;
        for (k, (name, g)) in model.dofs.iter().zip(&gains).enumerate() {
            let is_own = k == idx;
            if !is_own && *g == LocalGains::default() {
                continue;
            }
            let Some(x) = s.record.column(name) else {
                continue;
            };
            let band = reconstruct(x, dt, None).band;
            noise_only &= band.floor_is_noise_only();
            let terms: Vec<(usize, f64)> = [(0, g.disp.mean), (1, g.vel.mean)]
                .into_iter()
                .filter(|&(_, c)| c != 0.0)
                .collect();
            let spread = [(0, g.disp.var), (1, g.vel.var)];
            var += residual_noise_var(&band, dt, is_own, &terms, &spread, fc, derivative_response);
            if is_own {
                own.push((x, band));
            }
        }
        for (name, terms) in &inputs {
            let Some(x) = s.record.column(name) else {
                continue;
            };
            let band = reconstruct(x, dt, None).band;
            noise_only &= band.floor_is_noise_only();
            var += residual_noise_var(&band, dt, false, terms, &[], fc, derivative_response);
        }
        let n = s.usable();
        var_sum += var * n as f64;
        rows += n;
    }
    let snr = snr_db(own.iter().map(|(x, b)| (*x, b)));
    NoiseEstimate {
        residual_rms: if rows > 0 {
            (var_sum / rows as f64).sqrt()
        } else {
            0.0
        },
        snr_db: snr.map_or(f64::INFINITY, |s| s.db),
        snr_is_bound: snr.is_some_and(|s| s.lower_bound),
        noise_only,
        band_hz,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tfs_data::Record;
    use tfs_library::{ModelTerm, Term};

    /// The residual of DOF 0 of `model` on `s`'s usable rows.
    fn residual(model: &Model, s: &RecordStates) -> Vec<f64> {
        let set = tfs_library::ColumnSet::new(s);
        let n = s.record.len();
        let mut r: Vec<f64> = s.acc[0].clone();
        for t in &model.equations[0].terms {
            let v = tfs_library::evaluate_term(&t.term, &set).unwrap();
            for (ri, vi) in r.iter_mut().zip(v) {
                *ri -= t.coef * vi;
            }
        }
        r[s.margin..n - s.margin].to_vec()
    }

    /// A polynomial `M·(x − 1)³` written out (`M·x³ − 3M·x² + 3M·x`) on records that move about
    /// `x = 1`: its linear coefficient is 30,000 but its slope on the records is below 100. The
    /// estimate must follow what the noise actually leaves in the residual (the residual on the
    /// noisy record less that on the clean one, at the same cut-off): charged through the linear
    /// coefficient alone it came out about fifty times too large.
    #[test]
    fn noise_reaches_the_residual_through_the_local_slope_not_the_linear_coefficient() {
        let m = 1.0e4;
        let dofs = ["x"];
        let terms = [
            ("x^3", m),
            ("x^2", -3.0 * m),
            ("x", 3.0 * m),
            ("x'", -0.2),
            ("u", -1.0),
        ];
        let eq = tfs_library::Equation {
            dof: "x".into(),
            terms: terms
                .iter()
                .map(|(n, c)| ModelTerm::new(Term::parse(n, &dofs).unwrap(), *c))
                .collect(),
        };
        let model = Model::new(vec!["x".into()], vec![eq], "test").unwrap();
        let dt = 0.01;
        let t: Vec<f64> = (0..6000).map(|k| k as f64 * dt).collect();
        let tau = 2.0 * std::f64::consts::PI;
        let x: Vec<f64> = t
            .iter()
            .map(|&t| 1.0 + 0.04 * (tau * 1.3 * t).sin() + 0.03 * (tau * 0.45 * t + 0.3).sin())
            .collect();
        let u: Vec<f64> = t.iter().map(|&t| 0.5 * (tau * 0.8 * t).sin()).collect();
        let noisy =
            tfs_signal::noise::add_noise_seeded(&x, 40.0, tfs_signal::NoiseKind::White, 5).unwrap();
        let record = |name: &str, x: &[f64]| {
            Record::new(
                name,
                t.clone(),
                vec![("x".into(), x.to_vec()), ("u".into(), u.clone())],
            )
            .unwrap()
        };
        let opts = crate::DiagnoseOptions {
            cutoff_hz: Some(4.0),
            ..Default::default()
        };
        let clean = RecordStates::new(&model, &record("clean", &x), &opts).unwrap();
        let measured = RecordStates::new(&model, &record("noisy", &noisy), &opts).unwrap();
        let (a, b) = (residual(&model, &measured), residual(&model, &clean));
        let actual =
            (a.iter().zip(&b).map(|(p, q)| (p - q).powi(2)).sum::<f64>() / a.len() as f64).sqrt();
        let est = estimate(&model, 0, &[measured]).residual_rms;
        let ratio = est / actual;
        assert!(
            (0.67..1.5).contains(&ratio),
            "estimated {est:.4e} against the noise's own {actual:.4e} (ratio {ratio:.3})"
        );
    }
}
