//! One prediction score per record, chosen once for a set of models compared on it and applied
//! to each of them.
//!
//! A free run under the measured input is the plain score (`compare`'s R-MSE). On a record where
//! a fresh draw of the measured input's own noise moves the reference model's free run about as
//! far as its error (a multi-stable structure swept through chaotic snap-through: the noise picks
//! the well), the free-run R-MSE of any model — the true one included — says which well its run
//! ended in, not how close the model is. The same holds when it is one of the other models whose
//! run the noise times (a model nearer the truth can be the one that snaps through), so the
//! check is made for every model of the set, as the diagnosis's judge makes it for its
//! candidates. There the score is the **short-horizon** prediction
//! error the diagnosis's judge uses: the record cut into pieces as long as the reference model's
//! predictions keep their skill (at most two dominant periods, at least one cut-off period of
//! the smoothing), each simulated from the smoothed measured state at its start. The choice is
//! made once for the set and the piece length from the reference model alone, so every model
//! compared under one [`PredictionScore`] is scored by the same ruler.

use serde::{Deserialize, Serialize};
use tfs_data::Record;
use tfs_dynamics::SimulateOptions;
use tfs_library::Model;

use crate::prepare::{DiagnoseOptions, RecordStates, dominant_period};
use crate::{DiagnoseError, Result};

/// How predictions of one record are scored: a free run, or pieces of `horizon` samples each
/// started from the smoothed measured state ([`PredictionScore::choose`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PredictionScore {
    /// Piece length in samples; `None` for the free run over the whole record.
    pub horizon: Option<usize>,
    /// Why this score, in words.
    pub why: String,
}

impl PredictionScore {
    /// The free run over the whole record (`compare`'s R-MSE).
    pub fn free_run() -> Self {
        Self {
            horizon: None,
            why: "free-run simulation under the measured input".into(),
        }
    }

    /// Chooses the score for `record` when `reference` (e.g. the start model of a diagnosis) is
    /// compared with `others` on it: the free run, unless a fresh draw of the measured input's
    /// noise, or the run's own divergence, moves the free run of one of them about as far as
    /// its error ([`crate::simulate::noise_probe`]); then pieces as long as
    /// `reference`'s predictions from measured states keep their skill.
    pub fn choose(
        reference: &Model,
        others: &[&Model],
        record: &Record,
        opts: &DiagnoseOptions,
    ) -> Result<Self> {
        let dominated = std::iter::once(reference)
            .chain(others.iter().copied())
            .any(|m| crate::simulate::free_run_noise_dominated(m, record, opts));
        if !dominated {
            return Ok(Self::free_run());
        }
        Self::pieces(reference, record, opts)
    }

    /// Short-horizon pieces for `record`, as long as `reference`'s predictions from measured
    /// states keep their skill (at most two dominant periods, at least one cut-off period of
    /// the smoothing), whether or not the free run could rank models there.
    pub fn pieces(reference: &Model, record: &Record, opts: &DiagnoseOptions) -> Result<Self> {
        let states = RecordStates::new(reference, record, opts)?;
        let dt = record.dt();
        let mut period: f64 = 0.0;
        for d in &reference.dofs {
            let x = record
                .column(d)
                .ok_or_else(|| crate::prepare::missing(reference, record, d))?;
            period = period.max(dominant_period(x, dt)?);
        }
        let cap = ((2.0 * period / dt).round() as usize).max(16);
        let floor = (1.0 / (states.cutoff_hz * dt)).ceil().max(1.0) as usize;
        let h = crate::judge::divergence_horizon(
            reference,
            std::slice::from_ref(&states),
            opts,
            cap,
            floor,
        );
        Ok(Self {
            horizon: Some(h),
            why: format!(
                "a fresh draw of the measured input's noise, or the run's own divergence from a start one displacement-noise standard deviation away, moves a model's free run about as far as its error: predictions over pieces of {h} samples ({:.4} s) from the measured state",
                h as f64 * dt
            ),
        })
    }

    /// R-MSE of `model`'s predictions of `record` under this score (mean over DOFs of the
    /// summed squared error over the measured displacement's summed squared deviation from its
    /// mean). An error when the model cannot be simulated on the record.
    pub fn r_mse(&self, model: &Model, record: &Record, opts: &DiagnoseOptions) -> Result<f64> {
        self.r_mse_near(model, None, record, opts)
    }

    /// [`PredictionScore::r_mse`] of a model close to `near` (a refit of it): a free run's
    /// start-state fit begins at `near`'s fitted start ([`crate::simulate::r_mse_near`]);
    /// pieces start from the record's smoothed states and do not use it.
    pub(crate) fn r_mse_near(
        &self,
        model: &Model,
        near: Option<&Model>,
        record: &Record,
        opts: &DiagnoseOptions,
    ) -> Result<f64> {
        let Some(h) = self.horizon else {
            return crate::simulate::r_mse_near(model, record, &SimulateOptions::default(), near);
        };
        let states = RecordStates::new(model, record, opts)?;
        let rows = states.margin..states.margin + states.usable();
        crate::judge::predict_pieces(model, &states, rows, h, opts)
            .map(|p| p.0)
            .ok_or_else(|| DiagnoseError::Prediction {
                record: record.source().to_string(),
                horizon: h,
            })
    }

    /// A short label for tables: `free run` or `pieces of N samples`.
    pub fn label(&self) -> String {
        match self.horizon {
            None => "free run".into(),
            Some(h) => format!("pieces of {h} samples"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A linear oscillator driven by a sine: its free run is not noise-dominated, so the score
    /// is the free run and equals `r_mse`.
    #[test]
    fn a_regular_record_is_scored_by_its_free_run() {
        let m = Model::from_json_str(
            r#"{"format":"tfs-model/1","dofs":["x"],"equations":[{"dof":"x","terms":[{"term":"x","coef":-1},{"term":"x'","coef":-0.1},{"term":"u","coef":1}]}]}"#,
        )
        .unwrap();
        let dt = 0.02;
        let t: Vec<f64> = (0..3000).map(|k| k as f64 * dt).collect();
        let u: Vec<f64> = t.iter().map(|t| (0.7 * t).sin()).collect();
        let cols = |x: Vec<f64>| vec![("x".to_string(), x), ("u".to_string(), u.clone())];
        let rest = Record::new("r", t.clone(), cols(vec![0.0; t.len()])).unwrap();
        let tr = crate::simulate::simulate(&m, &rest).unwrap();
        let rec = Record::new("r", t.clone(), cols(tr.x[0].clone())).unwrap();
        let opts = DiagnoseOptions::default();
        let mut worse = m.clone();
        worse.equations[0].terms[0].coef = -1.2;
        let s = PredictionScore::choose(&m, &[&worse], &rec, &opts).unwrap();
        assert_eq!(s.horizon, None, "{}", s.why);
        assert_eq!(
            s.r_mse(&worse, &rec, &opts).unwrap(),
            crate::simulate::r_mse(&worse, &rec).unwrap()
        );
    }
}
