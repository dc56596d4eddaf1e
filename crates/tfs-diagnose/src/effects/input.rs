//! Input effects: the exciter's dynamics between the recorded input and the structure. A
//! delayed or low-pass filtered copy of the input takes the input's place in the equation (and
//! its coefficient, the gain); it is never added beside it. Both are scanned on the input's own
//! time scale ([`EffectContext::input_period`]) and refined between grid values
//! (`polish.rs`).
//!
//! A model can have lost its input: when the input reaches the structure late or filtered, the
//! plain input may explain so little that the fit drops it, and then no term is left for the
//! effect to act on. When no equation of the model uses an input the records carry (by the data
//! contract's names, [`CONTRACT_INPUTS`]), the input effects offer that input, delayed or
//! filtered, as an added column instead ([`EffectContext::lost_inputs`]).

use tfs_library::{Factor, Model, Term, Var};

use super::{ComputedColumn, Effect, EffectColumn, EffectContext, Variant, round3};

/// Input delay and gain (shaker dynamics, a base motion that reaches the structure late): every
/// input term `u` is replaced by `u(t − δ)` — the delayed input takes the input's place (and its
/// coefficient, the gain), it is not added beside it; a model that lost the input gets `u(t − δ)`
/// added. δ is scanned over an eighth, a quarter and half a sample, then whole samples on a
/// geometric grid (ratio about 1.25) from one sample up to half the input's RMS-frequency period
/// ([`EffectContext::input_period`]): a longer delay is a sign flip of a narrow-band input. The
/// best δ is then refined between grid values (`polish.rs`); between samples the input is
/// read by band-limited interpolation ([`crate::effects::delayed`]).
#[derive(Debug, Clone, Copy)]
pub struct InputDelay;

/// Delays in samples below one sample, each about twice the last: a delay shorter than the
/// sampling step is common (an anti-alias filter's group delay, a skew between channels) and at
/// ten samples a period a few tenths of a sample already move the input force by several
/// percent.
const SUB_SAMPLE: [f64; 3] = [0.125, 0.25, 0.5];

/// Delays in samples: [`SUB_SAMPLE`], then whole samples from 1 up to `max`, each about 1.25
/// times the last.
fn delay_grid(max: usize) -> Vec<f64> {
    let mut out = vec![1];
    loop {
        let last = out[out.len() - 1];
        let next = ((last as f64 * 1.25).round() as usize).max(last + 1);
        if next > max {
            break;
        }
        out.push(next);
    }
    SUB_SAMPLE
        .iter()
        .copied()
        .chain(out.into_iter().map(|n| n as f64))
        .collect()
}

impl Effect for InputDelay {
    fn name(&self) -> String {
        "input-delay".into()
    }
    fn description(&self) -> String {
        "input delay and gain: u(t) replaced by u(t - delta), delta scanned from an eighth of a sample up to half the input's period, then refined between grid values".into()
    }
    fn variants(&self, ctx: &EffectContext<'_>) -> Vec<Variant> {
        let (inputs, added) = acted_on(ctx);
        if inputs.is_empty() || ctx.dt.is_nan() || ctx.dt <= 0.0 {
            return Vec::new();
        }
        let max = if ctx.input_period.is_finite() && ctx.input_period > 0.0 {
            (0.5 * ctx.input_period / ctx.dt).floor().max(1.0) as usize
        } else {
            1
        };
        delay_grid(max)
            .into_iter()
            .map(|n| input_variant(&inputs, "delay", round3(n * ctx.dt), added))
            .collect()
    }
}

/// The inputs an input effect acts on in the equation of `ctx`: the ones it uses linearly
/// (replaced), else the inputs the model lost (added, `true`).
fn acted_on(ctx: &EffectContext<'_>) -> (Vec<String>, bool) {
    let inputs = linear_inputs(&ctx.terms);
    if inputs.is_empty() {
        (ctx.lost_inputs.clone(), true)
    } else {
        (inputs, false)
    }
}

/// Input columns by the data contract: a base acceleration `xb_acc`, a force or drive `u`,
/// `force` or `voltage`.
pub const CONTRACT_INPUTS: [&str; 4] = ["xb_acc", "u", "force", "voltage"];

/// The inputs the records carry (by [`CONTRACT_INPUTS`]; `has` says whether every record has a
/// column) that no equation of `model` uses, not even through a delayed or filtered copy: the
/// inputs a fit dropped. Empty when the model uses any contract input, so the equations of a
/// chain that are driven through their neighbours are not offered the base's input.
pub fn lost_inputs(model: &Model, has: impl Fn(&str) -> bool) -> Vec<String> {
    let used = |name: &str| {
        model
            .inputs
            .iter()
            .any(|i| i == name || ComputedColumn::parse(i).is_some_and(|c| c.source() == name))
    };
    if CONTRACT_INPUTS.iter().any(|n| used(n)) {
        return Vec::new();
    }
    CONTRACT_INPUTS
        .iter()
        .filter(|n| has(n))
        .map(|n| n.to_string())
        .collect()
}

/// The variant putting the computed column with parameter `value` (`"delay"` or `"tau"`) of
/// every input in `inputs` in the equation: in the input's place, or added beside the
/// equation's terms when `added` (an input the model lost).
pub(crate) fn input_variant(
    inputs: &[String],
    parameter: &str,
    value: f64,
    added: bool,
) -> Variant {
    let column = |input: &String| {
        if parameter == "delay" {
            ComputedColumn::Delayed {
                input: input.clone(),
                delay: value,
            }
        } else {
            ComputedColumn::Lowpass {
                input: input.clone(),
                tau: value,
            }
        }
    };
    if added {
        return Variant::adding(
            Some((parameter.into(), value)),
            inputs
                .iter()
                .map(|i| EffectColumn::computed(column(i)))
                .collect(),
        );
    }
    Variant {
        parameter: Some((parameter.into(), value)),
        add: Vec::new(),
        replace: inputs
            .iter()
            .map(|i| {
                (
                    Term::var(Var::Input(i.clone())),
                    EffectColumn::computed(column(i)),
                )
            })
            .collect(),
    }
}

/// The inputs used linearly by an equation with terms `terms` (plain input columns, not
/// computed ones).
pub(crate) fn linear_inputs(terms: &[Term]) -> Vec<String> {
    terms
        .iter()
        .filter_map(|t| match t.factors() {
            [Factor::Pow(Var::Input(n), 1)] if ComputedColumn::parse(n).is_none() => {
                Some(n.clone())
            }
            _ => None,
        })
        .collect()
}

/// Input filter and gain (exciter or amplifier dynamics): every input term `u` is replaced by
/// `u` low-pass filtered with time constant τ (added, for a model that lost the input), τ scanned over 1 %..50 % of the input's
/// RMS-frequency period ([`EffectContext::input_period`]) and then refined (`polish.rs`);
/// the gain is the refitted input coefficient.
#[derive(Debug, Clone, Copy)]
pub struct InputFilter;
impl Effect for InputFilter {
    fn name(&self) -> String {
        "input-filter".into()
    }
    fn description(&self) -> String {
        "input filter and gain: u replaced by u low-pass filtered with time constant tau (first-order exciter/amplifier dynamics), tau scanned over 1 %..50 % of the input's period, then refined".into()
    }
    fn variants(&self, ctx: &EffectContext<'_>) -> Vec<Variant> {
        let (inputs, added) = acted_on(ctx);
        if inputs.is_empty() || !(ctx.input_period.is_finite() && ctx.input_period > 0.0) {
            return Vec::new();
        }
        [0.01, 0.02, 0.05, 0.1, 0.2, 0.5]
            .iter()
            .map(|r| round3(r * ctx.input_period))
            .filter(|&tau| tau >= 0.1 * ctx.dt)
            .map(|tau| input_variant(&inputs, "tau", tau, added))
            .collect()
    }
}
