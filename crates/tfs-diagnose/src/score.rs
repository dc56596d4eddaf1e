//! Scoring one variant of an effect on one DOF's equation by held-out equation error: its
//! columns, design, compressed blocks and cross-validation; the main column's coefficient with
//! its block-bootstrap interval; and, for an effect whose parameter `refit` chooses by
//! simulation, the shortlist of the next variants by held-out residual.
//!
//! The primitives every stage of the scan is built on (`scan.rs`, `readmit.rs`, `polish.rs`,
//! `judged.rs`, `null.rs`); they know nothing of the stages.
//!
//! The shortlist: the equation error scores every variant of an effect and keeps the one with the
//! lowest held-out residual. For most effects that is also the model `refit --add` returns. Not
//! for a stop: the smoothing that makes the equation error usable spreads a contact's force over
//! the samples around it, so the residual's best position can lie well inside the true one, and
//! `refit` chooses the position among those with the lowest residual by how well the model
//! simulates the records ([`crate::effects::Effect::parameter_by_simulation`]). The judge then
//! judges what `refit` will return: the variants with the [`SHORTLIST`] lowest held-out residuals
//! are each simulated (`judged.rs`), and the one that predicts the held-out data best speaks for
//! the effect. Its significance is still the equation error's (the tests over blocks are
//! corrected over every variant scanned, so choosing among a few of them adds no test).

use tfs_library::Term;
use tfs_regress::Compressed;

use crate::Result;
use crate::design::{
    Cv, Design, compress_blocks, cross_validate, design, full_fit, variant_columns,
};
use crate::effects::{EffectColumn, Variant};
use crate::prepare::{DiagnoseOptions, Layout, RecordStates};
use crate::stats::bootstrap_interval;

/// One variant scored: its columns, design, compressed blocks and cross-validation.
pub(crate) struct Scored {
    pub variant: Variant,
    pub cols: Vec<EffectColumn>,
    pub main: Option<usize>,
    pub blocks: Vec<Compressed>,
    pub design: Design,
    pub cv: Cv,
    /// Held-out residual sum of squares over all blocks.
    pub cv_rss: f64,
}

impl Scored {
    /// The same without its design (a matrix of the usable rows of every record per column):
    /// what is read after a variant is scored — the columns, blocks, cross-validation — is
    /// small, and a scan keeps many scored variants (the shortlist of a stop's positions, every
    /// effect's best until the ranking).
    pub(crate) fn lean(self) -> Self {
        Self {
            design: Design::empty(),
            ..self
        }
    }

    /// A copy of [`Scored::lean`]'s, leaving this one whole.
    pub(crate) fn lean_copy(&self) -> Self {
        Self {
            variant: self.variant.clone(),
            cols: self.cols.clone(),
            main: self.main,
            blocks: self.blocks.clone(),
            design: Design::empty(),
            cv: Cv {
                coefs: self.cv.coefs.clone(),
                heldout: self.cv.heldout.clone(),
            },
            cv_rss: self.cv_rss,
        }
    }
}

/// Scores variant `v` on the equation of DOF `idx` with the terms `base`.
pub(crate) fn score_variant(
    states: &[RecordStates],
    layout: &Layout,
    idx: usize,
    base: &[Term],
    v: &Variant,
) -> Result<Scored> {
    let (cols, main) = variant_columns(base, v);
    let design = design(states, idx, &cols)?;
    let blocks = compress_blocks(&design, layout)?;
    let cv = cross_validate(&blocks, layout)?;
    let cv_rss = if pulls_into_contact(states, idx, &cols, main, &blocks)? {
        f64::INFINITY
    } else {
        cv.heldout.iter().sum()
    };
    Ok(Scored {
        variant: v.clone(),
        cols,
        main,
        blocks,
        design,
        cv,
        cv_rss,
    })
}

/// True when the variant's main column is a stop whose full-data fit on the equation of DOF `idx`
/// pulls its coordinate into the contact ([`crate::effects::stop_pushes_out`]): such a variant is
/// a kink the equation error fitted, not a stop, and is scored as fitting nothing (an infinite
/// held-out residual), so no stage of the scan or the refit chooses it.
fn pulls_into_contact(
    states: &[RecordStates],
    idx: usize,
    cols: &[EffectColumn],
    main: Option<usize>,
    blocks: &[Compressed],
) -> Result<bool> {
    let (Some(m), Some(dof)) = (main, states.first().and_then(|s| s.dofs.get(idx))) else {
        return Ok(false);
    };
    let Some(col) = cols.get(m).filter(|c| c.computed.is_none()) else {
        return Ok(false);
    };
    if crate::effects::stop_pushes_out(&col.term, dof, 1.0).is_none() {
        return Ok(false);
    }
    let coef = full_fit(blocks)?[m];
    Ok(crate::effects::stop_pushes_out(&col.term, dof, coef) == Some(false))
}

/// The coefficient of the main effect column of `s` in its full-data fit `coef` and its block
/// bootstrap interval (NaN when the variant has no main column).
pub(crate) fn main_coefficient(
    s: &Scored,
    coef: &[f64],
    opts: &DiagnoseOptions,
) -> Result<(f64, [f64; 2])> {
    Ok(match s.main {
        Some(m) => (
            coef[m],
            bootstrap_interval(&s.blocks, m, opts.bootstrap, opts.seed)?,
        ),
        None => (f64::NAN, [f64::NAN, f64::NAN]),
    })
}

/// How many variants, lowest held-out residual first, the judge simulates for an effect whose
/// parameter is chosen by simulation.
pub(crate) const SHORTLIST: usize = 3;

/// A variant beside the best one by equation error, with the coefficient of its main column in
/// its full-data fit and that coefficient's block-bootstrap interval (what the report shows when
/// the judge chooses it).
pub(crate) struct Alternative {
    /// The variant scored.
    pub scored: Scored,
    /// The main column's coefficient.
    pub coef: f64,
    /// Its 95 % block-bootstrap interval.
    pub interval: [f64; 2],
}

/// The variants other than `chosen` among `scanned` (every variant of an effect scored on one
/// equation, [`crate::polish::best_variant_with`]), the [`SHORTLIST`]` − 1` with the lowest
/// held-out residual first (ties in the catalogue's order), each with its main coefficient and
/// interval.
pub(crate) fn alternatives(
    scanned: Vec<Scored>,
    chosen: &Variant,
    opts: &DiagnoseOptions,
) -> Result<Vec<Alternative>> {
    let mut scored: Vec<Scored> = scanned
        .into_iter()
        .filter(|s| s.variant != *chosen)
        .collect();
    scored.retain(|s| s.cv_rss.is_finite());
    scored.sort_by(|a, b| a.cv_rss.total_cmp(&b.cv_rss));
    scored.truncate(SHORTLIST.saturating_sub(1));
    scored
        .into_iter()
        .map(|s| {
            let fit = full_fit(&s.blocks)?;
            let (coef, interval) = main_coefficient(&s, &fit, opts)?;
            Ok(Alternative {
                scored: s,
                coef,
                interval,
            })
        })
        .collect()
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use tfs_library::{Equation, Model, ModelTerm};

    /// Smoothed states of a forced oscillator `x'' = -x - 0.2 x' + k·above(x, 0.3) + xb_acc`
    /// (semi-implicit Euler at a fine step, sampled every 10 ms), and the model without the stop.
    pub(crate) fn oscillator(k: f64) -> (Vec<RecordStates>, Layout) {
        let dofs = ["x"];
        let (h, sub, n) = (0.001, 10, 6000);
        let (mut x, mut v) = (0.0_f64, 0.0_f64);
        let (mut t, mut xs, mut us) = (Vec::new(), Vec::new(), Vec::new());
        let force = |s: f64| 0.8 * (1.1 * s).sin() + 0.5 * (0.37 * s + 0.02 * s * s).sin();
        for i in 0..n * sub {
            let s = i as f64 * h;
            if i % sub == 0 {
                t.push(s);
                xs.push(x);
                us.push(force(s));
            }
            let a = -x - 0.2 * v + k * (x - 0.3).max(0.0) + force(s);
            v += h * a;
            x += h * v;
        }
        let rec = tfs_data::Record::new(
            "osc",
            t,
            vec![("x".to_string(), xs), ("xb_acc".to_string(), us)],
        )
        .unwrap();
        let eq = Equation {
            dof: "x".into(),
            terms: [("x", -1.0), ("x'", -0.2), ("xb_acc", 1.0)]
                .iter()
                .map(|(t, c)| ModelTerm::new(Term::parse(t, &dofs).unwrap(), *c))
                .collect(),
        };
        let model = Model::new(vec!["x".into()], vec![eq], "test").unwrap();
        let opts = DiagnoseOptions::default();
        let states = vec![RecordStates::new(&model, &rec, &opts).unwrap()];
        let layout = Layout::new(&states, &opts).unwrap();
        (states, layout)
    }

    /// The start equation's terms of [`oscillator`] (`x, x', xb_acc`) and the stop
    /// `above(x, 0.3)` as a variant.
    pub(crate) fn stop_above() -> (Vec<Term>, Variant) {
        let base: Vec<Term> = ["x", "x'", "xb_acc"]
            .iter()
            .map(|t| Term::parse(t, &["x"]).unwrap())
            .collect();
        let stop = Variant::adding(
            Some(("c".into(), 0.3)),
            vec![EffectColumn::term(
                Term::parse("above(x, 0.3)", &["x"]).unwrap(),
            )],
        );
        (base, stop)
    }

    /// The stop `above(x, 0.3)` scored on data whose force past 0.3 pushes back (k < 0) is a
    /// stop with a finite held-out residual; on data whose force there pulls further out (k > 0,
    /// a softening kink) its fit pulls into the contact and it is refused: scored as fitting
    /// nothing (the stop effect then has no best variant: `polish`'s tests).
    #[test]
    fn a_stop_fitted_pulling_into_its_contact_is_refused() {
        let (base, stop) = stop_above();
        let (states, layout) = oscillator(-5.0);
        let s = score_variant(&states, &layout, 0, &base, &stop).unwrap();
        assert!(s.cv_rss.is_finite(), "a pushing stop is scored");
        let coef = full_fit(&s.blocks).unwrap()[s.main.unwrap()];
        assert!(coef < -1.0, "its stiffness pushes down: {coef}");

        let (states, layout) = oscillator(0.6);
        let s = score_variant(&states, &layout, 0, &base, &stop).unwrap();
        assert_eq!(s.cv_rss, f64::INFINITY, "a pulling stop is refused");
        let coef = full_fit(&s.blocks).unwrap()[s.main.unwrap()];
        assert!(coef > 0.0, "the data pull the wrong way: {coef}");
    }
}
