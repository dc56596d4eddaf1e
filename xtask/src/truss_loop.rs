//! `cargo xtask truss-loop`: the diagnosis loop on the Kresling truss cell, measured as the user
//! runs it. For each noise level and seed it runs the `tfs` binary's own commands — `simulate
//! kresling --truth truss`, `identify` with `x^1..7, x', xb_acc`, `refit --until-clean 4`,
//! `basin --truth kresling:truss` — and scores the start and the final model against the truss
//! force: the restoring-force error over 0 ≤ h ≤ 1.8 beside the least-squares floor of the
//! start library's position columns there, and the basin-of-attraction error.
//! Writes `report.md`, `results.json` and one force figure per noise level.

use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{Context, Result, anyhow, bail};
use faer::Mat;
use serde_json::{Value, json};
use tfs::data::Record;
use tfs::library::{Factor, Library, Model};
use tfs::origami::KreslingCell;
use tfs::plot::{Figure, LineChart, Series};
use tfs::records::read_model;

use crate::common::{curve, f4, num, pct, rms};

/// The start library of the loop (the cell's position powers, its dashpot and the base input).
const LIBRARY: &str = "x^1..7, x', xb_acc";
/// Its columns that depend on the position only: the part a least-squares floor can use.
const POSITION_LIBRARY: &str = "x^1..7";
/// The heights over which the force is compared (the cell's folded state to past its deployed
/// one).
const H_RANGE: (f64, f64) = (0.0, 1.8);
/// Points of the comparison grid (step 1e-4): fine enough that a contact stop a few 1e-4 from
/// the truth's counts by the width it is wrong over, not by the width of one grid cell.
const GRID: usize = 18_001;
/// The force error may be at most this many times the floor.
const FLOOR_FACTOR: f64 = 1.5;
/// The basin error must stay below this share of the map.
const BASIN_BAR: f64 = 0.01;

/// Arguments of `cargo xtask truss-loop`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Noise levels (SNR in dB, on each recorded channel).
    #[arg(long, value_delimiter = ',', default_value = "60,30")]
    pub snr: Vec<f64>,
    /// Noise seeds (one run of the loop per seed and noise level).
    #[arg(long, value_delimiter = ',', default_value = "1,2,3")]
    pub seeds: Vec<u64>,
    /// Output folder (one subfolder of records and models per run).
    #[arg(long, default_value = "target/truss-loop")]
    pub out: PathBuf,
    /// The `tfs` binary to run (default: the one beside this xtask, built first with cargo).
    #[arg(long)]
    pub tfs: Option<PathBuf>,
}

/// The truth's restoring force per unit mass and the grid it is compared on.
pub struct ForceTruth {
    /// Heights of the grid.
    pub h: Vec<f64>,
    /// The truss force per unit mass at each height.
    pub f: Vec<f64>,
    /// RMS of `f` over the grid.
    pub rms: f64,
}

impl ForceTruth {
    /// The default cell's truss force (the cell `tfs simulate kresling` simulates) on `n`
    /// points of `range`.
    pub fn kresling(range: (f64, f64), n: usize) -> Result<Self> {
        let cell = KreslingCell::new(Default::default()).context("the default Kresling cell")?;
        let m = cell.params().m;
        let pts = curve(range.0, range.1, n, |h| cell.force(h) / m);
        Ok(Self::new(pts))
    }

    /// A truth given by its points.
    pub fn new(pts: Vec<(f64, f64)>) -> Self {
        let (h, f): (Vec<f64>, Vec<f64>) = pts.into_iter().unzip();
        let rms = rms(&f);
        Self { h, f, rms }
    }

    /// RMS of `model − truth` over the grid, over the RMS of the truth.
    pub fn error_of(&self, model: impl Fn(f64) -> f64) -> f64 {
        self.error_where(model, |_| true).unwrap_or(f64::NAN)
    }

    /// [`error_of`] over the grid's points where `keep` holds, over the RMS of the truth there
    /// (`None` when it holds nowhere).
    ///
    /// [`error_of`]: ForceTruth::error_of
    pub fn error_where(
        &self,
        model: impl Fn(f64) -> f64,
        keep: impl Fn(f64) -> bool,
    ) -> Option<f64> {
        let (mut e, mut t) = (Vec::new(), Vec::new());
        for (h, f) in self.h.iter().zip(&self.f).filter(|(h, _)| keep(**h)) {
            e.push(model(*h) - f);
            t.push(*f);
        }
        (!e.is_empty()).then(|| rms(&e) / rms(&t))
    }

    /// The grid as a record with the one column `x` (the heights), for evaluating terms on it.
    fn grid(&self) -> Result<Record> {
        Ok(Record::new(
            "grid",
            (0..self.h.len()).map(|i| i as f64).collect(),
            vec![("x".into(), self.h.clone())],
        )?)
    }

    /// The least-squares floor of a library of position columns: the smallest [`error_of`]
    /// any coefficients of `library` (over the DOF `x`) reach on this grid.
    ///
    /// [`error_of`]: ForceTruth::error_of
    pub fn floor(&self, library: &str) -> Result<f64> {
        let lib = Library::parse(library, &["x"])?;
        let a: Mat<f64> = lib.evaluate(&self.grid()?)?;
        let e = crate::dbench::size::residual(&a, &self.f)?;
        Ok(rms(&e) / self.rms)
    }

    /// The least-squares floor of `library` plus one stop `k·below(x, c)` (or `k·above(x, c)`)
    /// with its stiffness `k` and its position `c` both free: `c` is scanned over the grid's
    /// range (step [`STOP_STEP`], then [`STOP_STEP`]/50 around the best), `k` and the
    /// library's coefficients fitted by least squares at each. Returns the smallest error and
    /// the position it is reached at: the floor of the model class the loop ends with when it
    /// adds a stop.
    pub fn floor_with_stop(&self, library: &str, side: Side) -> Result<StopFloor> {
        let lib = Library::parse(library, &["x"])?;
        let grid = self.grid()?;
        let a: Mat<f64> = lib.evaluate(&grid)?;
        let (lo, hi) = (self.h[0], self.h[self.h.len() - 1]);
        // The library's columns once; each position rewrites only the stop's, the last.
        let p = a.ncols();
        let mut with =
            Mat::<f64>::from_fn(a.nrows(), p + 1, |r, j| if j < p { a[(r, j)] } else { 0.0 });
        drop(a);
        let mut at = |c: f64| -> Result<f64> {
            let col = tfs::library::evaluate_term(&side.term(c), &grid)?;
            for (r, v) in col.into_iter().enumerate() {
                with[(r, p)] = v;
            }
            let e = crate::dbench::size::residual(&with, &self.f)?;
            Ok(rms(&e) / self.rms)
        };
        let mut scan = |cs: Vec<f64>| -> Result<(f64, f64)> {
            let mut best = (f64::INFINITY, f64::NAN);
            for c in cs {
                let e = at(c)?;
                if e < best.0 {
                    best = (e, c);
                }
            }
            Ok(best)
        };
        let n = ((hi - lo) / STOP_STEP).round() as usize;
        // The ends are left out: there the stop's column is zero on the whole grid.
        let coarse = scan((1..n).map(|i| lo + STOP_STEP * i as f64).collect())?;
        let fine_step = STOP_STEP / 50.0;
        let fine = scan(
            (0..=100)
                .map(|i| coarse.1 - STOP_STEP + fine_step * i as f64)
                .filter(|c| *c > lo && *c < hi)
                .collect(),
        )?;
        let (error, position) = if fine.0 < coarse.0 { fine } else { coarse };
        // To four decimals, the fine pass's step (1e-4), so the term's name is the position's
        // digits.
        let position = format!("{position:.4}").parse::<f64>().unwrap_or(position);
        let stop = side.term(position);
        Ok(StopFloor {
            error,
            stop: stop.to_string(),
        })
    }
}

/// Step of the first pass of [`ForceTruth::floor_with_stop`]'s scan of the stop's position.
const STOP_STEP: f64 = 0.005;

/// Which side of its position a stop acts on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Side {
    /// `below(x, c)`: acts for `x < c` (the cell's folded stop).
    Below,
    /// `above(x, c)`: acts for `x > c`.
    Above,
}

impl Side {
    /// The one-factor stop term at `c`.
    fn term(self, c: f64) -> tfs::library::Term {
        let v = tfs::library::Var::Disp("x".into());
        tfs::library::Term::new(vec![match self {
            Side::Below => Factor::Below(v, c),
            Side::Above => Factor::Above(v, c),
        }])
    }
}

/// The floor of a library plus one stop with its position and stiffness free
/// ([`ForceTruth::floor_with_stop`]).
#[derive(Debug, Clone)]
pub struct StopFloor {
    /// The smallest force error the class reaches on the grid.
    pub error: f64,
    /// The stop term at the position where it is reached.
    pub stop: String,
}

/// The model with the coefficients of its displacement powers (`x^k` alone) at their
/// least-squares best against `truth` on its grid, every other term as identified (the stop's
/// force is taken out of the truth first): what the model's own support could reach with the
/// best coefficients. `None` when the model has no power term.
pub fn powers_at_best(model: &Model, truth: &ForceTruth) -> Result<Option<Model>> {
    let power = |t: &tfs::library::Term| matches!(t.factors(), [Factor::Pow(tfs::library::Var::Disp(d), _)] if d == "x");
    let eq = model
        .equations
        .first()
        .ok_or_else(|| anyhow!("the model has no equation"))?;
    let powers: Vec<usize> = (0..eq.terms.len())
        .filter(|&i| power(&eq.terms[i].term))
        .collect();
    if powers.is_empty() {
        return Ok(None);
    }
    let mut rest = model.clone();
    for &i in &powers {
        rest.equations[0].terms[i].coef = 0.0;
    }
    let other = model_force(&rest)?;
    let target: Vec<f64> = truth
        .h
        .iter()
        .zip(&truth.f)
        .map(|(h, f)| f - other(*h))
        .collect();
    // The restoring force is `−Σ coef·term`, so each column is `−term`.
    let grid = truth.grid()?;
    let cols = powers
        .iter()
        .map(|&i| tfs::library::evaluate_term(&eq.terms[i].term, &grid))
        .collect::<std::result::Result<Vec<_>, _>>()?;
    let a = Mat::<f64>::from_fn(truth.h.len(), cols.len(), |r, c| -cols[c][r]);
    let fit = tfs::regress::lstsq(a.as_ref(), &target).context("the powers' least-squares fit")?;
    let mut best = model.clone();
    for (c, &i) in powers.iter().enumerate() {
        let t = &mut best.equations[0].terms[i];
        t.coef = fit.coef[c];
        t.interval = None;
        t.inclusion = None;
    }
    Ok(Some(best))
}

/// The restoring force per unit mass of a 1-DOF model (`−x''` at the height with no velocity
/// and no input).
pub fn model_force(model: &Model) -> Result<impl Fn(f64) -> f64> {
    let dof = model
        .dofs
        .first()
        .ok_or_else(|| anyhow!("the model has no DOF"))?;
    if model.dofs.len() != 1 {
        bail!(
            "the model has {} DOFs; the truss cell has one",
            model.dofs.len()
        );
    }
    let r = model.restoring(dof)?;
    Ok(move |h| r.force(h))
}

/// Whether height `h` lies where none of the model's stops acts (`below(x, c)` acts for
/// `h < c`, `above(x, c)` for `h > c`).
fn outside_stops(model: &Model, h: f64) -> bool {
    model
        .equations
        .iter()
        .flat_map(|e| &e.terms)
        .flat_map(|t| t.term.factors())
        .all(|f| match f {
            Factor::Below(_, c) => h >= *c,
            Factor::Above(_, c) => h <= *c,
            _ => true,
        })
}

/// One model's scores.
#[derive(Debug, Clone)]
struct Score {
    force_error: f64,
    /// The force error over the heights where none of the model's stops acts (`None` when
    /// they act everywhere): how much of [`Score::force_error`] is the contact's.
    force_error_free: Option<f64>,
    /// The basin error, or why `tfs basin` gave none.
    basin_error: std::result::Result<f64, String>,
    /// The model itself (its force is drawn in the figure).
    model: Model,
    terms: String,
    /// The model's stop terms with their stiffness, e.g. `below(x, 0.0003), k = 10637`.
    stops: Vec<String>,
}

/// One run of the loop.
#[derive(Debug, Clone)]
struct Run {
    snr: f64,
    seed: u64,
    start: Score,
    end: Score,
    /// The final model with its powers at their least-squares best (`None`: it has none).
    end_best: Option<Score>,
    added: Vec<String>,
    seconds: f64,
}

/// Runs `cargo xtask truss-loop`.
pub fn run(args: Args) -> Result<()> {
    if args.snr.is_empty() || args.seeds.is_empty() {
        bail!("--snr and --seeds each need at least one value");
    }
    if let Some(s) = args.snr.iter().find(|s| !s.is_finite() || **s <= 0.0) {
        bail!("--snr {s}: give SNRs in dB above 0 (e.g. --snr 60,30)");
    }
    let tfs = tfs_binary(args.tfs.as_deref())?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("--out {}: cannot create it", args.out.display()))?;
    let truth = ForceTruth::kresling(H_RANGE, GRID)?;
    let floor = truth.floor(POSITION_LIBRARY)?;
    let with_stop = [
        truth.floor_with_stop(POSITION_LIBRARY, Side::Below)?,
        truth.floor_with_stop(POSITION_LIBRARY, Side::Above)?,
    ];
    let pb = crate::common::progress((args.snr.len() * args.seeds.len()) as u64, "runs");
    let mut runs = Vec::new();
    for &snr in &args.snr {
        for &seed in &args.seeds {
            pb.set_message(format!("{snr} dB, seed {seed}"));
            let dir = args.out.join(format!("snr{snr}-seed{seed}"));
            let r = one_run(&tfs, &dir, snr, seed, &truth)
                .with_context(|| format!("{snr} dB, seed {seed} (files in {})", dir.display()))?;
            runs.push(r);
            pb.inc(1);
        }
    }
    pb.finish_and_clear();
    let md = report(&args, &runs, floor, &with_stop);
    print!("{md}");
    tfs::data::write_atomic(args.out.join("report.md"), &md)?;
    let js = json!({
        "library": LIBRARY,
        "h_range": [H_RANGE.0, H_RANGE.1],
        "grid_points": GRID,
        "floor": floor,
        "floor_library": POSITION_LIBRARY,
        "force_bound": FLOOR_FACTOR * floor,
        "floor_with_one_stop": with_stop.iter().map(|f| json!({"error": num(f.error), "stop": f.stop})).collect::<Vec<_>>(),
        "basin_bar": BASIN_BAR,
        "runs": runs.iter().map(run_json).collect::<Vec<_>>(),
    });
    tfs::data::write_atomic(
        args.out.join("results.json"),
        serde_json::to_string_pretty(&js)?,
    )?;
    for &snr in &args.snr {
        figure(&args.out, snr, &runs, &truth)?;
    }
    Ok(())
}

/// The `tfs` binary: `given`, or the one beside this program, built first by the cargo that
/// runs this program (same profile).
fn tfs_binary(given: Option<&Path>) -> Result<PathBuf> {
    if let Some(p) = given {
        if !p.is_file() {
            bail!(
                "--tfs {}: no such file (build it: cargo build -p tfs)",
                p.display()
            );
        }
        // Each run executes it from its own folder, so a relative path is made absolute here.
        return std::fs::canonicalize(p).with_context(|| format!("--tfs {}", p.display()));
    }
    let me = std::env::current_exe().context("locating this program")?;
    let path = me.with_file_name(format!("tfs{}", std::env::consts::EXE_SUFFIX));
    if let Ok(cargo) = std::env::var("CARGO") {
        let release = me
            .parent()
            .and_then(|d| d.file_name())
            .is_some_and(|n| n == "release");
        let mut cmd = Command::new(cargo);
        cmd.args(["build", "-q", "-p", "tfs", "--bin", "tfs"]);
        if release {
            cmd.arg("--release");
        }
        let st = cmd.status().context("running cargo build -p tfs")?;
        if !st.success() {
            bail!("cargo build -p tfs failed ({st})");
        }
    }
    if !path.is_file() {
        bail!(
            "{}: no tfs binary beside this program; build it (cargo build -p tfs) or give --tfs",
            path.display()
        );
    }
    Ok(path)
}

/// Runs `tfs` with `args` in `dir`; returns its standard output, or an error with its
/// standard error.
fn tfs_run(tfs: &Path, dir: &Path, args: &[&str]) -> Result<String> {
    let out = Command::new(tfs)
        .args(args)
        .current_dir(dir)
        .output()
        .with_context(|| format!("running {}", tfs.display()))?;
    if !out.status.success() {
        bail!(
            "`tfs {}` failed: {}",
            args.join(" "),
            String::from_utf8_lossy(&out.stderr).trim()
        );
    }
    Ok(String::from_utf8_lossy(&out.stdout).into_owned())
}

fn one_run(tfs: &Path, dir: &Path, snr: f64, seed: u64, truth: &ForceTruth) -> Result<Run> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let t0 = std::time::Instant::now();
    let (snr_s, seed_s) = (snr.to_string(), seed.to_string());
    tfs_run(
        tfs,
        dir,
        &[
            "simulate",
            "kresling",
            "--truth",
            "truss",
            "--excitation",
            "sweep:0.05:1.5:4",
            "--excitation",
            "sweep:0.1:1.5:3.5",
            "--duration",
            "80",
            "--snr-db",
            &snr_s,
            "--seed",
            &seed_s,
            "--out",
            "k.csv",
        ],
    )?;
    tfs_run(
        tfs,
        dir,
        &[
            "identify",
            "k-1.csv",
            "k-2.csv",
            "--library",
            LIBRARY,
            "--out",
            "m.json",
        ],
    )?;
    let refit = tfs_run(
        tfs,
        dir,
        &[
            "refit",
            "--model",
            "m.json",
            "--until-clean",
            "4",
            "--json",
            "--out",
            "u.json",
            "k-1.csv",
            "k-2.csv",
        ],
    )?;
    let refit: Value = serde_json::from_str(&refit).context("reading refit's --json output")?;
    tfs::data::write_atomic(
        dir.join("refit.json"),
        serde_json::to_string_pretty(&refit)?,
    )?;
    let added = refit["rounds"]
        .as_array()
        .map(|rs| {
            rs.iter()
                .filter_map(|r| r["added"].as_str().map(str::to_string))
                .collect()
        })
        .unwrap_or_default();
    let start = score(tfs, dir, "m.json", truth)?;
    let end = score(tfs, dir, "u.json", truth)?;
    let end_best = score_at_best(tfs, dir, "u-best.json", &end, truth)?;
    Ok(Run {
        snr,
        seed,
        start,
        end,
        end_best,
        added,
        seconds: t0.elapsed().as_secs_f64(),
    })
}

/// A model file's force error and basin error (`tfs basin --truth kresling:truss`). A model
/// whose basin map cannot be drawn (no two stable states, say) has no basin error, and the
/// score keeps what `tfs basin` said.
fn score(tfs: &Path, dir: &Path, file: &str, truth: &ForceTruth) -> Result<Score> {
    let model = read_model(&dir.join(file))?;
    let (force_error, force_error_free) = {
        let force = model_force(&model)?;
        (
            truth.error_of(&force),
            truth.error_where(&force, |h| outside_stops(&model, h)),
        )
    };
    let basin_error = basin_error(tfs, dir, file);
    Ok(Score {
        force_error,
        force_error_free,
        basin_error,
        terms: model.equation_string(),
        stops: stop_terms(&model),
        model,
    })
}

/// The scores of `score.model` with its powers at their least-squares best
/// ([`powers_at_best`]; written to `file` in `dir` for `tfs basin`), or `None` when it has no
/// power term.
fn score_at_best(
    tfs: &Path,
    dir: &Path,
    file: &str,
    score: &Score,
    truth: &ForceTruth,
) -> Result<Option<Score>> {
    let Some(best) = powers_at_best(&score.model, truth)? else {
        return Ok(None);
    };
    tfs::data::write_atomic(dir.join(file), best.to_json_string()?)?;
    self::score(tfs, dir, file, truth).map(Some)
}

/// `tfs basin --truth kresling:truss` on a model file: the share of the map that settles in
/// another well than the truth's, or what `tfs basin` said instead.
fn basin_error(tfs: &Path, dir: &Path, file: &str) -> std::result::Result<f64, String> {
    tfs_run(
        tfs,
        dir,
        &[
            "basin",
            "--model",
            file,
            "--truth",
            "kresling:truss",
            "--json",
        ],
    )
    .map_err(|e| format!("{e:#}"))
    .and_then(|out| {
        let v: Value = serde_json::from_str(&out)
            .map_err(|e| format!("reading tfs basin's --json output: {e}"))?;
        v["boa_error"]
            .as_f64()
            .ok_or_else(|| "tfs basin gave no boa_error".to_string())
    })
}

/// The stop terms (`below`, `above`) of a model's equations with their coefficients.
fn stop_terms(model: &Model) -> Vec<String> {
    model
        .equations
        .iter()
        .flat_map(|e| &e.terms)
        .filter(|t| {
            t.term
                .factors()
                .iter()
                .any(|f| matches!(f, Factor::Below(..) | Factor::Above(..)))
        })
        .map(|t| format!("{}, k = {}", t.term, f4(t.coef)))
        .collect()
}

fn run_json(r: &Run) -> Value {
    let s = |s: &Score| {
        json!({"force_error": num(s.force_error),
            "force_error_outside_stops": s.force_error_free.map_or(Value::Null, num),
            "basin_error": s.basin_error.as_ref().map_or(Value::Null, |b| num(*b)),
            "basin_note": s.basin_error.as_ref().err(), "stops": s.stops,
            "model": s.terms})
    };
    json!({"snr_db": r.snr, "seed": r.seed, "start": s(&r.start), "end": s(&r.end),
        "end_powers_at_best": r.end_best.as_ref().map_or(Value::Null, s),
        "added": r.added, "seconds": r.seconds})
}

fn report(args: &Args, runs: &[Run], floor: f64, with_stop: &[StopFloor]) -> String {
    let bound = FLOOR_FACTOR * floor;
    let basin = |b: &std::result::Result<f64, String>| match b {
        Ok(b) => pct(*b),
        Err(_) => "no map (below)".to_string(),
    };
    let mut s = String::new();
    s.push_str("# The diagnosis loop on the Kresling truss cell\n\n");
    s.push_str(&format!(
        "`cargo xtask truss-loop --snr {} --seeds {}`. Each run: `tfs simulate kresling --truth truss --excitation sweep:0.05:1.5:4 --excitation sweep:0.1:1.5:3.5 --duration 80 --snr-db D --seed S`, `tfs identify` with `{LIBRARY}`, `tfs refit --until-clean 4`, `tfs basin --truth kresling:truss`.\n\n",
        args.snr.iter().map(|s| s.to_string()).collect::<Vec<_>>().join(","),
        args.seeds.iter().map(|s| s.to_string()).collect::<Vec<_>>().join(","),
    ));
    s.push_str(&format!(
        "Force error: RMS of the model's restoring force per unit mass minus the truss force over {} ≤ h ≤ {} ({GRID} points), over the RMS of the truss force. Floor: the least-squares fit of `{POSITION_LIBRARY}` to the truss force on the same grid misses it by **{}**; the bound is {FLOOR_FACTOR}× that, **{}**. Basin error: share of the 200 × 200 map of starts (0 ≤ x ≤ 2, −3 ≤ v ≤ 3) that settle in another well than the truth's; bar {}.\n\n",
        H_RANGE.0,
        H_RANGE.1,
        pct(floor),
        pct(bound),
        pct(BASIN_BAR)
    ));
    s.push_str(&format!(
        "The class the loop ends with, `{POSITION_LIBRARY}` plus one stop with its position and stiffness free (least squares on the same grid, the position scanned over the whole range): {}. A miss below the bound but above these is the identification's (its support, its coefficients, the stop's placement), not the class's.\n\n",
        with_stop
            .iter()
            .map(|f| format!("with `{}`, **{}**", f.stop, pct(f.error)))
            .collect::<Vec<_>>()
            .join("; ")
    ));
    s.push_str("At its powers' best: the final model with the coefficients of its displacement powers replaced by their least-squares best against the truss force on the same grid (the stop's force taken out first), its dashpot, input and stop as identified — what the model's own terms could reach, so a miss there is the support's (which powers the records let `identify` keep), not the coefficients'. Where no stop acts: the end model's force error over the heights above its `below` stops and under its `above` stops, over the truss force's RMS there — the rest of the miss is the contact's (a stop placed inside the range instead of at its edge).\n\n");
    s.push_str("| SNR | seed | start: force, basin | the loop added | end: force | end: force where no stop acts | end: basin | within both | at its powers' best: force, basin | time |\n|---|---|---|---|---|---|---|---|---|---|\n");
    for r in runs {
        let ok =
            r.end.force_error <= bound && r.end.basin_error.as_ref().is_ok_and(|b| *b < BASIN_BAR);
        let at_best = r.end_best.as_ref().map_or("no powers".to_string(), |b| {
            format!("{}, {}", pct(b.force_error), basin(&b.basin_error))
        });
        s.push_str(&format!(
            "| {} dB | {} | {}, {} | {} | {} | {} | {} | {} | {at_best} | {} s |\n",
            r.snr,
            r.seed,
            pct(r.start.force_error),
            basin(&r.start.basin_error),
            if r.added.is_empty() {
                "nothing".to_string()
            } else if r.end.stops.is_empty() {
                r.added.join(", ")
            } else {
                format!("{}: {}", r.added.join(", "), r.end.stops.join("; "))
            },
            pct(r.end.force_error),
            r.end.force_error_free.map_or("—".to_string(), pct),
            basin(&r.end.basin_error),
            if ok { "yes" } else { "no" },
            f4(r.seconds)
        ));
    }
    for r in runs {
        let scores = [
            ("start", Some(&r.start)),
            ("end", Some(&r.end)),
            ("end (its powers at their best)", r.end_best.as_ref()),
        ];
        for (which, sc) in scores {
            if let Some(Err(why)) = sc.map(|sc| &sc.basin_error) {
                s.push_str(&format!(
                    "\n{} dB, seed {}, {which} model: no basin map: {why}\n",
                    r.snr, r.seed
                ));
            }
        }
    }
    s.push_str("\nFinal models:\n\n");
    for r in runs {
        s.push_str(&format!(
            "- {} dB, seed {}: `{}`\n",
            r.snr, r.seed, r.end.terms
        ));
    }
    s
}

/// The truss force and each seed's final model at one noise level: `force-<snr>dB.png/.svg`.
fn figure(out: &Path, snr: f64, runs: &[Run], truth: &ForceTruth) -> Result<()> {
    let mut chart = LineChart::new(
        format!("Restoring force after the loop, {snr} dB"),
        "cell height h (length unit of the crease lengths)",
        "restoring force per unit mass F(h)/m (length/s²)",
    );
    let pts: Vec<(f64, f64)> = truth
        .h
        .iter()
        .zip(&truth.f)
        .step_by(50)
        .map(|(h, f)| (*h, *f))
        .collect();
    chart = chart.with_series(Series::line("truss force (truth)", pts).color(0));
    for (k, r) in runs.iter().filter(|r| r.snr == snr).enumerate() {
        let f = model_force(&r.end.model)?;
        let pts = curve(H_RANGE.0, H_RANGE.1, 361, f);
        chart = chart.with_series(
            Series::dashed(format!("seed {}: {}", r.seed, pct(r.end.force_error)), pts)
                .color(k + 1),
        );
    }
    Figure::from(chart).save(&out.join(format!("force-{snr}dB")))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The floor is what the best coefficients reach: a model built from them scores the floor,
    /// a model with one of them off scores worse, and a library holding the truth scores 0.
    #[test]
    fn floor_is_the_best_error_of_the_library() {
        use faer::prelude::Solve;
        let truth = ForceTruth::new(curve(0.0, 1.8, 901, |h| (3.0 * h).sin() + 0.1 * h));
        let floor = truth.floor("x^1..3").unwrap();
        assert!(floor > 0.01 && floor < 1.0, "{floor}");
        // The best cubic, found independently by the normal equations on the same grid.
        let cols = |h: f64| [h, h * h, h * h * h];
        let mut g = Mat::<f64>::zeros(3, 3);
        let mut b = Mat::<f64>::zeros(3, 1);
        for (h, f) in truth.h.iter().zip(&truth.f) {
            let c = cols(*h);
            for i in 0..3 {
                b[(i, 0)] += c[i] * f;
                for j in 0..3 {
                    g[(i, j)] += c[i] * c[j];
                }
            }
        }
        let xi = g.partial_piv_lu().solve(&b);
        let best = |h: f64| (0..3).map(|i| xi[(i, 0)] * cols(h)[i]).sum::<f64>();
        assert!((truth.error_of(best) / floor - 1.0).abs() < 1e-6);
        let off = |h: f64| best(h) + 0.05 * h;
        assert!(truth.error_of(off) > floor * 1.01);
        let poly = ForceTruth::new(curve(0.0, 1.8, 901, |h| 2.0 * h - h.powi(3)));
        assert!(poly.floor("x^1..3").unwrap() < 1e-12);
    }

    /// A truth in the span of a cubic plus a stop: the class floor finds the stop's position
    /// and reaches zero, where the cubic alone cannot; a stop on the other side helps no more
    /// than the cubic alone.
    #[test]
    fn the_floor_with_a_stop_finds_the_stops_position() {
        let truth = ForceTruth::new(curve(0.0, 1.8, 1801, |h| {
            2.0 * h - h.powi(3) + 40.0 * (h - 1.3).max(0.0)
        }));
        let bare = truth.floor("x^1..3").unwrap();
        assert!(bare > 0.01, "{bare}");
        let above = truth.floor_with_stop("x^1..3", Side::Above).unwrap();
        assert!(above.error < 1e-9, "{above:?}");
        assert_eq!(above.stop, "above(x, 1.3)");
        let below = truth.floor_with_stop("x^1..3", Side::Below).unwrap();
        assert!(
            below.error <= bare && below.error > 0.5 * bare,
            "{below:?} against {bare}"
        );
    }

    /// `x'' = a·x + b·x^3 − 0.5·x' − xb_acc + 100·below(x, 0.1)`.
    fn cell_model(a: f64, b: f64) -> Model {
        Model::from_json_str(&format!(
            r#"{{"format": "tfs-model/1", "dofs": ["x"], "inputs": ["xb_acc"],
                "equations": [{{"dof": "x", "terms": [
                  {{"term": "x", "coef": {a}}}, {{"term": "x^3", "coef": {b}}},
                  {{"term": "x'", "coef": -0.5}}, {{"term": "xb_acc", "coef": -1.0}},
                  {{"term": "below(x, 0.1)", "coef": 100.0}}]}}]}}"#
        ))
        .unwrap()
    }

    /// At their best the powers reach the truth where the truth is in their span (a stop's
    /// force taken out first), and the library's floor where it is not; the other terms keep
    /// their coefficients.
    #[test]
    fn powers_at_best_reach_the_supports_floor() {
        let m = cell_model(-1.5, 0.7);
        let stop = |h: f64| -100.0 * (0.1 - h).max(0.0);
        let truth = ForceTruth::new(curve(0.0, 1.8, 901, |h| 2.0 * h - h.powi(3) + stop(h)));
        assert!(truth.error_of(model_force(&m).unwrap()) > 0.05);
        let best = powers_at_best(&m, &truth).unwrap().unwrap();
        assert!(truth.error_of(model_force(&best).unwrap()) < 1e-12);
        let coefs: Vec<f64> = best.equations[0].terms.iter().map(|t| t.coef).collect();
        assert!((coefs[0] + 2.0).abs() < 1e-9 && (coefs[1] - 1.0).abs() < 1e-9);
        assert_eq!(coefs[2..], [-0.5, -1.0, 100.0]);
        // Out of the span, no stop: the best is the floor of the same powers.
        let wavy = ForceTruth::new(curve(0.0, 1.8, 901, |h| (3.0 * h).sin()));
        let mut free = m.clone();
        free.equations[0].terms.pop();
        let best = powers_at_best(&free, &wavy).unwrap().unwrap();
        let err = wavy.error_of(model_force(&best).unwrap());
        assert!(
            (err / wavy.floor("x, x^3").unwrap() - 1.0).abs() < 1e-9,
            "{err}"
        );
        // No power, no best.
        free.equations[0].terms.drain(..2);
        assert!(powers_at_best(&free, &wavy).unwrap().is_none());
    }

    /// Each run executes `--tfs` from its own folder: a relative path is made absolute, and a
    /// missing file is an error naming the option.
    #[test]
    fn a_relative_tfs_path_is_made_absolute() {
        // Tests run in the crate's folder, which holds its Cargo.toml.
        let p = tfs_binary(Some(Path::new("Cargo.toml"))).unwrap();
        assert!(p.is_absolute() && p.is_file(), "{}", p.display());
        let e = tfs_binary(Some(Path::new("no-such-tfs"))).unwrap_err();
        assert!(format!("{e:#}").contains("--tfs no-such-tfs"), "{e:#}");
    }

    /// A model's force is `−x''` at rest: the dashpot and the input do not enter it, a stop
    /// does where it engages.
    #[test]
    fn the_error_where_no_stop_acts_leaves_the_contact_out() {
        // The model's polynomial is the truth; its stop below(x, 0.1) adds force only under
        // h = 0.1, where the truth has none: the whole-grid error is the contact's alone.
        let truth = ForceTruth::new(curve(0.0, 1.8, 901, |h| 2.0 * h - h.powi(3)));
        let m = cell_model(-2.0, 1.0);
        let f = model_force(&m).unwrap();
        assert!(truth.error_of(&f) > 0.05, "{}", truth.error_of(&f));
        let free = truth.error_where(&f, |h| outside_stops(&m, h)).unwrap();
        assert!(free < 1e-12, "{free}");
        assert!(outside_stops(&m, 0.1) && !outside_stops(&m, 0.0999));
        assert_eq!(truth.error_where(&f, |_| false), None);
    }

    #[test]
    fn model_force_is_the_restoring_part() {
        let m = cell_model(-2.0, 1.0);
        let f = model_force(&m).unwrap();
        assert!((f(0.5) - (2.0 * 0.5 - 0.125)).abs() < 1e-12);
        assert!((f(0.0) - (-100.0 * 0.1)).abs() < 1e-12);
    }

    /// The truth is the cell `tfs simulate kresling` simulates: zero force at its two stable
    /// states, none between them.
    #[test]
    fn the_truth_is_the_default_cell() {
        let t = ForceTruth::kresling(H_RANGE, 1801).unwrap();
        let cell = KreslingCell::new(Default::default()).unwrap();
        for s in cell.stable() {
            let i = t.h.iter().position(|h| (h - s).abs() < 5e-4).unwrap();
            assert!(t.f[i].abs() < 0.05 * t.rms, "{} at {s}", t.f[i]);
        }
        assert!(t.rms > 0.0 && t.f.iter().all(|f| f.is_finite()));
    }
}
