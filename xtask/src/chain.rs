//! §3.2: the two-cell chain (cell 1 γ0 = 20° monostable, cell 2 γ0 = 28.5° bistable) under its
//! truss truth, white noise at 60 and 30 dB (Table 2, Figs 6–7).

use std::sync::Arc;

use anyhow::{Context, Result, bail};
use indicatif::ProgressBar;
use serde_json::{Value, json};
use tfs::basin::{
    BasinConfig, BasinMap, BoaComparison, ChainMed, ChainWells, Slice, WellInfo, basin_chain,
    compare, med_chain,
};
use tfs::criteria::{IdentifySpec, TieOptions, identify_tfs_tied};
use tfs::data::Record;
use tfs::dynamics::SecondOrderSystem;
use tfs::library::Model;
use tfs::origami::{
    CellForce, CellSpec, Chain, DatasetConfig, Excitation, KreslingParams, NoiseKind, SystemSpec,
    Truth, build_system, generate,
};
use tfs::plot::{LineChart, Series};

use crate::common::{Opts, basin_figure, coef, curve, f4, fixed, model_json, num, pct, progress};
use crate::report::{Study, Table};

/// A shared potential of the chain displacements.
type Potential = Arc<dyn Fn(&[f64]) -> f64 + Send + Sync>;

/// Training sweeps of base acceleration for the chain (f0, f1, duration, amplitude).
/// The §3.1 sweeps at half amplitude: large enough to carry each cell across its whole range
/// (cell 1 from the folded state to beyond its stable state, cell 2 across its barrier between
/// both stable states — the measured ranges are reported in `training_ranges`), small enough to
/// stay off the folded stop (h < 0), which a polynomial library cannot represent, except for
/// brief touches (min h ≈ −0.02).
///
/// Sweep rate: every sweep that snaps cell 2 down also brings it to its folded state (h2 ≈ 0,
/// the stop) — lowering the amplitude does not avoid that (measured: ×0.7 still touches). Each
/// contact is a short, stiff acceleration burst no polynomial library represents; slow sweeps
/// dwell near resonance and pile up contacts, whose broadband content lifts the automatic
/// reconstruction cut-off of the records to 8–45 Hz and lets the bursts into the regression
/// (measured with sweeps twice this long: cell 2 lost its lower state at 60 dB). These sweeps
/// pass each resonance in a few cycles, so the data are dominated by the smooth response.
const TRAIN: [(f64, f64, f64, f64); 4] = [
    (0.05, 1.5, 50.0, 1.5),
    (0.05, 1.5, 30.0, 2.0),
    (0.1, 1.2, 40.0, 2.5),
    (0.05, 2.0, 60.0, 3.0),
];
const DT: f64 = 0.005;
const LIB1: &str = "x1^1..7, x1', (x2-x1)^1..7, (x2-x1)', xb_acc";
const LIB2: &str = "(x2-x1)^1..7, (x2-x1)', xb_acc";
/// Paper Table 2 (a_i, b_i for i = 1..7; ζ1, ζ2) at 60 and 30 dB.
const PAPER_A60: [f64; 7] = [-4.53, -9.58, 30.83, -25.13, 6.95, 0.0, 0.0];
#[allow(clippy::approx_constant)] // the paper's printed coefficient, not τ
const PAPER_B60: [f64; 7] = [0.0, -4.58, 8.08, 0.0, 0.0, -6.28, 3.17];
const PAPER_Z60: [f64; 2] = [0.99, 1.00];
const PAPER_A30: [f64; 7] = [-4.68, -9.14, 30.36, -24.90, 6.90, 0.0, 0.0];
const PAPER_B30: [f64; 7] = [0.0, -4.36, 7.61, 0.0, 0.0, -5.84, 2.94];
const PAPER_Z30: [f64; 2] = [0.98, 1.01];

fn spec() -> SystemSpec {
    let cell = |g: f64| CellSpec {
        params: KreslingParams {
            gamma0_deg: g,
            ..Default::default()
        },
        truth: Truth::Truss,
        ..Default::default()
    };
    SystemSpec::Chain {
        cells: vec![cell(20.0), cell(28.5)],
    }
}

fn pw(v: &str, k: usize) -> String {
    if k == 1 {
        v.to_string()
    } else {
        format!("{v}^{k}")
    }
}

/// Per-cell coefficients of a chain model: (a_1..7, b_1..7, ζ1, ζ2, xb_acc coefs, coupling b in eq. 1).
struct CellCoefs {
    a: [f64; 7],
    b: [f64; 7],
    b_in_1: [f64; 7],
    zeta: [f64; 2],
    xb: [f64; 2],
}

fn cell_coefs(m: &Model) -> CellCoefs {
    let mut c = CellCoefs {
        a: [0.0; 7],
        b: [0.0; 7],
        b_in_1: [0.0; 7],
        zeta: [0.0; 2],
        xb: [0.0; 2],
    };
    for k in 1..=7 {
        c.a[k - 1] = -coef(m, "x1", &pw("x1", k));
        c.b[k - 1] = -coef(m, "x2", &pw("(x2-x1)", k));
        c.b_in_1[k - 1] = coef(m, "x1", &pw("(x2-x1)", k));
    }
    c.zeta = [-coef(m, "x1", "x1'"), -coef(m, "x2", "(x2-x1)'")];
    c.xb = [coef(m, "x1", "xb_acc"), coef(m, "x2", "xb_acc")];
    c
}

fn poly(c: &[f64; 7], h: f64) -> f64 {
    c.iter()
        .enumerate()
        .map(|(k, a)| a * h.powi(k as i32 + 1))
        .sum()
}

fn poly_int(c: &[f64; 7], h: f64) -> f64 {
    c.iter()
        .enumerate()
        .map(|(k, a)| a * h.powi(k as i32 + 2) / (k as f64 + 2.0))
        .sum()
}

/// Chain wells from per-cell stable/unstable lists and a potential of the relative heights.
/// `order` gives, for each truth stable state, the matching state of this system first.
fn chain_wells(
    cells: [(Vec<f64>, Vec<f64>); 2],
    pot: Potential,
    reference: Option<&[Vec<f64>]>,
) -> Result<(ChainWells, Vec<Vec<f64>>)> {
    let x_of = |h1: f64, h2: f64| vec![h1, h1 + h2];
    let mut stable = Vec::new();
    let mut saddles = Vec::new();
    let all = |c: &(Vec<f64>, Vec<f64>)| -> Vec<(f64, bool)> {
        c.0.iter()
            .map(|&h| (h, true))
            .chain(c.1.iter().map(|&h| (h, false)))
            .collect()
    };
    for &(h1, s1) in &all(&cells[0]) {
        for &(h2, s2) in &all(&cells[1]) {
            if s1 && s2 {
                stable.push(x_of(h1, h2));
            } else {
                saddles.push(x_of(h1, h2));
            }
        }
    }
    if stable.is_empty() {
        bail!("no stable chain state");
    }
    if let Some(r) = reference {
        // Put the states nearest to the reference states first, in the reference order.
        let mut ordered = Vec::new();
        for rs in r {
            if let Some((k, _)) = stable
                .iter()
                .enumerate()
                .map(|(k, s)| (k, (s[0] - rs[0]).powi(2) + (s[1] - rs[1]).powi(2)))
                .min_by(|a, b| a.1.total_cmp(&b.1))
            {
                ordered.push(stable.remove(k));
            }
        }
        ordered.append(&mut stable);
        stable = ordered;
    } else {
        stable.sort_by(|a, b| a[1].total_cmp(&b[1]));
    }
    let p2 = pot.clone();
    let barrier = if saddles.is_empty() {
        None
    } else {
        Some(ChainWells::barrier_from_saddles(|x| p2(x), &saddles)?)
    };
    let p3 = pot.clone();
    let w = ChainWells::new(stable.clone(), vec![1.0, 1.0], move |x| p3(x), barrier)?;
    Ok((w, stable))
}

/// Wells of a chain model from its per-cell restoring polynomials, states ordered like `reference`.
fn model_wells(
    c: &CellCoefs,
    reference: &[Vec<f64>],
    visited: [(f64, f64); 2],
) -> Result<(ChainWells, Vec<Vec<f64>>)> {
    let (a, b) = (c.a, c.b);
    let w1 = WellInfo::from_force(
        move |h| poly(&a, h),
        move |h| poly_int(&a, h),
        visited[0],
        1.0,
    )
    .context("cell 1 of the model")?;
    let w2 = WellInfo::from_force(
        move |h| poly(&b, h),
        move |h| poly_int(&b, h),
        visited[1],
        1.0,
    )
    .context("cell 2 of the model")?;
    let pot: Potential = Arc::new(move |x: &[f64]| poly_int(&a, x[0]) + poly_int(&b, x[1] - x[0]));
    chain_wells(
        [
            (w1.stable().to_vec(), w1.unstable().to_vec()),
            (w2.stable().to_vec(), w2.unstable().to_vec()),
        ],
        pot,
        Some(reference),
    )
}

/// Stiffness of the folded-stop contact added to a model: 100 × the largest |dF/dh| of the
/// model's own cell forces on the training range (the rule the truss truth uses with its own
/// force, here evaluated on the identified polynomials — no truth information).
fn stop_stiffness(c: &CellCoefs, visited: [(f64, f64); 2]) -> f64 {
    let mut k: f64 = 0.0;
    for (cf, (lo, hi)) in [(c.a, visited[0]), (c.b, visited[1])] {
        let n = 400;
        for i in 0..=n {
            let h = lo + (hi - lo) * i as f64 / n as f64;
            let d: f64 = cf
                .iter()
                .enumerate()
                .map(|(j, a)| (j + 1) as f64 * a * h.powi(j as i32))
                .sum();
            k = k.max(d.abs());
        }
    }
    100.0 * k
}

/// The identified model with the folded stop of each cell: a one-sided contact force
/// `k·h` for `h < 0` (cell 1: h = x1; cell 2: h = x2 − x1, acting on both masses). The folded state
/// h = 0 is geometry (the cell cannot be compressed beyond flat), not dynamics the sweeps can
/// identify: a polynomial cannot represent a contact, and the training data only graze it.
struct WithStop<'a, S> {
    sys: &'a S,
    k: f64,
}

impl<S: SecondOrderSystem> SecondOrderSystem for WithStop<'_, S> {
    fn dofs(&self) -> usize {
        2
    }

    fn inputs(&self) -> usize {
        self.sys.inputs()
    }

    fn accel(&self, t: f64, x: &[f64], v: &[f64], u: &[f64], a: &mut [f64]) {
        self.sys.accel(t, x, v, u, a);
        let h1 = x[0];
        if h1 < 0.0 {
            a[0] -= self.k * h1;
        }
        let h2 = x[1] - x[0];
        if h2 < 0.0 {
            a[1] -= self.k * h2;
            a[0] += self.k * h2;
        }
    }
}

fn with_stop<S: SecondOrderSystem>(sys: &S, k: f64) -> WithStop<'_, S> {
    WithStop { sys, k }
}

/// One identified chain model and its basin, BOA error and MED.
struct ChainFit {
    /// Stiffness of the folded-stop contact added for the basin maps.
    k_stop: f64,
    /// BOA error of the identified equations without the contact.
    boa_plain: std::result::Result<f64, String>,
    /// Range of (h1, h2) in the training data (where the model's states are searched).
    visited: [(f64, f64); 2],
    label: String,
    model: Model,
    coefs: CellCoefs,
    basin: std::result::Result<(Vec<Vec<f64>>, BasinMap, BoaComparison), String>,
    med: std::result::Result<ChainMed, String>,
}

fn renamed(r: &Record, name: &str) -> Result<Record> {
    let cols = r
        .names()
        .iter()
        .map(|n| (n.clone(), r.column(n).unwrap_or_default().to_vec()))
        .collect();
    Ok(Record::new(name, r.t().to_vec(), cols)?)
}

fn records(snr: f64, scale: f64, seed: u64) -> Result<Vec<Record>> {
    let mut out = Vec::new();
    for (i, &(f0, f1, d, a)) in TRAIN.iter().enumerate() {
        let cfg = DatasetConfig {
            system: spec(),
            excitations: vec![Excitation::Sweep {
                f0,
                f1,
                amplitude: a,
                log: false,
                ramp: 0.0,
            }],
            duration: d * scale,
            dt: DT,
            snr_db: Some(snr),
            noise: NoiseKind::White,
            seed: seed + 31 * i as u64,
            x0: None,
            v0: None,
            rtol: 1e-9,
        };
        let ds = generate(&cfg).with_context(|| format!("simulating chain sweep {}", i + 1))?;
        out.push(renamed(&ds.records[0], &format!("train{}", i + 1))?);
    }
    Ok(out)
}

fn cfg(o: &Opts) -> BasinConfig {
    let n = o.pick(21, 101);
    let mut c = BasinConfig::new(n, n, (-1.2, 1.0), (-3.0, 3.0));
    c.dt = 0.01;
    c.t_max = 40.0;
    c
}

/// The truth's side of the chain study: each cell's force law and equilibria (stable, unstable),
/// the chain's stable states, the paper's slice through the first, the basin grid, and the
/// truth's basin map and minimum-energy deployment on it.
struct TruthSide {
    laws: [CellForce; 2],
    eq: [(Vec<f64>, Vec<f64>); 2],
    tstable: Vec<Vec<f64>>,
    slice: Slice,
    cfg: BasinConfig,
    tmap: BasinMap,
    tmed: ChainMed,
}

/// The truth chain, its wells, basin map and MED on the paper's slice, and the study's opening
/// text (the truth, the training sweeps, the libraries and the tied identification).
fn truth_side(st: &mut Study, o: &Opts, pb: &ProgressBar) -> Result<TruthSide> {
    let truth: Chain = build_system(&spec())?;
    let cells = truth.cells();
    let laws = [cells[0].force_law().clone(), cells[1].force_law().clone()];
    let eq = [laws[0].equilibria(), laws[1].equilibria()];
    st.text(format!(
        "Truth: two Kresling cells in series (a0 = 1.6, c0 = 1, k = 9.30, m = 1, c = 2 each), cell 1 γ0 = 20° ({} stable state(s) {:?}), cell 2 γ0 = 28.5° (stable {:?}, unstable {:?}), simulated with the **truss** force law (with the folded stop at h < 0): the paper's Table 2 polynomials have the zeros of these truss forces (cell 1 near h = 1.37; cell 2 near 0.64 and 1.54), so the paper's chain truth is the truss model, not a fixed polynomial. Coordinates x1, x2 are displacements relative to the base; Table 2's a_i, b_i are read as a_i = −(coefficient of x1^i in the x1 equation) and b_i = −(coefficient of (x2−x1)^i in the x2 equation). Training: four base-acceleration sweeps {:?} at 200 Hz; libraries `{LIB1}` (x1) and `{LIB2}` (x2). Identification: the **tied** T-F-S regression (`tfs_criteria::identify_tfs_tied`): the weak-form frequency rows of both equations are stacked and cell 2's terms `(x2-x1)^i`, `(x2-x1)'` get one unknown each, entering x2'' with +1 and x1'' with −1 (Newton's third law with equal masses — the paper's Eq. 18 ties b_i and ζ2 the same way); δ, windows, the STLSQ threshold and Criterion 4 run on the stacked rows of the training records only. Identified separately, x1'' had to find cell 2's coupling as a small part of its own acceleration among 17 strongly collinear columns (x1 and x2−x1 move together in a sweep): its coupling coefficients disagreed with x2'''s (e.g. the linear (x2−x1) term 4.8 in x1'' against 11.9 in x2'' at 30 dB, where the truth has them equal and opposite), and at 30 dB the whole x1 equation was once returned empty, leaving cell 1 without a stable state (38.8% / 30.8% BOA error in the untied run before this change). Empty fits are one way Criterion 4 can stop early: two successive assembly steps whose λ path picks the empty support both have σ = 1, which the σ-convergence test reads as converged; the tied fit does not accept an empty equation as converged. A polynomial says nothing outside the range its data visited, so each model's stable states are searched on the measured training range of each cell (reported below); a spurious well far outside it (e.g. near h1 = −0.28 at 30 dB, beyond the folded stop the truth has there) is not a state of the model's claim.{}",
        eq[0].0.len(),
        r3(&eq[0].0),
        r3(&eq[1].0),
        r3(&eq[1].1),
        TRAIN,
        if o.quick { " Quick mode: 21×21 basin grid." } else { "" }
    ));
    // Truth wells and basin.
    let tr2 = truth.clone();
    let tpot: Potential = Arc::new(move |x: &[f64]| tr2.energy(x, &[0.0, 0.0]));
    let (twells, tstable) = chain_wells([eq[0].clone(), eq[1].clone()], tpot, None)?;
    if tstable.len() < 2 {
        bail!(
            "the truth chain has {} stable state(s); need two",
            tstable.len()
        );
    }
    let slice = Slice::paper(&tstable[0]);
    let cfg = cfg(o);
    pb.set_message("truth basin");
    let tmap = basin_chain(&truth, &twells, &slice, &cfg, None).context("truth basin map")?;
    let tmed = med_chain(&truth, &twells, &slice, &tmap, &cfg, 0, 1).context("truth MED")?;
    pb.inc(1);
    Ok(TruthSide {
        laws,
        eq,
        tstable,
        slice,
        cfg,
        tmap,
        tmed,
    })
}

/// One noise level's chain fit: its training sweeps (noise seed `seed`, durations times
/// `scale`), each cell's visited range, the tied T-F-S model, and its basin maps (with and
/// without the folded-stop contact) and MED against the truth. Each record's clean ranges of h1,
/// h2 are appended to `ranges`.
fn fit_chain(
    snr: f64,
    seed: u64,
    scale: f64,
    truth: &TruthSide,
    ranges: &mut Vec<Value>,
    pb: &ProgressBar,
) -> Result<ChainFit> {
    let TruthSide {
        tstable,
        slice,
        cfg,
        tmap,
        ..
    } = truth;
    pb.set_message(format!("data {snr} dB"));
    let recs = records(snr, scale, seed)?;
    // Range of each cell's relative displacement in the measured (noisy) training data: the
    // model's stable states are searched there only.
    let mut visited = [(f64::INFINITY, f64::NEG_INFINITY); 2];
    for r in &recs {
        let x1 = r.column("x1").unwrap_or_default();
        let x2 = r.column("x2").unwrap_or_default();
        for (a, b) in x1.iter().zip(x2) {
            for (c, h) in [*a, b - a].into_iter().enumerate() {
                visited[c].0 = visited[c].0.min(h);
                visited[c].1 = visited[c].1.max(h);
            }
        }
    }
    for r in &recs {
        let x1 = r.column("x1_clean").unwrap_or_default();
        let x2 = r.column("x2_clean").unwrap_or_default();
        let h2: Vec<f64> = x1.iter().zip(x2).map(|(a, b)| b - a).collect();
        let mm = |v: &[f64]| {
            (
                v.iter().cloned().fold(f64::INFINITY, f64::min),
                v.iter().cloned().fold(f64::NEG_INFINITY, f64::max),
            )
        };
        ranges.push(json!({"snr": snr, "record": r.source(), "h1": [mm(x1).0, mm(x1).1], "h2": [mm(&h2).0, mm(&h2).1]}));
    }
    pb.inc(1);
    pb.set_message(format!("identify {snr} dB"));
    let mut sp = IdentifySpec::new(&["x1", "x2"], LIB1);
    sp.dof_libraries = vec![LIB1.to_string(), LIB2.to_string()];
    // Tied regression: cell 2's force law (b_i, ζ2) enters both equations (Newton's third
    // law, equal masses), as in the paper's Eq. 18.
    let id = identify_tfs_tied(&recs, &sp, &TieOptions::default())
        .with_context(|| format!("tied T-F-S identification of the chain ({snr} dB)"))?;
    let model = id.model;
    let coefs = cell_coefs(&model);
    let k_stop = stop_stiffness(&coefs, visited);
    // BOA of the identified equations alone (no contact): trajectories that reach h < 0
    // fall through the folded state.
    let boa_plain = (|| -> Result<f64> {
        let (mw, _) = model_wells(&coefs, tstable, visited)?;
        let sys = model.compile()?;
        let map = basin_chain(&sys, &mw, slice, cfg, None)?;
        Ok(compare(&map, tmap)?.error)
    })()
    .map_err(|e| format!("{e:#}"));
    let basin = (|| -> Result<(Vec<Vec<f64>>, BasinMap, BoaComparison)> {
        let (mw, ms) = model_wells(&coefs, tstable, visited)?;
        let sys = model.compile()?;
        let map = basin_chain(&with_stop(&sys, k_stop), &mw, slice, cfg, None)?;
        let cmp = compare(&map, tmap)?;
        Ok((ms, map, cmp))
    })()
    .map_err(|e| format!("{e:#}"));
    let med = match &basin {
        Ok((_, map, _)) => (|| -> Result<ChainMed> {
            let (mw, _) = model_wells(&coefs, tstable, visited)?;
            let sys = model.compile()?;
            Ok(med_chain(
                &with_stop(&sys, k_stop),
                &mw,
                slice,
                map,
                cfg,
                0,
                1,
            )?)
        })()
        .map_err(|e| format!("{e:#}")),
        Err(e) => Err(format!("no basin map: {e}")),
    };
    let fit = ChainFit {
        visited,
        k_stop,
        boa_plain,
        label: format!("{snr} dB"),
        model,
        coefs,
        basin,
        med,
    };
    pb.inc(1);
    Ok(fit)
}

/// Table 2: each cell's coefficients at both noise levels, the paper's beside ours, and the
/// equations identified.
fn table2(st: &mut Study, fits: &[ChainFit]) -> Result<()> {
    let mut t2 = Table::new(
        "table2",
        "Table 2: per-cell coefficients of Eq. 18 (paper beside ours)",
        &[
            "SNR", "source", "coef", "i=1", "i=2", "i=3", "i=4", "i=5", "i=6", "i=7",
        ],
    );
    let row = |snr: &str, src: &str, name: &str, v: &[f64]| -> Vec<String> {
        let mut r = vec![snr.to_string(), src.to_string(), name.to_string()];
        r.extend(v.iter().map(|x| f4(*x)));
        while r.len() < 10 {
            r.push("\\".into());
        }
        r
    };
    for (f, (pa, pb_, pz)) in fits.iter().zip([
        (PAPER_A60, PAPER_B60, PAPER_Z60),
        (PAPER_A30, PAPER_B30, PAPER_Z30),
    ]) {
        t2.row(row(&f.label, "paper", "a_i", &pa));
        t2.row(row(&f.label, "ours", "a_i", &f.coefs.a));
        t2.row(row(&f.label, "paper", "b_i", &pb_));
        t2.row(row(&f.label, "ours", "b_i", &f.coefs.b));
        t2.row(row(
            &f.label,
            "ours",
            "b_i in x1 eq. (tied: = b_i)",
            &f.coefs.b_in_1,
        ));
        t2.row(row(&f.label, "paper", "ζ_i", &pz));
        t2.row(row(&f.label, "ours", "ζ_i", &f.coefs.zeta));
        t2.row(row(&f.label, "ours", "xb_acc coef", &f.coefs.xb));
    }
    st.table(t2)?;
    st.text(format!(
        "Equations identified:\n\n- 60 dB: `{}`\n- 30 dB: `{}`\n\nTrue damping per unit mass: ζ1 = ζ2 = 2 (c = 2, m = 1) and xb_acc coefficient −1 in both equations; the paper's 0.99/1.00 imply it simulated c = 1 (ours are compared with 2). Polynomial coefficients of a truss force are not unique (many degree-7 polynomials fit it equally well on the visited range), so Table 2 is compared term by term for information only; the force curves (Fig. 7a–b) and the BOA errors are the meaningful comparison.",
        fits[0].model.equation_string(),
        fits[1].model.equation_string()
    ));
    Ok(())
}

/// Each cell's stable states, the truth's against each model's (searched on the cell's training
/// range), as a table, JSON and checks.
fn states_table(st: &mut Study, fits: &[ChainFit], eq: &[(Vec<f64>, Vec<f64>); 2]) -> Result<()> {
    let mut ts = Table::new(
        "chain_states",
        "Stable states per cell: truth (truss) vs identified model (searched on the training range)",
        &[
            "SNR",
            "cell",
            "truth stable",
            "model stable",
            "max |error|",
            "training range of h",
        ],
    );
    let mut states_json = Vec::new();
    for f in fits {
        for (c, (eqc, vis)) in eq.iter().zip(f.visited).enumerate() {
            let cf = if c == 0 { f.coefs.a } else { f.coefs.b };
            let got =
                WellInfo::from_force(move |h| poly(&cf, h), move |h| poly_int(&cf, h), vis, 1.0)
                    .map(|w| w.stable().to_vec())
                    .unwrap_or_default();
            let want = &eqc.0;
            let err = if got.len() == want.len() {
                got.iter()
                    .zip(want)
                    .map(|(g, w)| (g - w).abs())
                    .fold(0.0, f64::max)
            } else {
                f64::NAN
            };
            ts.row(vec![
                f.label.clone(),
                format!("{}", c + 1),
                format!("{:?}", r3(want)),
                format!("{:?}", r3(&got)),
                if err.is_finite() {
                    f4(err)
                } else {
                    "count differs".into()
                },
                format!("[{:.3}, {:.3}]", vis.0, vis.1),
            ]);
            states_json.push(json!({"snr": f.label, "cell": c + 1, "truth": want, "model": got, "max_error": num(err), "range": [vis.0, vis.1]}));
            st.compare(
                &format!("Chain cell {} stable states {}", c + 1, f.label),
                &format!("{:?}", r3(want)),
                &if err.is_finite() {
                    format!("{:?} (max error {})", r3(&got), f4(err))
                } else {
                    format!("{:?} (count differs)", r3(&got))
                },
                if c == 0 { "monostable" } else { "bistable" },
                Some(err.is_finite() && err <= 0.05),
                "same count as the truth, each within 0.05",
            );
        }
    }
    st.table(ts)?;
    st.set("stable_states", json!(states_json));
    Ok(())
}

/// The basin errors of each model on the paper's slice, with and without the folded-stop
/// contact, as a table and checks, and why the contact is added.
fn boa_table(st: &mut Study, fits: &[ChainFit]) -> Result<()> {
    let mut tb = Table::new(
        "boa_chain",
        "Chain BOA errors on the paper's slice x_i(0) = x_i^S1 + Δx, ẋ_i(0) = v0",
        &[
            "case",
            "BOA error (model + folded stop)",
            "BOA error (model alone)",
            "stop stiffness",
            "paper",
            "model stable states (x1, x2)",
        ],
    );
    for f in fits {
        let e = f.basin.as_ref().map(|b| b.2.error).unwrap_or(f64::NAN);
        tb.row(vec![
            f.label.clone(),
            f.basin
                .as_ref()
                .map(|b| pct(b.2.error))
                .unwrap_or_else(|e| format!("failed: {e}")),
            f.boa_plain
                .as_ref()
                .map(|e| pct(*e))
                .unwrap_or_else(|e| format!("failed: {e}")),
            f4(f.k_stop),
            "< 3% (§5)".into(),
            f.basin
                .as_ref()
                .map(|b| format!("{:?}", b.0.iter().map(|s| r3(s)).collect::<Vec<_>>()))
                .unwrap_or_default(),
        ]);
        st.compare(
            &format!("Chain BOA error {} (model + folded stop)", f.label),
            "0% (the truth's map)",
            &pct(e),
            "< 3% (§5)",
            Some(e.is_finite() && e < crate::sdof::BOA_BOUND),
            crate::sdof::BOA_RULE,
        );
    }
    st.table(tb)?;
    st.text("The truth's folded stop (a stiff one-sided contact for h < 0) decides the fate of every start with a large negative velocity on this slice: the cells hit the flat state and bounce. The training sweeps stay off the stop (a polynomial cannot represent a contact), so the identified equations alone let those trajectories fall through h = 0 (the 'model alone' column: all of its disagreement lies in the bottom corners of the map). The basin maps, figures and MED use each identified model plus the geometric contact at h = 0 with stiffness 100 × the largest |F'| of the model's own cell forces (the same rule the truss truth uses, evaluated on the identified polynomials, no truth information).".to_string());
    Ok(())
}

/// The minimum-energy deployment S1 → S2 of the truth and of each model.
fn med_table(st: &mut Study, fits: &[ChainFit], tmed: &ChainMed) -> Result<()> {
    let mut tm = Table::new(
        "med_chain",
        "Chain minimum-energy deployment S1 → S2 on the slice",
        &["system", "E_MED", "Δx", "v0", "quasi-static barrier"],
    );
    tm.row(vec![
        "truth".into(),
        f4(tmed.energy),
        f4(tmed.c0),
        f4(tmed.c1),
        tmed.quasi_static_barrier.map_or("—".into(), f4),
    ]);
    for f in fits {
        match &f.med {
            Ok(m) => tm.row(vec![
                format!("model {}", f.label),
                f4(m.energy),
                f4(m.c0),
                f4(m.c1),
                m.quasi_static_barrier.map_or("—".into(), f4),
            ]),
            Err(e) => tm.row(vec![
                format!("model {}", f.label),
                format!("failed: {e}"),
                String::new(),
                String::new(),
                String::new(),
            ]),
        }
    }
    st.table(tm)?;
    Ok(())
}

/// The study's results in JSON: the truth, the basin grid and each model's fit.
fn results_json(st: &mut Study, truth: &TruthSide, fits: &[ChainFit]) {
    let TruthSide {
        eq,
        tstable,
        cfg,
        tmap,
        tmed,
        ..
    } = truth;
    let med_json = |m: &ChainMed| json!({"energy": num(m.energy), "dx": num(m.c0), "v0": num(m.c1), "x": m.x, "v": m.v, "quasi_static_barrier": m.quasi_static_barrier.map(num)});
    st.set("truth", json!({"stable": tstable, "cell1": {"stable": eq[0].0, "unstable": eq[0].1}, "cell2": {"stable": eq[1].0, "unstable": eq[1].1}, "med": med_json(tmed), "basin_shares": tmap.shares}));
    st.set("grid", json!({"nx": cfg.nx, "ny": cfg.ny, "dx_range": [cfg.x_range.0, cfg.x_range.1], "v_range": [cfg.v_range.0, cfg.v_range.1]}));
    for f in fits {
        let key = if f.label.starts_with("60") {
            "chain_60db"
        } else {
            "chain_30db"
        };
        let v: Value = json!({
            "equation": f.model.equation_string(),
            "model": model_json(&f.model),
            "a": f.coefs.a.iter().map(|v| num(*v)).collect::<Vec<_>>(),
            "b": f.coefs.b.iter().map(|v| num(*v)).collect::<Vec<_>>(),
            "zeta": f.coefs.zeta.iter().map(|v| num(*v)).collect::<Vec<_>>(),
            "boa_error": f.basin.as_ref().ok().map(|b| num(b.2.error)),
            "basin_error": f.basin.as_ref().err(),
            "boa_error_model_alone": f.boa_plain.as_ref().ok().map(|e| num(*e)),
            "stop_stiffness": num(f.k_stop),
            "med": f.med.as_ref().ok().map(med_json),
            "med_error": f.med.as_ref().err(),
        });
        st.set(key, v);
    }
}

/// Fig. 7a–b: each cell's restoring force, the truth's against each model's.
fn force_figures(st: &mut Study, laws: &[CellForce; 2], fits: &[ChainFit]) -> Result<()> {
    let (lo, hi, n) = (0.0, 2.0, 201);
    for (c, (name, letter)) in [("cell 1 (γ0 = 20°)", "a"), ("cell 2 (γ0 = 28.5°)", "b")]
        .iter()
        .enumerate()
    {
        let law = laws[c].clone();
        let mut ch = LineChart::new(
            format!("Fig. 7{letter}: restoring force of {name}"),
            "relative displacement h (length unit c0)",
            "restoring force F(h) per unit mass (c0/s²)",
        )
        .with_series(Series::line("truth (truss)", curve(lo, hi, n, |h| law.force(h))).color(0));
        for (k, f) in fits.iter().enumerate() {
            let cf = if c == 0 { f.coefs.a } else { f.coefs.b };
            ch = ch.with_series(
                Series::dashed(
                    format!("model {}", f.label),
                    curve(lo, hi, n, |h| poly(&cf, h)),
                )
                .color(k + 1),
            );
        }
        st.figure(
            &format!("fig7{letter}_force_cell{}", c + 1),
            &format!("Fig. 7{letter}: restoring force of {name}, truth vs identified models"),
            ch,
        )?;
    }
    Ok(())
}

/// Fig. 6c: a piece of the first 60 dB training sweep, its displacements and its base
/// acceleration (one figure each: different units).
fn signal_figures(st: &mut Study) -> Result<()> {
    if let Ok(recs) = records(60.0, 0.3, 500) {
        let r = &recs[0];
        let t = r.t();
        let step = (t.len() / 2500).max(1);
        let s = |name: &str| -> Vec<(f64, f64)> {
            t.iter()
                .zip(r.column(name).unwrap_or_default())
                .step_by(step)
                .map(|(a, b)| (*a, *b))
                .collect()
        };
        // Displacements and the base acceleration have different units: one figure each.
        let ch = LineChart::new(
            "Fig. 6c: chain response to the first training sweep (60 dB)",
            "t (s)",
            "displacement relative to the base (length unit c0)",
        )
        .with_series(Series::line("x1 (measured)", s("x1")).color(1))
        .with_series(Series::line("x2 (measured)", s("x2")).color(2));
        let ex = LineChart::new(
            "Fig. 6c: base acceleration of the first training sweep (60 dB)",
            "t (s)",
            "xb_acc (c0/s²)",
        )
        .with_series(Series::line("xb_acc (measured)", s("xb_acc")).color(0));
        st.figure(
            "fig6c_excitation",
            "Fig. 6c: base acceleration driving the chain (first 30% of training sweep 1)",
            ex,
        )?;
        st.figure(
            "fig6c_signals",
            "Fig. 6c: simulated responses of the chain (first 30% of training sweep 1)",
            ch,
        )?;
    }
    Ok(())
}

/// Fig. 7c–e: the basins of attraction of the truth and of each model on the paper's slice, MED
/// points marked, disagreeing cells dark.
fn basin_figures(st: &mut Study, truth: &TruthSide, fits: &[ChainFit]) -> Result<()> {
    let TruthSide {
        tstable,
        tmap,
        tmed,
        ..
    } = truth;
    let axes = (
        "Δx, shift of every displacement from S1 (length unit c0)",
        "v0, initial velocity of every mass (c0/s)",
    );
    let names: Vec<String> = tstable
        .iter()
        .enumerate()
        .map(|(k, s)| format!("S{} (h2 = {})", k + 1, fixed(s[1] - s[0], 3)))
        .collect();
    let fig = basin_figure(
        tmap,
        "Fig. 7c: chain BOA of the truth",
        axes,
        &names,
        None,
        vec![(tmed.c0, tmed.c1, format!("MED {:.3}", tmed.energy))],
    );
    st.figure(
        "fig7c_boa_truth",
        "Fig. 7c: chain basins of attraction of the truth on the paper's slice (MED point marked)",
        fig,
    )?;
    for (k, f) in fits.iter().enumerate() {
        if let Ok((_, map, cmp)) = &f.basin {
            let pts = f
                .med
                .as_ref()
                .map(|m| vec![(m.c0, m.c1, format!("MED {:.3}", m.energy))])
                .unwrap_or_default();
            let fig = basin_figure(
                map,
                &format!(
                    "Fig. 7: chain BOA, {} model — BOA error {}",
                    f.label,
                    pct(cmp.error)
                ),
                axes,
                &names,
                Some(&cmp.disagree),
                pts,
            );
            let letter = (b'd' + k as u8) as char;
            st.figure(
                &format!("fig7{letter}_boa_{}", f.label.replace(' ', "")),
                &format!("Fig. 7{letter}: chain basins of the {} model; dark cells disagree with the truth (BOA error {})", f.label, pct(cmp.error)),
                fig,
            )?;
        }
    }
    Ok(())
}

/// Study 3.
pub fn study_chain(st: &mut Study, o: &Opts) -> Result<()> {
    let pb = progress(7, "§3.2 chain");
    let truth = truth_side(st, o, &pb)?;
    // Quick mode shrinks only the basin grid: shorter sweeps would change the data (see TRAIN).
    let scale = 1.0;
    let mut fits = Vec::new();
    let mut ranges = Vec::new();
    for (snr, seed) in [(60.0, 500), (30.0, 600)] {
        fits.push(fit_chain(snr, seed, scale, &truth, &mut ranges, &pb)?);
    }
    pb.set_message("tables and figures");
    st.set("training_ranges", json!(ranges));
    table2(st, &fits)?;
    states_table(st, &fits, &truth.eq)?;
    boa_table(st, &fits)?;
    med_table(st, &fits, &truth.tmed)?;
    results_json(st, &truth, &fits);
    force_figures(st, &truth.laws, &fits)?;
    signal_figures(st)?;
    basin_figures(st, &truth, &fits)?;
    pb.inc(1);
    pb.finish_and_clear();
    Ok(())
}

fn r3(v: &[f64]) -> Vec<f64> {
    v.iter().map(|x| (x * 1e3).round() / 1e3).collect()
}
