//! Synthetic datasets: base-acceleration sweeps and sines applied to a cell or a chain,
//! simulated with the adaptive Dormand–Prince integrator of `tfs-dynamics`, then noised per
//! measured channel at a given SNR, returned as [`tfs_data::Record`]s plus serialisable metadata.
//!
//! Columns (DESIGN §5): `t`, `x` (one cell) or `x1..xN` (chain), `xb_acc` — the measured,
//! possibly noisy channels — and, kept apart, the clean truth `x_clean`, `xb_acc_clean`,
//! `x_vel_clean`, `x_acc_clean` (or `x1_clean`, `x1_vel_clean`, …). The simulation is driven by
//! the clean sampled `xb_acc` (not-a-knot cubic spline between samples, `tfs_dynamics::SampledInput`),
//! so the clean columns are exactly what the integrated system saw; `x_acc_clean` is the model's
//! acceleration evaluated at the sampled clean state and input.

use serde::{Deserialize, Serialize};
use std::sync::Arc;
use tfs_data::Record;
use tfs_dynamics::{Dopri5, Integrator, SampledInput, SecondOrderSystem};
use tfs_signal::{Sine, Sweep, SweepKind};

use crate::cell::{CellOptions, KreslingCell};
use crate::geometry::KreslingParams;
use crate::system::{CellSystem, Chain};
use crate::truth::{CellForce, Surrogate, SurrogateSpec, Truth};
use crate::{OrigamiError, Result};

/// One cell of a simulated system: parameters, truth and numerical options.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(default)]
pub struct CellSpec {
    /// Crease and material parameters.
    pub params: KreslingParams,
    /// Which force law is simulated.
    pub truth: Truth,
    /// Table and stop options (truss).
    pub options: CellOptions,
    /// Surrogate fitting spec (used when `truth` is `surrogate`).
    pub surrogate: SurrogateSpec,
}

/// The simulated structure.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum SystemSpec {
    /// One Kresling cell (DOF `x`).
    Kresling(CellSpec),
    /// A serial chain, base cell first (DOFs `x1..xN`).
    Chain {
        /// The cells.
        cells: Vec<CellSpec>,
    },
}

impl Default for SystemSpec {
    fn default() -> Self {
        SystemSpec::Kresling(CellSpec::default())
    }
}

impl SystemSpec {
    fn cells(&self) -> &[CellSpec] {
        match self {
            SystemSpec::Kresling(c) => std::slice::from_ref(c),
            SystemSpec::Chain { cells } => cells,
        }
    }

    /// DOF column names: `["x"]` for one cell, `["x1", …, "xN"]` for a chain.
    pub fn dof_names(&self) -> Vec<String> {
        match self {
            SystemSpec::Kresling(_) => vec!["x".into()],
            SystemSpec::Chain { cells } => (1..=cells.len()).map(|i| format!("x{i}")).collect(),
        }
    }
}

/// Builds the simulated system (always a [`Chain`]; a one-cell chain equals the cell exactly).
pub fn build_system(spec: &SystemSpec) -> Result<Chain> {
    let cells = spec
        .cells()
        .iter()
        .enumerate()
        .map(|(i, c)| {
            let cell = KreslingCell::with_options(c.params, c.options).map_err(|e| match e {
                OrigamiError::Param(m) => OrigamiError::Param(format!("cell {}: {m}", i + 1)),
                other => other,
            })?;
            let force = match c.truth {
                Truth::Truss => CellForce::Truss(Arc::new(cell)),
                Truth::Surrogate => CellForce::Surrogate(Surrogate::fit(&cell, &c.surrogate)?),
            };
            CellSystem::from_force(force, c.params.m, c.params.c)
        })
        .collect::<Result<Vec<_>>>()?;
    Chain::new(cells)
}

/// A base-acceleration signal for one record (starts at `t = 0`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum Excitation {
    /// Frequency sweep over the whole record, `f0 → f1` Hz, amplitude in acceleration units.
    Sweep {
        /// Start frequency (Hz).
        f0: f64,
        /// End frequency (Hz).
        f1: f64,
        /// Acceleration amplitude.
        amplitude: f64,
        /// Logarithmic (true) or linear (false, default) frequency law.
        #[serde(default)]
        log: bool,
        /// Linear ramp-in/out time (s), default 0.
        #[serde(default)]
        ramp: f64,
    },
    /// Sine of constant frequency.
    Sine {
        /// Frequency (Hz).
        freq: f64,
        /// Acceleration amplitude.
        amplitude: f64,
        /// Phase (rad), default 0.
        #[serde(default)]
        phase: f64,
        /// Linear ramp-in time (s), default 0.
        #[serde(default)]
        ramp: f64,
    },
}

impl std::str::FromStr for Excitation {
    type Err = OrigamiError;
    /// Parses the CLI form `sweep:F0,F1,AMP[,log][,ramp=R]` or `sine:FREQ,AMP[,phase=P][,ramp=R]`
    /// (Hz, acceleration units, seconds, radians), e.g. `sweep:0.5,5,4` or `sine:1.2,3,ramp=2`.
    fn from_str(s: &str) -> Result<Self> {
        let bad = |why: &str| {
            OrigamiError::Param(format!(
                "excitation '{s}': {why}; use 'sweep:F0,F1,AMP[,log][,ramp=R]' or 'sine:FREQ,AMP[,phase=P][,ramp=R]'"
            ))
        };
        let (kind, rest) = s.trim().split_once(':').ok_or_else(|| bad("missing ':'"))?;
        let mut nums = Vec::new();
        let (mut log, mut ramp, mut phase) = (false, 0.0, 0.0);
        for part in rest.split(',').map(str::trim) {
            let num = |v: &str| {
                v.parse::<f64>()
                    .map_err(|_| bad(&format!("'{v}' is not a number")))
            };
            if part == "log" {
                log = true;
            } else if let Some(v) = part.strip_prefix("ramp=") {
                ramp = num(v)?;
            } else if let Some(v) = part.strip_prefix("phase=") {
                phase = num(v)?;
            } else {
                nums.push(num(part)?);
            }
        }
        match (kind.trim().to_ascii_lowercase().as_str(), nums.as_slice()) {
            ("sweep", [f0, f1, amplitude]) => Ok(Excitation::Sweep {
                f0: *f0,
                f1: *f1,
                amplitude: *amplitude,
                log,
                ramp,
            }),
            ("sine", [freq, amplitude]) if !log => Ok(Excitation::Sine {
                freq: *freq,
                amplitude: *amplitude,
                phase,
                ramp,
            }),
            ("sweep", _) => Err(bad("a sweep needs exactly F0, F1 and AMP")),
            ("sine", _) => Err(bad("a sine needs exactly FREQ and AMP (no 'log')")),
            (k, _) => Err(bad(&format!("unknown kind '{k}'"))),
        }
    }
}

impl Excitation {
    fn sample(&self, t: &[f64], duration: f64) -> Result<Vec<f64>> {
        use tfs_signal::Excitation as E;
        let s = match *self {
            Excitation::Sweep {
                f0,
                f1,
                amplitude,
                log,
                ramp,
            } => {
                let kind = if log {
                    SweepKind::Log
                } else {
                    SweepKind::Linear
                };
                E::sample(&Sweep::new(kind, f0, f1, duration, amplitude, ramp)?, t)
            }
            Excitation::Sine {
                freq,
                amplitude,
                phase,
                ramp,
            } => E::sample(&Sine::new(freq, amplitude, phase, ramp)?, t),
        };
        Ok(s)
    }
}

/// Spectral colour of the measurement noise.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum NoiseKind {
    /// White Gaussian.
    #[default]
    White,
    /// Pink (1/f) Gaussian.
    Pink,
}

/// Everything needed to generate a dataset (maps onto `tfs simulate kresling|chain` flags).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct DatasetConfig {
    /// The structure and its truth.
    pub system: SystemSpec,
    /// One record per excitation.
    pub excitations: Vec<Excitation>,
    /// Record length (s).
    pub duration: f64,
    /// Sampling interval (s).
    pub dt: f64,
    /// SNR in dB of the noise added to every measured channel (`None`: no noise).
    pub snr_db: Option<f64>,
    /// Noise colour.
    pub noise: NoiseKind,
    /// Seed of all noise (each record and channel gets its own derived stream).
    pub seed: u64,
    /// Initial displacements; `None`: every cell at its lowest stable state.
    pub x0: Option<Vec<f64>>,
    /// Initial velocities; `None`: zero.
    pub v0: Option<Vec<f64>>,
    /// Relative tolerance of the Dormand–Prince integrator.
    pub rtol: f64,
}

impl Default for DatasetConfig {
    /// One γ0 = 30° truss cell, one 0.5→5 Hz sweep of amplitude 4, 60 s at 100 Hz, no noise.
    fn default() -> Self {
        Self {
            system: SystemSpec::default(),
            excitations: vec![Excitation::Sweep {
                f0: 0.5,
                f1: 5.0,
                amplitude: 4.0,
                log: false,
                ramp: 1.0,
            }],
            duration: 60.0,
            dt: 0.01,
            snr_db: None,
            noise: NoiseKind::White,
            seed: 0,
            x0: None,
            v0: None,
            rtol: 1e-9,
        }
    }
}

/// Metadata of one record.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RecordMeta {
    /// Record name (also the `Record`'s source).
    pub name: String,
    /// The excitation.
    pub excitation: Excitation,
    /// Initial displacements and velocities.
    pub x0: Vec<f64>,
    /// Initial velocities.
    pub v0: Vec<f64>,
    /// Derived noise seed of this record (channel `c` uses `seed + c`).
    pub noise_seed: u64,
}

/// Metadata of a dataset (serialisable to JSON beside the CSV files).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DatasetMeta {
    /// Truth label(s): `"truss"`, `"surrogate{5,6,7}"`, comma-joined for chains.
    pub truth: String,
    /// Fitted surrogate coefficients per cell (empty for truss cells).
    pub surrogate_coefs: Vec<Vec<f64>>,
    /// The full configuration.
    pub config: DatasetConfig,
    /// Integrator used.
    pub integrator: String,
    /// Measured (noisy) column names.
    pub measured: Vec<String>,
    /// Clean truth column names.
    pub clean: Vec<String>,
    /// Per-record metadata.
    pub records: Vec<RecordMeta>,
}

/// A generated dataset.
#[derive(Debug, Clone)]
pub struct Dataset {
    /// The records.
    pub records: Vec<Record>,
    /// Metadata.
    pub meta: DatasetMeta,
}

fn splitmix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

fn check_config(cfg: &DatasetConfig, dofs: usize) -> Result<()> {
    if !(cfg.duration.is_finite() && cfg.duration > 0.0) {
        return Err(OrigamiError::Param(format!(
            "'duration' = {} s must be > 0",
            cfg.duration
        )));
    }
    if !(cfg.dt.is_finite() && cfg.dt > 0.0 && cfg.dt * 4.0 <= cfg.duration) {
        return Err(OrigamiError::Param(format!(
            "'dt' = {} s must be > 0 and give at least 4 samples in the duration",
            cfg.dt
        )));
    }
    if cfg.excitations.is_empty() {
        return Err(OrigamiError::Param(
            "'excitations' is empty; give at least one sweep or sine (one record each)".into(),
        ));
    }
    if let Some(s) = cfg.snr_db
        && !s.is_finite()
    {
        return Err(OrigamiError::Param(format!(
            "'snr_db' = {s} must be finite (omit it for noise-free data)"
        )));
    }
    for (name, v) in [("x0", &cfg.x0), ("v0", &cfg.v0)] {
        if let Some(v) = v
            && (v.len() != dofs || v.iter().any(|x| !x.is_finite()))
        {
            return Err(OrigamiError::Param(format!(
                "'{name}' has {} finite values but the system has {dofs} DOFs; give one finite value per DOF",
                v.len()
            )));
        }
    }
    if !(cfg.rtol.is_finite() && cfg.rtol > 0.0 && cfg.rtol < 1e-2) {
        return Err(OrigamiError::Param(format!(
            "'rtol' = {} must be in (0, 1e-2)",
            cfg.rtol
        )));
    }
    Ok(())
}

/// Generates one record per excitation: simulate (Dopri5), add noise, assemble columns.
/// A run that blows up returns [`OrigamiError::Simulation`] naming the record and the time.
pub fn generate(cfg: &DatasetConfig) -> Result<Dataset> {
    let sys = build_system(&cfg.system)?;
    let n_dof = sys.dofs();
    check_config(cfg, n_dof)?;
    let names = cfg.system.dof_names();
    let n = (cfg.duration / cfg.dt).round() as usize + 1;
    let t: Vec<f64> = (0..n).map(|k| k as f64 * cfg.dt).collect();
    let x0 = match &cfg.x0 {
        Some(x) => x.clone(),
        None => sys
            .equilibria()
            .into_iter()
            .find(|e| e.stable)
            .map(|e| e.x)
            .ok_or_else(|| {
                OrigamiError::Param(
                    "the system has no stable equilibrium to start from; give 'x0'".into(),
                )
            })?,
    };
    let v0 = cfg.v0.clone().unwrap_or_else(|| vec![0.0; n_dof]);
    let integ = Dopri5 {
        rtol: cfg.rtol,
        atol: cfg.rtol * 1e-2,
        ..Dopri5::default()
    };
    let mut records = Vec::with_capacity(cfg.excitations.len());
    let mut metas = Vec::with_capacity(cfg.excitations.len());
    let mut measured = names.clone();
    measured.push("xb_acc".into());
    let mut clean = Vec::new();
    for nm in &names {
        clean.push(format!("{nm}_clean"));
        clean.push(format!("{nm}_vel_clean"));
        clean.push(format!("{nm}_acc_clean"));
    }
    clean.push("xb_acc_clean".into());
    for (r, exc) in cfg.excitations.iter().enumerate() {
        let u = exc.sample(&t, cfg.duration)?;
        let input = SampledInput::new(0.0, cfg.dt, vec![u.clone()])
            .map_err(|source| OrigamiError::Simulation { record: r, source })?;
        let tr = integ
            .integrate(&sys, &input, &x0, &v0, &t)
            .map_err(|source| OrigamiError::Simulation { record: r, source })?;
        // Exact accelerations of the model at the samples.
        let mut acc = vec![vec![0.0; n]; n_dof];
        let (mut xs, mut vs, mut a) = (vec![0.0; n_dof], vec![0.0; n_dof], vec![0.0; n_dof]);
        for k in 0..n {
            for d in 0..n_dof {
                xs[d] = tr.x[d][k];
                vs[d] = tr.v[d][k];
            }
            sys.accel(t[k], &xs, &vs, &[u[k]], &mut a);
            for d in 0..n_dof {
                acc[d][k] = a[d];
            }
        }
        let noise_seed = splitmix(cfg.seed ^ splitmix(r as u64));
        let noisy = |c: usize, x: &[f64]| -> Result<Vec<f64>> {
            match cfg.snr_db {
                None => Ok(x.to_vec()),
                Some(snr) => {
                    let kind = match cfg.noise {
                        NoiseKind::White => tfs_signal::NoiseKind::White,
                        NoiseKind::Pink => tfs_signal::NoiseKind::Pink,
                    };
                    let e = tfs_signal::noise::noise_for(
                        x,
                        snr,
                        kind,
                        noise_seed.wrapping_add(c as u64),
                    )
                    .map_err(|e| {
                        OrigamiError::Numeric(format!("noise for record {r}, channel {c}: {e}"))
                    })?;
                    Ok(x.iter().zip(&e).map(|(a, b)| a + b).collect())
                }
            }
        };
        let mut cols: Vec<(String, Vec<f64>)> = Vec::new();
        for (d, nm) in names.iter().enumerate() {
            cols.push((nm.clone(), noisy(d, &tr.x[d])?));
        }
        cols.push(("xb_acc".into(), noisy(n_dof, &u)?));
        for (d, nm) in names.iter().enumerate() {
            cols.push((format!("{nm}_clean"), tr.x[d].clone()));
            cols.push((format!("{nm}_vel_clean"), tr.v[d].clone()));
            cols.push((format!("{nm}_acc_clean"), std::mem::take(&mut acc[d])));
        }
        cols.push(("xb_acc_clean".into(), u));
        let name = format!("record{r}");
        records.push(Record::new(name.clone(), t.clone(), cols)?);
        metas.push(RecordMeta {
            name,
            excitation: exc.clone(),
            x0: x0.clone(),
            v0: v0.clone(),
            noise_seed,
        });
    }
    let surrogate_coefs = sys
        .cells()
        .iter()
        .map(|c| match c.force_law() {
            CellForce::Surrogate(s) => s.coefs.clone(),
            CellForce::Truss(_) => Vec::new(),
        })
        .collect();
    Ok(Dataset {
        records,
        meta: DatasetMeta {
            truth: sys.truth_name(),
            surrogate_coefs,
            config: cfg.clone(),
            integrator: format!(
                "tfs_dynamics::Dopri5 (rtol {:e}, atol {:e}), input: not-a-knot cubic spline of the sampled xb_acc",
                integ.rtol, integ.atol
            ),
            measured,
            clean,
            records: metas,
        },
    })
}
