//! Simulation as `tfs simulate` and the Python package do it: the Kresling cell and chain records
//! (excitations by their text form), and a model run from a given state under a sampled input.

use tfs_dynamics::{Dopri5, Integrator, SampledInput, Trajectory};
use tfs_library::Model;
use tfs_origami::{
    CellSpec, Dataset, DatasetConfig, Excitation, KreslingParams, NoiseKind, SystemSpec, Truth,
    generate,
};

use crate::error::{Context, Result};
use crate::invalid;

/// Parses an excitation `sweep:F0:F1:AMP` (linear sweep, Hz, acceleration) or `sine:F:AMP`, with
/// ramp-in/out time `ramp` (s).
pub fn parse_excitation(text: &str, ramp: f64) -> Result<Excitation> {
    let parts: Vec<&str> = text.split(':').collect();
    let num = |s: &str| -> Result<f64> {
        match s.parse::<f64>() {
            Ok(v) => Ok(v),
            Err(_) => invalid!("--excitation '{text}': '{s}' is not a number"),
        }
    };
    match parts.as_slice() {
        ["sweep", f0, f1, amp] => Ok(Excitation::Sweep {
            f0: num(f0)?,
            f1: num(f1)?,
            amplitude: num(amp)?,
            log: false,
            ramp,
        }),
        ["sine", f, amp] => Ok(Excitation::Sine {
            freq: num(f)?,
            amplitude: num(amp)?,
            phase: 0.0,
            ramp,
        }),
        _ => invalid!("--excitation '{text}': expected sweep:F0:F1:AMP or sine:F:AMP"),
    }
}

/// The excitation of `tfs simulate kresling` when none is given: one slow sweep of base
/// acceleration through the cell's resonances, large enough to snap it between its states.
pub const CELL_EXCITATIONS: [&str; 1] = ["sweep:0.05:1.5:4"];
/// The record length (s) of `tfs simulate kresling` when none is given.
pub const CELL_DURATION: f64 = 100.0;
/// The excitations of `tfs simulate chain` when none is given: four sweeps of base acceleration
/// over 0.05–1.5 Hz at 1.5 … 3, each large enough to carry the cells across their ranges (the
/// bistable cell across its barrier) and short enough ([`CHAIN_DURATION`]) to pass each
/// resonance in a few cycles. The one-cell sweep (amplitude 4 over 100 s) presses a chain onto
/// its folded stop cycle after cycle at the slow start (0.05–0.4 Hz is nearly static and the
/// load exceeds what the cells can hold up): most of the recorded acceleration is then contact,
/// which no polynomial force law represents. Several records also give the identification
/// held-out records of the same kind instead of two halves of one sweep.
pub const CHAIN_EXCITATIONS: [&str; 4] = [
    "sweep:0.05:1.5:1.5",
    "sweep:0.05:1.5:2",
    "sweep:0.05:1.5:2.5",
    "sweep:0.05:1.5:3",
];
/// The record length (s) of `tfs simulate chain` when none is given (see [`CHAIN_EXCITATIONS`]).
pub const CHAIN_DURATION: f64 = 50.0;

/// What `tfs simulate kresling|chain` is asked, with its defaults.
#[derive(Debug, Clone, PartialEq)]
pub struct DatasetRequest {
    /// γ0 of each cell (degrees), base cell first; one angle is a single cell (DOF `x`),
    /// several a chain (DOFs `x1..xN`).
    pub gamma0: Vec<f64>,
    /// Whether to simulate a chain (DOFs `x1..xN`) even of one cell.
    pub chain: bool,
    /// The force law; `None`: the surrogate for one cell, the truss for a chain (a cell's
    /// surrogate polynomial holds on 0 ≤ h ≤ 1.7 and has no folded stop).
    pub truth: Option<Truth>,
    /// One record per excitation (`sweep:F0:F1:AMP` or `sine:F:AMP`).
    pub excitations: Vec<String>,
    /// Record length (s).
    pub duration: f64,
    /// Sampling interval (s).
    pub dt: f64,
    /// Ramp-in/out time of the excitation (s).
    pub ramp: f64,
    /// SNR (dB) of the noise on every measured channel; `None` for clean data.
    pub snr_db: Option<f64>,
    /// Pink (1/f) instead of white noise.
    pub pink: bool,
    /// Noise seed.
    pub seed: u64,
}

impl Default for DatasetRequest {
    fn default() -> Self {
        Self {
            gamma0: vec![30.0],
            chain: false,
            truth: None,
            excitations: CELL_EXCITATIONS.iter().map(|e| e.to_string()).collect(),
            duration: CELL_DURATION,
            dt: 0.005,
            ramp: 2.0,
            snr_db: None,
            pink: false,
            seed: 1,
        }
    }
}

/// The most samples one simulated record may have (about a gigabyte of columns and integrator
/// output for one cell): a size a user sets must not run the machine out of memory.
pub const MAX_SAMPLES: f64 = 10_000_000.0;

/// Refuses a duration and sampling interval that are not positive and finite, or that would
/// produce more than [`MAX_SAMPLES`] samples per record.
fn check_size(duration: f64, dt: f64) -> Result<()> {
    if !(duration.is_finite() && duration > 0.0) {
        invalid!("--duration {duration}: give a positive number of seconds");
    }
    if !(dt.is_finite() && dt > 0.0) {
        invalid!("--dt {dt}: give a positive sampling interval in seconds");
    }
    let n = (duration / dt).round() + 1.0;
    if n > MAX_SAMPLES {
        invalid!(
            "--duration {duration} --dt {dt}: a record would have {n:.4e} samples; at most {MAX_SAMPLES:.0} are allowed per record (memory grows with it): shorten --duration or raise --dt"
        );
    }
    if n < 16.0 {
        invalid!(
            "--duration {duration} --dt {dt}: a record would have only {n} samples; give at least 16 (a longer --duration or a smaller --dt)"
        );
    }
    Ok(())
}

/// Simulates the records a [`DatasetRequest`] asks for.
pub fn dataset(req: &DatasetRequest) -> Result<Dataset> {
    check_size(req.duration, req.dt)?;
    if req.gamma0.is_empty() {
        invalid!("--gamma0: give at least one cell angle");
    }
    let truth = req.truth.unwrap_or(if req.chain {
        Truth::Truss
    } else {
        Truth::Surrogate
    });
    let specs: Vec<CellSpec> = req
        .gamma0
        .iter()
        .map(|g| CellSpec {
            params: KreslingParams {
                gamma0_deg: *g,
                ..KreslingParams::default()
            },
            truth,
            ..CellSpec::default()
        })
        .collect();
    let system = if req.chain {
        SystemSpec::Chain { cells: specs }
    } else {
        if specs.len() != 1 {
            invalid!("--gamma0: a single cell takes one angle; simulate a chain for several");
        }
        SystemSpec::Kresling(specs[0].clone())
    };
    let excitations = req
        .excitations
        .iter()
        .map(|e| parse_excitation(e, req.ramp))
        .collect::<Result<Vec<_>>>()?;
    let cfg = DatasetConfig {
        system,
        excitations,
        duration: req.duration,
        dt: req.dt,
        snr_db: req.snr_db,
        noise: if req.pink {
            NoiseKind::Pink
        } else {
            NoiseKind::White
        },
        seed: req.seed,
        ..DatasetConfig::default()
    };
    match generate(&cfg) {
        Ok(d) => Ok(d),
        // The surrogate's advice belongs to a run that diverged, not to every error.
        Err(e @ tfs_origami::OrigamiError::Simulation { .. }) if truth == Truth::Surrogate => {
            Err::<Dataset, _>(e).context(
                "simulating the dataset (the surrogate force is a polynomial fitted on 0 ≤ h ≤ 1.7 \
                 without the folded stop: lower the excitation amplitude or use --truth truss)",
            )
        }
        Err(e) => Err::<Dataset, _>(e).context("simulating the dataset"),
    }
}

/// How one cell of one simulated record met its folded stop (relative height `h < 0`).
#[derive(Debug, Clone, PartialEq)]
pub struct StopContact {
    /// The record's source name.
    pub record: String,
    /// The cell (1-based, base cell first).
    pub cell: usize,
    /// Share of the samples with `h < 0`.
    pub share: f64,
    /// The lowest `h` reached.
    pub min_h: f64,
}

/// The folded-stop contacts of every truss cell in every record of `data` (a surrogate cell has
/// no stop), from the clean displacement columns (`x_clean`, or `x1_clean`, `x2_clean`, … whose
/// differences are the cells' heights).
pub fn stop_contacts(data: &Dataset) -> Vec<StopContact> {
    let cells = match &data.meta.config.system {
        SystemSpec::Kresling(c) => std::slice::from_ref(c),
        SystemSpec::Chain { cells } => &cells[..],
    };
    let has_stop = |cell: usize| cells.get(cell).is_some_and(|c| c.truth == Truth::Truss);
    let mut out = Vec::new();
    for r in &data.records {
        let mut below: Option<Vec<f64>> = None;
        let mut cell = 0;
        loop {
            let name = if cell == 0 && r.column("x_clean").is_some() {
                "x_clean".to_string()
            } else {
                format!("x{}_clean", cell + 1)
            };
            let Some(x) = r.column(&name) else { break };
            let h: Vec<f64> = match &below {
                Some(b) => x.iter().zip(b).map(|(a, b)| a - b).collect(),
                None => x.to_vec(),
            };
            let n = h.len().max(1) as f64;
            if has_stop(cell) {
                out.push(StopContact {
                    record: r.source().to_string(),
                    cell: cell + 1,
                    share: h.iter().filter(|v| **v < 0.0).count() as f64 / n,
                    min_h: h.iter().cloned().fold(f64::INFINITY, f64::min),
                });
            }
            if name == "x_clean" {
                break;
            }
            below = Some(x.to_vec());
            cell += 1;
        }
    }
    out
}

/// Simulates `model` from `x0`, `v0` at the uniformly spaced times `t` under the inputs `u` (one
/// column per name of `model.inputs`, sampled at `t`, interpolated by a cubic spline between
/// samples), with the adaptive Dormand–Prince integrator. A run that blows up is an error that
/// carries the time and the state ([`crate::Error::blow_up`]).
pub fn simulate_model(
    model: &Model,
    t: &[f64],
    u: Vec<Vec<f64>>,
    x0: &[f64],
    v0: &[f64],
) -> Result<Trajectory> {
    let computed = tfs_diagnose::effects::computed_columns(model);
    if let Some(c) = computed.first() {
        invalid!(
            "the model has the computed column '{}' (an effect added by refit); simulate it on a record with compare, which computes that column from the record",
            c.name()
        );
    }
    if t.len() < 2 {
        invalid!("t has {} samples; give at least 2 times", t.len());
    }
    let dt = (t[t.len() - 1] - t[0]) / (t.len() - 1) as f64;
    if !(dt.is_finite() && dt > 0.0) {
        invalid!("t must increase and be finite");
    }
    if let Some(k) = (1..t.len()).find(|&k| ((t[k] - t[k - 1]) - dt).abs() > 1e-6 * dt) {
        invalid!(
            "t is not uniformly spaced at sample {k} (step {:e} s, mean {dt:e} s); the input is interpolated on a uniform grid",
            t[k] - t[k - 1]
        );
    }
    let n = model.dofs.len();
    if u.len() != model.inputs.len() {
        invalid!(
            "u has {} column(s) but the model takes {} input(s) [{}]",
            u.len(),
            model.inputs.len(),
            model.inputs.join(", ")
        );
    }
    for (name, col) in model.inputs.iter().zip(&u) {
        if col.len() != t.len() {
            invalid!(
                "input '{name}' has {} samples but t has {}; sample every input at t",
                col.len(),
                t.len()
            );
        }
        if let Some(k) = col.iter().position(|v| !v.is_finite()) {
            invalid!("input '{name}' is not finite at sample {k}");
        }
    }
    if x0.len() != n || v0.len() != n {
        invalid!(
            "x0 and v0 need one value per DOF ({n}: [{}]); got {} and {}",
            model.dofs.join(", "),
            x0.len(),
            v0.len()
        );
    }
    let compiled = model.compile()?;
    let input = SampledInput::new(t[0], dt, u)?;
    // Internal states (Maxwell elements, hysteresis, Dahl friction) start at rest.
    let (mut x0, mut v0) = (x0.to_vec(), v0.to_vec());
    x0.resize(compiled.system_dofs(), 0.0);
    v0.resize(compiled.system_dofs(), 0.0);
    let mut tr = Dopri5::default().integrate(&compiled, &input, &x0, &v0, t)?;
    tr.x.truncate(n);
    tr.v.truncate(n);
    Ok(tr)
}

/// The accelerations `x''` the model gives at `rows` states: per row the displacements `x`
/// and velocities `v` (one per DOF) and the inputs `u` (one per name of `model.inputs`).
/// Returns one row of accelerations (one per DOF) per state.
pub fn predict(model: &Model, x: &[f64], v: &[f64], u: &[f64], rows: usize) -> Result<Vec<f64>> {
    let (n, m) = (model.dofs.len(), model.inputs.len());
    if x.len() != rows * n || v.len() != rows * n || u.len() != rows * m {
        invalid!(
            "predict: {rows} state(s) need x and v of {rows}×{n} and u of {rows}×{m} values (DOFs [{}], inputs [{}])",
            model.dofs.join(", "),
            model.inputs.join(", ")
        );
    }
    let compiled = model.compile()?;
    if compiled.states() > 0 {
        invalid!(
            "predict: the model has internal states ({}); its acceleration depends on the motion's history, not on one state: simulate it instead",
            model
                .internal_states()
                .iter()
                .map(
                    |(v, l)| tfs_library::Term::new(vec![tfs_library::Factor::State(
                        v.clone(),
                        *l
                    )])
                    .to_string()
                )
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    let mut out = vec![0.0; rows * n];
    for k in 0..rows {
        compiled.try_accel(
            &x[k * n..(k + 1) * n],
            &v[k * n..(k + 1) * n],
            &u[k * m..(k + 1) * m],
            &mut out[k * n..(k + 1) * n],
        )?;
    }
    Ok(out)
}
