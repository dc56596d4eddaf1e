//! Study 4: Appendix B, T-F-S against classical SINDy on the same 30 dB data (Table B1).

use std::time::Instant;

use anyhow::{Context, Result};
use serde_json::json;
use tfs::criteria::{IdentifySpec, identify_sindy, identify_tfs};
use tfs::data::Record;
use tfs::library::Model;
use tfs::origami::NoiseKind;
use tfs::plot::{LineChart, Series};

use crate::common::{Opts, coef, f4, num, progress, sim_rmse, terms};
use crate::report::{Study, Table};

use super::b1_pysindy::{self, PySindyFit, PythonChoice};
use super::{SINDY_LIBRARY, TFS_LIBRARY, records, truth};

/// The derivatives classical SINDy is offered, in the order tried: central differences (the
/// library's default), then Savitzky–Golay filters of half-width 5, 10, 20 and 40 samples
/// (cubic), the windows PySINDy's row is offered too (2h + 1 samples).
const DERIVATIVES: [Option<(usize, usize)>; 5] = [
    None,
    Some((5, 3)),
    Some((10, 3)),
    Some((20, 3)),
    Some((40, 3)),
];

/// A derivative: central differences (`None`) or a Savitzky–Golay (half-width, order).
type Derivative = Option<(usize, usize)>;

/// A derivative choice in words.
fn derivative_name(sg: Option<(usize, usize)>) -> String {
    match sg {
        None => "central differences".into(),
        Some((h, p)) => format!("Savitzky–Golay, {} samples, order {p}", 2 * h + 1),
    }
}

/// One derivative offered to classical SINDy: the threshold its identification on every
/// record chose, and the model of that threshold fitted without the held-out record, simulated
/// on it.
struct Offered {
    sg: Option<(usize, usize)>,
    threshold: f64,
    terms: usize,
    held_out: std::result::Result<f64, String>,
}

/// Chooses classical SINDy's derivative as a careful user would, the same way as PySINDy's
/// window: for each derivative, the library's own threshold choice (on the last record held
/// out), that threshold's fit without the held-out record simulated on it; the derivative whose
/// fit simulates it best (central differences when none does). Returns the choice and every try.
fn choose_derivative(train: &[Record]) -> Result<(Derivative, Vec<Offered>)> {
    let (fit, held) = train.split_at(train.len() - 1);
    let mut tried = Vec::new();
    let mut best: Option<(f64, usize)> = None;
    for (i, sg) in DERIVATIVES.into_iter().enumerate() {
        let mut spec = IdentifySpec::new(&["x"], SINDY_LIBRARY);
        spec.sindy.savitzky_golay = sg;
        spec.sindy.vet_by_simulation = true;
        let what = || format!("classical SINDy with {}", derivative_name(sg));
        let all = identify_sindy(train, &spec).with_context(what)?;
        let threshold = all.trace.dofs[0].settings.threshold;
        spec.sindy.threshold = Some(threshold);
        let part = identify_sindy(fit, &spec).with_context(what)?;
        let terms = part.model.equations.iter().map(|e| e.terms.len()).sum();
        let held_out = if terms == 0 {
            Err("kept no term".into())
        } else {
            sim_rmse(&part.model, &held[0], "x").map(|r| r.0)
        };
        if let Ok(&r) = held_out.as_ref()
            && r.is_finite()
            && best.is_none_or(|b| r < b.0)
        {
            best = Some((r, i));
        }
        tried.push(Offered {
            sg,
            threshold,
            terms,
            held_out,
        });
    }
    Ok((best.and_then(|b| DERIVATIVES[b.1]), tried))
}

/// The records with x smoothed by a cubic Savitzky–Golay filter of half-width `h` (the input
/// left as measured), as PySINDy's SmoothedFiniteDifference smooths the state it differentiates
/// and builds its library on.
fn smoothed(recs: &[Record], h: usize) -> Result<Vec<Record>> {
    recs.iter()
        .map(|r| {
            let x = r
                .column("x")
                .with_context(|| format!("record '{}' has no column 'x'", r.source()))?;
            let u = r
                .column("xb_acc")
                .with_context(|| format!("record '{}' has no column 'xb_acc'", r.source()))?;
            let xs = tfs::signal::savitzky_golay(x, super::DT, h, 3, 0)?;
            Ok(Record::new(
                r.source(),
                r.t().to_vec(),
                vec![("x".into(), xs), ("xb_acc".into(), u.to_vec())],
            )?)
        })
        .collect()
}

/// The records with the noise-free channels in place of the measured ones (to separate what the
/// noise costs classical SINDy from what its derivative costs on clean data).
fn noise_free(recs: &[Record]) -> Result<Vec<Record>> {
    recs.iter()
        .map(|r| {
            let col = |n: &str| {
                r.column(n)
                    .map(<[f64]>::to_vec)
                    .with_context(|| format!("record '{}' has no column '{n}'", r.source()))
            };
            Ok(Record::new(
                r.source(),
                r.t().to_vec(),
                vec![
                    ("x".into(), col("x_clean")?),
                    ("xb_acc".into(), col("xb_acc_clean")?),
                ],
            )?)
        })
        .collect()
}

/// A simulation's R-MSE and response, or why it failed.
type SimResult = std::result::Result<(f64, Vec<f64>), String>;
/// PySINDy's fit with its test simulation, or why it was not run.
type PyRow = std::result::Result<(PySindyFit, SimResult), String>;

/// Each method is timed as the median of three calls on the same data, so neither pays a
/// one-off cost (FFT planning, thread-pool start) that the other does not.
fn timed<T>(mut f: impl FnMut() -> Result<T>) -> Result<(T, f64)> {
    let mut times = Vec::new();
    let mut last = None;
    for _ in 0..3 {
        let t0 = Instant::now();
        last = Some(f()?);
        times.push(t0.elapsed().as_secs_f64());
    }
    times.sort_by(f64::total_cmp);
    Ok((last.expect("three runs"), times[1]))
}

/// Study 4: Appendix B, Table B1 — classical SINDy vs T-F-S on the same 30 dB data, with
/// PySINDy's classical SINDy on the same records beside them.
pub fn study_table_b1(st: &mut Study, o: &Opts) -> Result<()> {
    let pb = progress(6, "App. B");
    let scale = o.pick(0.5, 1.0);
    let t = truth()?;
    pb.set_message("data");
    let (train, test) = records(&t, NoiseKind::White, 30.0, scale, 200)?;
    pb.inc(1);
    let samples: usize = train.iter().map(|r| r.len()).sum();
    let held_name = train.last().map_or("", |r| r.source()).to_string();
    st.text(format!(
        "Same 30 dB white-noise training data for every method ({} records, {samples} samples; the paper had 200,020). T-F-S library `{TFS_LIBRARY}` (pipeline defaults); classical SINDy library `{SINDY_LIBRARY}` (36 columns as in the paper). Classical SINDy is set up as a careful user would, with '{held_name}' held out. Its STLSQ threshold is the library's own choice: of the λ path's supports fitted without '{held_name}' that keep a term (x'' = 0 is no candidate), the lowest BIC of the equation error on '{held_name}' among those whose model simulates '{held_name}'; coefficients refit on all records. Its derivative (central differences, or a Savitzky–Golay filter of 11, 21, 41 or 81 samples) is the one whose chosen threshold, fitted without '{held_name}', simulates '{held_name}' best: simulation error here, because equation errors against differently differentiated x'' are not comparable. PySINDy 2.1's classical SINDy (its SmoothedFiniteDifference with the same windows, its STLSQ, 16 thresholds from 0.001 to 100) gets the same two choices on the same record, its held-out equation error computed by its own differentiation, then is refit with them on all records. Time = wall time of the final identification call (ours: with its threshold selection; PySINDy: its fit at the chosen settings, in Python), median of three calls (PySINDy: of five). R-MSE = Eq. B.2 on the test sweep, against the measured (noisy) displacement.",
        train.len()
    ));
    pb.set_message("T-F-S");
    let spec = IdentifySpec::new(&["x"], TFS_LIBRARY);
    let (a, t_tfs) = timed(|| identify_tfs(&train, &spec).context("T-F-S identification"))?;
    pb.inc(1);
    pb.set_message("classical SINDy: derivative");
    let (sg, offered) = choose_derivative(&train)?;
    pb.inc(1);
    pb.set_message("classical SINDy");
    let mut spec_s = IdentifySpec::new(&["x"], SINDY_LIBRARY);
    spec_s.sindy.savitzky_golay = sg;
    spec_s.sindy.vet_by_simulation = true;
    let (b, t_sindy) =
        timed(|| identify_sindy(&train, &spec_s).context("classical SINDy identification"))?;
    pb.inc(1);
    pb.set_message("PySINDy classical");
    let choice = match &o.venv {
        Some(v) => PythonChoice::Venv(v.clone()),
        None => PythonChoice::Off,
    };
    let py: PyRow = match b1_pysindy::run(&choice, &train, &st.out_dir().join("b1_pysindy")) {
        Ok(r) => r,
        Err(e) => Err(format!("failed: {e:#}")),
    }
    .map(|p| {
        let r = sim_rmse(&p.model, &test, "x");
        (p, r)
    });
    pb.inc(1);
    let da = &a.trace.dofs[0];
    let tfs_rows = da.assembly.last().map_or(0, |s| s.rows);
    let tfs_cols = da.regression_library.len();
    // Classical SINDy regresses on every sample except the derivative's trims at both ends.
    let trim = sg.map_or(1, |s| s.0);
    let sindy_rows: usize = train.iter().map(|r| r.len() - 2 * trim).sum();
    let sindy_cols = b.trace.dofs[0].library.len();
    let ra = sim_rmse(&a.model, &test, "x");
    let rb = sim_rmse(&b.model, &test, "x");
    // PySINDy keeps every sample (its differences have one-sided stencils at the ends).
    let shape = [
        (tfs_rows, tfs_cols),
        (sindy_rows, sindy_cols),
        (samples, sindy_cols),
    ];
    table(st, shape, [&ra, &rb], &py, [t_tfs, t_sindy])?;
    st.text(format!(
        "T-F-S model: `{}`\n\nClassical SINDy model: `{}`\n\nPySINDy classical model: {}\n\nT-F-S rows are the frequency-domain rows (real and imaginary parts of the kept bins) of the records used by the final fit; its columns are the library after Criterion 2 ({} of {}).\n\nThe paper's cost argument is that T-F-S regresses on a much smaller matrix, which its sparsification solves again for every threshold; that is the check above. The times are shown, not judged: our classical SINDy folds its rows into a small triangular factor in one pass before it sparsifies, so its regression no longer grows with the 200,020 rows that cost the paper's implementation two minutes (its time includes simulating the held-out record to vet its support). Most of T-F-S's time goes to its criteria (the noise curve of Criterion 1 and the transforms of Criterion 3), not to regression.",
        a.model.equation_string(),
        b.model.equation_string(),
        py.as_ref()
            .map_or_else(|e| format!("{e}."), |p| format!("`{}`", p.0.model.equation_string())),
        tfs_cols,
        da.library.len()
    ));
    derivative_table(st, &offered, sg, &held_name)?;
    pb.set_message("why");
    let clean = noise_free(&train)
        .and_then(|c| identify_sindy(&c, &spec_s).context("classical SINDy on noise-free records"))
        .map(|id| sim_rmse(&id.model, &test, "x").map(|r| (r.0, id.model)));
    // Our pipeline (central differences, same threshold choice) on x smoothed PySINDy's way with
    // the chosen window: what separates our derivative from PySINDy's.
    let spec_c = IdentifySpec::new(&["x"], SINDY_LIBRARY);
    let pre: Result<CleanFit> = match sg {
        Some((h, _)) => smoothed(&train, h)
            .and_then(|c| identify_sindy(&c, &spec_c).context("classical SINDy on smoothed x"))
            .map(|id| sim_rmse(&id.model, &test, "x").map(|r| (r.0, id.model))),
        None => Ok(Err("no smoothing window was chosen".into())),
    };
    why_text(st, &t, (&b.model, &rb), &py, [&clean, &pre], sg);
    pb.inc(1);
    let (ea, eb) = (ra.as_ref().map(|r| r.0).ok(), rb.as_ref().map(|r| r.0).ok());
    let better = match (ea, eb) {
        (Some(x), Some(y)) => x < y,
        (Some(_), None) => true,
        _ => false,
    };
    st.compare(
        "Table B1: test R-MSE, T-F-S vs classical",
        "0 (the measured test sweep)",
        &format!(
            "{} vs {}",
            ea.map_or("—".into(), f4),
            eb.map_or("blew up".into(), f4)
        ),
        "0.0045 vs 0.0332",
        Some(better),
        "T-F-S lower than classical SINDy",
    );
    // The paper's cost claim is its mechanism: the criteria shrink the regression problem that
    // the sparsification solves again and again. That is what is checked. The wall times are
    // shown beside the paper's but judge nothing: a timing on a shared machine is not a pass or
    // fail (the report's exit code must not depend on the load), and our classical SINDy folds
    // its rows into a small triangle in one pass before sparsifying, so it no longer pays for
    // its row count the way the paper's did.
    st.compare(
        "Table B1: regression matrix, T-F-S vs classical",
        "—",
        &format!("{tfs_rows}×{tfs_cols} vs {sindy_rows}×{sindy_cols}"),
        "2143×28 vs 200,020×36",
        Some(tfs_rows * tfs_cols < sindy_rows * sindy_cols),
        "T-F-S regresses on a smaller matrix than classical SINDy",
    );
    st.compare(
        "Table B1: fit time, T-F-S vs classical",
        "—",
        &format!("{t_tfs:.3} s vs {t_sindy:.3} s"),
        "4.4 s vs 120.72 s",
        None,
        "informational: wall time on this machine, not a check",
    );
    st.set("tfs", json!({"rows": tfs_rows, "cols": tfs_cols, "seconds": t_tfs, "test_r_mse": ea.map(num), "r_mse_error": ra.as_ref().err(), "equation": a.model.equation_string()}));
    st.set("sindy", json!({"rows": sindy_rows, "cols": sindy_cols, "seconds": t_sindy, "test_r_mse": eb.map(num), "blew_up": eb.is_none(), "r_mse_error": rb.as_ref().err(), "equation": b.model.equation_string(), "derivative": derivative_name(sg), "threshold_why": b.trace.dofs[0].settings.why, "derivatives_offered": offered.iter().map(|o| json!({"derivative": derivative_name(o.sg), "threshold": o.threshold, "terms": o.terms, "held_out_r_mse": o.held_out.as_ref().ok().map(|r| num(*r)), "held_out_error": o.held_out.as_ref().err()})).collect::<Vec<_>>()}));
    st.set("pysindy", match &py {
        Ok((p, r)) => json!({"ran": true, "version": p.version, "window": p.window, "threshold": p.threshold, "held_out_r_mse": num(p.held_out_r_mse), "candidates": p.tried.0, "candidates_simulated": p.tried.1, "seconds": p.seconds, "test_r_mse": r.as_ref().ok().map(|r| num(r.0)), "r_mse_error": r.as_ref().err(), "equation": p.model.equation_string()}),
        Err(e) => json!({"ran": false, "why": e}),
    });
    st.set("paper", json!({"tfs": {"rows": 2143, "cols": 28, "seconds": 4.4, "r_mse": 0.0045}, "sindy": {"rows": 200020, "cols": 36, "seconds": 120.72, "r_mse": 0.0332}}));
    figure(st, &test, &ra, &rb, &py)?;
    pb.inc(1);
    pb.finish_and_clear();
    Ok(())
}

/// An R-MSE cell: the number, or why the simulation failed.
fn show(r: &SimResult) -> String {
    r.as_ref()
        .map(|r| f4(r.0))
        .unwrap_or_else(|e| format!("simulation failed: {e}"))
}

/// Table B1 itself: T-F-S, our classical SINDy and PySINDy's, beside the paper's numbers.
fn table(
    st: &mut Study,
    shape: [(usize, usize); 3],
    r: [&SimResult; 2],
    py: &PyRow,
    secs: [f64; 2],
) -> Result<()> {
    let mut tab = Table::new(
        "table_b1",
        "Table B1: cost and accuracy of T-F-S vs classical SINDy on the same 30 dB data",
        &[
            "method",
            "library matrix (ours)",
            "time (ours)",
            "test R-MSE (ours)",
            "library matrix (paper)",
            "time (paper)",
            "R-MSE (paper)",
        ],
    );
    tab.row(vec![
        "T-F-S SINDy".into(),
        format!("{}×{}", shape[0].0, shape[0].1),
        format!("{:.3} s", secs[0]),
        show(r[0]),
        "2143×28".into(),
        "4.4 s".into(),
        "0.0045".into(),
    ]);
    tab.row(vec![
        "classical SINDy".into(),
        format!("{}×{}", shape[1].0, shape[1].1),
        format!("{:.3} s", secs[1]),
        show(r[1]),
        "200,020×36".into(),
        "120.72 s".into(),
        "0.0332".into(),
    ]);
    let py_row = match py {
        Ok((p, rp)) => vec![
            format!("PySINDy {} classical", p.version),
            format!("{}×{}", shape[2].0, shape[2].1),
            format!("{:.3} s", p.seconds),
            show(rp),
        ],
        Err(e) => vec![
            "PySINDy classical".into(),
            "—".into(),
            "—".into(),
            e.clone(),
        ],
    };
    tab.row(
        py_row
            .into_iter()
            .chain(["—".into(), "—".into(), "—".into()])
            .collect(),
    );
    st.table(tab)
}

/// The derivatives offered to our classical SINDy and how each one's model, identified without
/// the held-out record, simulated it.
fn derivative_table(
    st: &mut Study,
    offered: &[Offered],
    chosen: Option<(usize, usize)>,
    held: &str,
) -> Result<()> {
    let mut tab = Table::new(
        "table_b1_derivatives",
        &format!("Classical SINDy's derivative, chosen on '{held}' held out"),
        &[
            "derivative",
            "threshold (scaled)",
            &format!("terms kept without '{held}'"),
            &format!("R-MSE on '{held}'"),
            "chosen",
        ],
    );
    for o in offered {
        tab.row(vec![
            derivative_name(o.sg),
            format!("{:.4}", o.threshold),
            o.terms.to_string(),
            o.held_out.as_ref().map_or_else(|e| e.clone(), |r| f4(*r)),
            if o.sg == chosen {
                "yes".into()
            } else {
                String::new()
            },
        ]);
    }
    st.table(tab)
}

/// Damping and input coefficients of a model of the cell (`x'' = … − ζ·x' … − k·xb_acc`).
fn damping_input(m: &Model) -> (f64, f64) {
    (-coef(m, "x", "x'"), -coef(m, "x", "xb_acc"))
}

/// Says whether our classical SINDy is still worse than the paper's and PySINDy's, and why,
/// from what was measured: the terms it kept against the truth's, its damping and input
/// coefficients, and the same pipeline on the noise-free copies of the records.
fn why_text(
    st: &mut Study,
    t: &super::SdofTruth,
    ours: (&Model, &SimResult),
    py: &PyRow,
    [clean, pre]: [&Result<CleanFit>; 2],
    sg: Option<(usize, usize)>,
) {
    let (model, r) = ours;
    let truth_terms = ["x'", "x^5", "x^6", "x^7", "xb_acc"];
    let kept: Vec<String> = terms(model, "x").into_iter().map(|(n, _)| n).collect();
    let extra = kept
        .iter()
        .filter(|k| !truth_terms.contains(&k.as_str()))
        .count();
    let (zeta, input) = damping_input(model);
    let ours_r = r.as_ref().ok().map(|r| r.0);
    let py_r = match py {
        Ok((_, Ok(rp))) => Some(rp.0),
        _ => None,
    };
    let mut s = format!(
        "**Is our classical SINDy still worse?** Its test R-MSE is {} against the paper's 0.0332 and PySINDy's {}",
        ours_r.map_or("— (its simulation failed)".into(), f4),
        match py {
            Ok((_, Ok(rp))) => f4(rp.0),
            Ok((_, Err(e))) => format!("— (simulation failed: {e})"),
            Err(e) => format!("— (PySINDy {e})"),
        }
    );
    s += &match (ours_r, py_r) {
        (Some(o), Some(p)) => format!(
            ": {} than the paper's and {} than PySINDy's. ",
            if o > 0.0332 { "worse" } else { "better" },
            if o > p { "worse" } else { "better" }
        ),
        (Some(o), None) => format!(
            ": {} than the paper's. ",
            if o > 0.0332 { "worse" } else { "better" }
        ),
        _ => ". ".into(),
    };
    s += &format!(
        "With {} it kept {} of the truth's five terms (x', x^5, x^6, x^7, xb_acc) and {extra} other term{}; damping {} (truth {}), input coefficient {} (truth 1)",
        derivative_name(sg),
        truth_terms
            .iter()
            .filter(|n| kept.iter().any(|k| k == *n))
            .count(),
        if extra == 1 { "" } else { "s" },
        f4(zeta),
        f4(t.zeta),
        f4(input),
    );
    if let Ok((p, _)) = py {
        let (pz, pi) = damping_input(&p.model);
        s += &format!(
            "; PySINDy (window {}, threshold {}) {} terms, damping {}, input {}",
            p.window,
            p.threshold,
            terms(&p.model, "x").len(),
            f4(pz),
            f4(pi)
        );
    }
    s += ". ";
    match clean {
        Ok(Ok((rc, mc))) => {
            let (cz, ci) = damping_input(mc);
            s += &format!(
                "The same pipeline (same derivative, same held-out choice) on the noise-free copies of the records gives damping {}, input {}, test R-MSE {} (`{}`): ",
                f4(cz),
                f4(ci),
                f4(*rc),
                mc.equation_string()
            );
            // Which share of the coefficient error is there without noise: the derivative's own.
            let err = |z: f64, i: f64| ((z - t.zeta) / t.zeta).abs().max((i - 1.0).abs());
            let (noisy, noise_free) = (err(zeta, input), err(cz, ci));
            s += &if noise_free >= 0.5 * noisy {
                format!(
                    "on clean data the same derivative leaves {:.1} % damping/input error against {:.1} % at 30 dB, so most of the error is the derivative's own, not the noise. ",
                    100.0 * noise_free,
                    100.0 * noisy
                )
            } else {
                format!(
                    "on clean data the same derivative leaves {:.1} % damping/input error against {:.1} % at 30 dB, so most of the error is the noise the derivative passes on to x' and x'' (both sides of the regression), which classical least squares does not correct for. ",
                    100.0 * noise_free,
                    100.0 * noisy
                )
            };
            if let Ok(Ok((rs, ms))) = pre {
                let (sz, si) = damping_input(ms);
                s += &format!(
                    "Where PySINDy differs is how it differentiates: it smooths x with the window, differences the smoothed state and builds its library on it, where ours takes the Savitzky–Golay filter's own derivatives of the raw x and builds the library on the raw x. Our pipeline on x smoothed that way (same window, central differences, same threshold choice) gives damping {}, input {}, {} terms, test R-MSE {} ({:.1} % damping/input error). ",
                    f4(sz),
                    f4(si),
                    terms(ms, "x").len(),
                    f4(*rs),
                    100.0 * err(sz, si)
                );
            }
            s += "The test R-MSE of this bistable cell is steep in the coefficients: a few per cent of damping or input gain move its snap-throughs, which the R-MSE counts in full.";
        }
        Ok(Err(e)) => {
            s += &format!(
                "On the noise-free copies of the records its model did not simulate ({e})."
            )
        }
        Err(e) => s += &format!("The noise-free comparison could not be run: {e:#}."),
    }
    st.text(s);
}

/// A model with its test R-MSE (the noise-free comparison).
type CleanFit = std::result::Result<(f64, Model), String>;

/// Figure: the test sweep simulated by every model beside the measured response.
fn figure(
    st: &mut Study,
    test: &Record,
    ra: &SimResult,
    ours: &SimResult,
    py: &PyRow,
) -> Result<()> {
    let tt = test.t();
    let meas = test.column("x").unwrap_or_default();
    let step = (tt.len() / 3000).max(1);
    let sub = |y: &[f64]| -> Vec<(f64, f64)> {
        tt.iter()
            .zip(y)
            .step_by(step)
            .map(|(a, b)| (*a, *b))
            .collect()
    };
    let mut ch = LineChart::new(
        "Appendix B: test sweep, measured vs simulated models",
        "t (s)",
        "x (length unit c0)",
    )
    .with_series(Series::line("measured (30 dB)", sub(meas)).color(0));
    if let Ok((_, p)) = ra {
        ch = ch.with_series(Series::dashed("T-F-S model", sub(p)).color(1));
    }
    if let Ok((_, p)) = ours {
        ch = ch.with_series(Series::dashed("classical SINDy (ours)", sub(p)).color(3));
    }
    if let Ok((_, Ok((_, p)))) = py {
        ch = ch.with_series(Series::dashed("PySINDy classical", sub(p)).color(2));
    }
    st.figure(
        "figB1_test_response",
        "Appendix B: the test sweep simulated by every model beside the measured response",
        ch,
    )
}
