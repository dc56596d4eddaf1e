//! `cargo xtask peers`: tfs side by side with PySINDy (weak form and classical) and our own
//! classical SINDy on the same CSV files, every model scored by the same Rust code.
//!
//! Records: the paper's S-DOF Kresling cell with the surrogate truth (m = 1, c = 2), four training
//! sweeps and one test sweep of base acceleration with a 2 s ramp in and out, 200 Hz, noise on x
//! and xb_acc at each SNR. Scores: relative RMS error of the restoring force over 0 ≤ h ≤ 1.8, BOA
//! error on a 200×200 grid of (x0, v0) ∈ [0, 2] × [−3, 3], test R-MSE against the noise-free test
//! displacement when the model is driven by the measured test input, and fit time.
//!
//! A benchmark, not a test: CI does not run it.
//!
//! Files: this module (the cases and one draw from records to scores), [`records`] (the truth
//! and the CSV files both sides read), [`python`] (the pinned PySINDy environment and its run) and
//! [`output`] (tables, figures and the summary over draws).

mod output;
mod python;
mod records;

use output::{num, pct, slug, write_draws_summary, write_outputs};
use python::{Fit, pysindy, venv};
use records::{score, truth_model, truth_set, write_records};

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, anyhow, bail};
use serde_json::{Value, json};
use tfs::basin::{BasinConfig, BasinMap};
use tfs::criteria::{IdentifySpec, TransformForm, identify_sindy, identify_tfs};
use tfs::data::{Record, read_csv};
use tfs::origami::{CellForce, SystemSpec};

/// Training sweeps (f0 Hz, f1 Hz, duration s, amplitude).
const TRAIN: [(f64, f64, f64, f64); 4] = [
    (0.05, 1.5, 100.0, 3.0),
    (0.05, 1.5, 60.0, 4.0),
    (0.1, 1.2, 80.0, 5.0),
    (0.05, 2.0, 120.0, 6.0),
];
/// Test sweep.
const TEST: (f64, f64, f64, f64) = (0.08, 1.4, 90.0, 4.5);
/// Sampling interval (200 Hz).
const DT: f64 = 0.005;
/// Linear ramp in and out (s).
const RAMP: f64 = 2.0;
/// T-F-S library of the paper.
const TFS_LIBRARY: &str = "x^1..7, x', xb_acc";
/// Timed repetitions of every tfs fit (the median is reported).
const FIT_TIMINGS: usize = 5;
/// Classical library (Appendix B: 35 monomials of x, x' plus the input = 36 columns); PySINDy uses
/// the same columns.
const CLASSICAL_LIBRARY: &str = "poly(x, x'; 1..7), xb_acc";
/// Method name of the reference row: the true model, scored like the identified ones.
const TRUTH_ROW: &str = "truth (reference)";
/// Force-error range of h.
const FORCE_RANGE: (f64, f64) = (0.0, 1.8);
/// Equilibrium search range.
const SEARCH: (f64, f64) = (-0.6, 2.6);

/// Smallest error (percent) drawn on the log-scale figures.
const LOG_FLOOR_PCT: f64 = 0.001;

/// Arguments of `cargo xtask peers`.
#[derive(Debug, Clone, clap::Args)]
pub struct PeersArgs {
    /// Output folder (CSVs, models, table, figure).
    #[arg(long, default_value = "target/peers")]
    pub out: PathBuf,
    /// Python virtual environment with pysindy, created on first use and shared by every `--out`
    /// (reinstalled only when `xtask/peers/requirements.txt` changes).
    #[arg(long, default_value = "target/peers/venv")]
    pub venv: PathBuf,
    /// Shorter records (30%) and a 61×61 basin grid.
    #[arg(long)]
    pub quick: bool,
    /// Noise cases: white SNRs in dB, `pinkNN` for pink noise (e.g. `60,30,20,pink30,10`).
    #[arg(long, value_delimiter = ',', default_value = "60,30,20,pink30,10")]
    pub snr: Vec<String>,
    /// Skip PySINDy (no venv, no Python); tfs and classical SINDy only.
    #[arg(long)]
    pub no_python: bool,
    /// Python used to create the virtual environment.
    #[arg(long, default_value = "python3")]
    pub python: String,
    /// Only redraw the table and figures from an existing `<out>/peers.json` (no simulation,
    /// no fitting).
    #[arg(long)]
    pub replot: bool,
    /// Noise realisation: 0 writes the records of the published table; K > 0 draws new noise for
    /// every case (same truth, sweeps and SNRs), to see how much a result moves from one draw to
    /// the next. Use a separate `--out` per draw.
    #[arg(long, default_value_t = 0)]
    pub draw: u64,
    /// Run noise realisations 0..N (draw 0 into `--out`, draw K into `<out>/draw-K`) and write
    /// `peers_draws.md`/`.json`: every cell's median and range over the draws, and in how many
    /// draws each tfs variant is at or below PySINDy weak. One draw decides little: the
    /// oracle-chosen weak form swings by two orders of magnitude between draws.
    #[arg(long, default_value_t = 1)]
    pub draws: u64,
}

/// One noise case.
#[derive(Debug, Clone, Copy)]
struct Case {
    snr: f64,
    pink: bool,
}

impl Case {
    fn parse(s: &str) -> Result<Self> {
        let t = s.trim().to_ascii_lowercase();
        let (pink, num) = match t.strip_prefix("pink") {
            Some(r) => (true, r),
            None => (false, t.strip_prefix("white").unwrap_or(&t)),
        };
        let snr: f64 = num
            .trim()
            .parse()
            .map_err(|_| anyhow!("--snr '{s}': not a number; use e.g. 60 or pink30"))?;
        if !snr.is_finite() {
            bail!("--snr '{s}': must be finite");
        }
        Ok(Self { snr, pink })
    }
    fn key(&self) -> String {
        format!("{}{}", if self.pink { "pink" } else { "white" }, self.snr)
    }
    /// Base seed of the case's noise: fixed per case, so `--snr 30` alone writes the same records
    /// as the 30 dB case of the default list (the default cases keep the seeds of their list
    /// positions, 1000 + 100·i; any other case gets one from its key).
    fn seed_base(&self) -> u64 {
        const DEFAULT: [&str; 5] = ["white60", "white30", "white20", "pink30", "white10"];
        let key = self.key();
        match DEFAULT.iter().position(|k| *k == key) {
            Some(i) => 1000 + 100 * i as u64,
            None => {
                // FNV-1a of the key: stable across runs and platforms.
                let h = key.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
                    (h ^ b as u64).wrapping_mul(0x0000_0100_0000_01b3)
                });
                10_000 + h % 1_000_000
            }
        }
    }
    /// Seed of the case's noise in realisation `draw` (0 = [`Case::seed_base`]); the stride keeps
    /// the draws of different cases apart.
    fn seed(&self, draw: u64) -> u64 {
        self.seed_base() + 7_919 * draw
    }
    fn label(&self) -> String {
        format!(
            "{} dB {}",
            self.snr,
            if self.pink { "pink" } else { "white" }
        )
    }
}

/// The truth: force law, its basin map, wells.
struct TruthSet {
    spec: SystemSpec,
    law: CellForce,
    mass: f64,
    map: BasinMap,
}

/// Scores of one model.
struct Score {
    force_error: f64,
    boa_error: std::result::Result<f64, String>,
    r_mse: std::result::Result<f64, String>,
}

/// Entry point of `cargo xtask peers`.
pub fn run(args: PeersArgs) -> Result<()> {
    let t_all = Instant::now();
    if args.replot {
        let file = args.out.join("peers.json");
        let text = std::fs::read_to_string(&file).with_context(|| {
            format!(
                "--replot: reading {}; run `cargo xtask peers` first",
                file.display()
            )
        })?;
        let v: Value = serde_json::from_str(&text)
            .with_context(|| format!("--replot: {} is not JSON", file.display()))?;
        let rows = v["rows"]
            .as_array()
            .with_context(|| format!("--replot: {} has no 'rows' array", file.display()))?;
        write_outputs(
            &args.out,
            rows,
            v["quick"].as_bool().unwrap_or(false),
            v["draw"].as_u64().unwrap_or(0),
            v["total_seconds"].as_f64().unwrap_or(f64::NAN),
        )?;
        eprintln!("redrew {}/peers.md and the figures", args.out.display());
        return Ok(());
    }
    let cases = args
        .snr
        .iter()
        .map(|s| Case::parse(s))
        .collect::<Result<Vec<_>>>()?;
    if cases.is_empty() {
        bail!("--snr is empty; give at least one case, e.g. --snr 60,30");
    }
    if args.draws == 0 {
        bail!("--draws 0: give at least 1");
    }
    if args.draws > 1 && args.draw != 0 {
        bail!(
            "--draws {} runs draws 0..{} itself; leave out --draw",
            args.draws,
            args.draws
        );
    }
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating the output folder {}", args.out.display()))?;
    let scale = if args.quick { 0.3 } else { 1.0 };
    let n = if args.quick { 61 } else { 200 };
    let cfg = BasinConfig::new(n, n, (0.0, 2.0), (-3.0, 3.0));
    eprintln!("truth basin map ({n}×{n}) …");
    let truth = truth_set(&cfg)?;
    let python = if args.no_python {
        None
    } else {
        Some(venv(&args)?)
    };
    let mut all = Vec::new();
    for k in 0..args.draws {
        let (out, draw) = if args.draws == 1 {
            (args.out.clone(), args.draw)
        } else {
            if k > 0 {
                eprintln!("draw {k} of 0..{} …", args.draws);
            }
            let out = if k == 0 {
                args.out.clone()
            } else {
                args.out.join(format!("draw-{k}"))
            };
            (out, k)
        };
        let ctx = DrawContext {
            args: &args,
            cases: &cases,
            truth: &truth,
            cfg: &cfg,
            scale,
            python: python.as_deref(),
        };
        all.push(run_draw(&ctx, &out, draw)?);
    }
    if args.draws > 1 {
        write_draws_summary(&args.out, &all, args.quick)?;
        eprintln!(
            "wrote {}/peers_draws.md and peers_draws.json ({:.0} s)",
            args.out.display(),
            t_all.elapsed().as_secs_f64()
        );
    }
    Ok(())
}

/// What every draw of one `cargo xtask peers` run shares.
struct DrawContext<'a> {
    args: &'a PeersArgs,
    cases: &'a [Case],
    truth: &'a TruthSet,
    cfg: &'a BasinConfig,
    scale: f64,
    python: Option<&'a Path>,
}

/// One noise realisation `draw` of every case, written to `out` (records, models, table,
/// figures); returns the table's rows.
fn run_draw(ctx: &DrawContext<'_>, out: &Path, draw: u64) -> Result<Vec<Value>> {
    let t_all = Instant::now();
    let (args, cases, truth, cfg, scale) = (ctx.args, ctx.cases, ctx.truth, ctx.cfg, ctx.scale);
    std::fs::create_dir_all(out)
        .with_context(|| format!("creating the output folder {}", out.display()))?;
    let mut rows: Vec<Value> = Vec::new();
    for (ci, case) in cases.iter().enumerate() {
        eprintln!("[{}/{}] {} …", ci + 1, cases.len(), case.label());
        let dir = out.join("data").join(case.key());
        let clean_test = write_records(truth, *case, scale, case.seed(draw), &dir)?;
        let train: Vec<Record> = (1..=TRAIN.len())
            .map(|i| read_csv(dir.join(format!("train{i}.csv"))).map_err(anyhow::Error::from))
            .collect::<Result<_>>()?;
        let test = read_csv(dir.join("test.csv"))?;
        let models_dir = out.join("models").join(case.key());
        std::fs::create_dir_all(&models_dir)?;
        // The truth itself, scored by the same code: its test R-MSE is what the noise on the
        // measured test input alone costs a perfect model (a snap-through sweep amplifies it).
        let mut fits: Vec<Fit> = vec![(
            TRUTH_ROW.to_string(),
            truth_model(truth)
                .map(|m| (m, f64::NAN))
                .map_err(|e| format!("{e:#}")),
            Value::Null,
        )];
        let tfs_spec = |form: TransformForm, lib: &str| {
            let mut s = IdentifySpec::new(&["x"], lib);
            s.tfs.criterion3.form = form;
            s
        };
        for (name, spec, classical) in [
            ("tfs", tfs_spec(TransformForm::Weak, TFS_LIBRARY), false),
            (
                "tfs (plain FFT, paper)",
                tfs_spec(TransformForm::PlainSavitzkyGolay, TFS_LIBRARY),
                false,
            ),
            (
                "tfs (classical library)",
                tfs_spec(TransformForm::Weak, CLASSICAL_LIBRARY),
                false,
            ),
            (
                "SINDy (tfs, classical)",
                tfs_spec(TransformForm::Weak, CLASSICAL_LIBRARY),
                true,
            ),
        ] {
            // Fit time: the median of five identical calls (the first one also pays for FFT
            // planning and the thread pool's start; PySINDy's reported time likewise excludes
            // its import and the velocity smoothing it shares between candidates).
            let run = || {
                if classical {
                    identify_sindy(&train, &spec)
                } else {
                    identify_tfs(&train, &spec)
                }
            };
            let mut times = Vec::with_capacity(FIT_TIMINGS);
            let mut r = None;
            for _ in 0..FIT_TIMINGS {
                let t0 = Instant::now();
                let out = run();
                times.push(t0.elapsed().as_secs_f64());
                let failed = out.is_err();
                r = Some(out);
                if failed {
                    break;
                }
            }
            let r = r.expect("at least one fit");
            times.sort_by(f64::total_cmp);
            let secs = times[times.len() / 2];
            fits.push((
                name.to_string(),
                r.map(|id| (id.model_with_trace(), secs))
                    .map_err(|e| e.to_string()),
                Value::Null,
            ));
        }
        if let Some(py) = ctx.python {
            fits.extend(pysindy(py, &dir, &models_dir, &test, &clean_test)?);
        }
        for (name, fit, extra) in fits {
            let row = match fit {
                Ok((model, secs)) => {
                    let file = models_dir.join(format!("{}.json", slug(&name)));
                    model
                        .write_path(&file)
                        .with_context(|| format!("writing {}", file.display()))?;
                    let t0 = Instant::now();
                    let s = score(&model, truth, cfg, &test, &clean_test);
                    let fit = if secs.is_finite() {
                        format!("{secs:.2} s")
                    } else {
                        "—".into()
                    };
                    eprintln!(
                        "  {name:<26} force {:>9}  BOA {:>9}  R-MSE {:>9}  fit {fit}  (scored in {:.1} s)",
                        pct(s.force_error),
                        s.boa_error.as_ref().map_or("failed".into(), |v| pct(*v)),
                        s.r_mse.as_ref().map_or("failed".into(), |v| pct(*v)),
                        t0.elapsed().as_secs_f64()
                    );
                    json!({"case": case.label(), "snr_db": case.snr, "pink": case.pink, "method": name,
                        "force_error": num(s.force_error), "boa_error": s.boa_error.as_ref().ok().map(|v| num(*v)),
                        "boa_failure": s.boa_error.err(), "test_r_mse": s.r_mse.as_ref().ok().map(|v| num(*v)),
                        "r_mse_failure": s.r_mse.err(), "fit_seconds": secs, "equation": model.equation_string(),
                        "model_file": file.display().to_string(), "selection": extra})
                }
                Err(e) => {
                    eprintln!("  {name:<26} failed: {e}");
                    json!({"case": case.label(), "snr_db": case.snr, "pink": case.pink, "method": name, "failure": e})
                }
            };
            rows.push(row);
        }
        // Rewrite the table after every case so an interrupted run keeps what it finished.
        write_outputs(out, &rows, args.quick, draw, t_all.elapsed().as_secs_f64())?;
    }
    let total = t_all.elapsed().as_secs_f64();
    write_outputs(out, &rows, args.quick, draw, total)?;
    eprintln!(
        "wrote {}/peers.md, peers.json, peers_force_error.svg, peers_boa_error.svg ({total:.0} s)",
        out.display()
    );
    Ok(rows)
}

#[cfg(test)]
mod tests {
    use super::*;
    use tfs::data::write_csv;
    use tfs::origami::{DatasetConfig, Excitation, NoiseKind, generate};

    /// The draws summary takes the median over draws (a failure counting as the worst value)
    /// and counts the draws in which tfs is at or below PySINDy weak.
    #[test]
    fn draws_summary_takes_medians_and_counts_wins() {
        let row = |m: &str, f: Option<f64>, b: f64| {
            let mut r =
                json!({"case": "20 dB white", "method": m, "boa_error": b, "fit_seconds": 0.01});
            if let Some(f) = f {
                r["force_error"] = json!(f);
            } else {
                r["failure"] = json!("blew up");
            }
            r
        };
        let draws = vec![
            vec![
                row("tfs", Some(0.02), 0.009),
                row("PySINDy weak", Some(0.15), 0.006),
            ],
            vec![
                row("tfs", Some(0.03), 0.004),
                row("PySINDy weak", Some(0.20), 0.725),
            ],
            vec![
                row("tfs", None, 0.012),
                row("PySINDy weak", Some(0.10), 0.791),
            ],
        ];
        let dir = std::env::temp_dir().join(format!("tfs-peers-draws-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        write_draws_summary(&dir, &draws, false).unwrap();
        let md = std::fs::read_to_string(dir.join("peers_draws.md")).unwrap();
        // tfs force: 2 %, 3 %, failed → median 3 %; BOA 0.9, 0.4, 1.2 % → median 0.9 %.
        assert!(
            md.contains("| 20 dB white | tfs | 3.00% (2.00%–failed) | 0.90% (0.40%–1.20%)"),
            "{md}"
        );
        // Force: tfs below weak in draws 0 and 1 (a failure is never below); BOA in draws 1, 2.
        assert!(
            md.contains("| 20 dB white | tfs | 2 of 3 | 2 of 3 |"),
            "{md}"
        );
        let v: Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join("peers_draws.json")).unwrap())
                .unwrap();
        assert_eq!(v["cells"][0]["force_error"][2], Value::Null);
        std::fs::remove_dir_all(&dir).ok();
    }

    /// A case's records do not depend on where it sits in `--snr`: the default cases keep the
    /// seeds of the default list, other cases get distinct ones.
    #[test]
    fn case_seeds_follow_the_case_not_its_position() {
        let seed = |s: &str| Case::parse(s).unwrap().seed_base();
        assert_eq!(seed("60"), 1000);
        assert_eq!(seed("30"), 1100);
        assert_eq!(seed("pink30"), 1300);
        assert_eq!(seed("10"), 1400);
        let others = [seed("25"), seed("pink20"), seed("40")];
        assert!(others.iter().all(|s| *s >= 10_000));
        assert!(others[0] != others[1] && others[1] != others[2] && others[0] != others[2]);
        assert_eq!(seed("25"), seed(" 25 "));
        // Draw 0 is the published table; other draws give every case new, distinct noise.
        let c = Case::parse("20").unwrap();
        assert_eq!(c.seed(0), c.seed_base());
        let draws: Vec<u64> = (0..4).map(|k| c.seed(k)).collect();
        assert!(draws.windows(2).all(|w| w[0] != w[1]));
        assert!(
            draws
                .iter()
                .all(|s| *s != Case::parse("30").unwrap().seed(0))
        );
    }

    #[test]
    fn cases_parse_white_and_pink_and_reject_junk() {
        let c = Case::parse("30").unwrap();
        assert!(!c.pink && c.snr == 30.0);
        let p = Case::parse(" Pink30 ").unwrap();
        assert!(p.pink && p.snr == 30.0);
        assert_eq!(p.key(), "pink30");
        assert!(
            Case::parse("loud")
                .unwrap_err()
                .to_string()
                .contains("--snr 'loud'")
        );
        assert!(Case::parse("inf").is_err());
    }

    #[test]
    fn slug_is_file_safe() {
        assert_eq!(slug("tfs (plain FFT, paper)"), "tfs_plain_fft_paper");
    }

    /// The truth written as a model must score zero on every measure: an independent check that
    /// the scoring code compares like with like (signs, mass, input convention, grids).
    #[test]
    fn the_truth_as_a_model_scores_zero() {
        let cfg = BasinConfig::new(21, 21, (0.0, 2.0), (-3.0, 3.0));
        let truth = truth_set(&cfg).unwrap();
        let model = truth_model(&truth).unwrap();
        // A short noise-free sweep as the test record.
        let dir = tempfile::tempdir().unwrap();
        let short = DatasetConfig {
            system: truth.spec.clone(),
            excitations: vec![Excitation::Sweep {
                f0: 0.2,
                f1: 1.0,
                amplitude: 4.0,
                log: false,
                ramp: RAMP,
            }],
            duration: 10.0,
            dt: DT,
            snr_db: None,
            noise: NoiseKind::White,
            seed: 1,
            x0: None,
            v0: None,
            rtol: 1e-10,
        };
        let ds = generate(&short).unwrap();
        let r = &ds.records[0];
        let rec = Record::new(
            "test",
            r.t().to_vec(),
            vec![
                ("x".into(), r.column("x").unwrap().to_vec()),
                ("xb_acc".into(), r.column("xb_acc").unwrap().to_vec()),
            ],
        )
        .unwrap();
        write_csv(dir.path().join("test.csv"), &rec).unwrap();
        let test = read_csv(dir.path().join("test.csv")).unwrap();
        let s = score(&model, &truth, &cfg, &test, r.column("x_clean").unwrap());
        assert!(s.force_error < 1e-9, "force error {}", s.force_error);
        assert!(s.boa_error.unwrap() <= 1.0 / 441.0);
        assert!(s.r_mse.unwrap() < 1e-3);
    }
}
