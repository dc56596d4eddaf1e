//! §4 experiment-like study: a synthetic truth of the form of Eq. 19 with Table 3's coefficients,
//! six training sweeps, a test sweep (Fig. 9), eight harmonic deployment tests (Fig. 10) and MED.

use anyhow::{Context, Result, anyhow};
use serde_json::{Value, json};
use tfs::basin::{BasinConfig, WellInfo, basin_sdof, compare, med_sdof};
use tfs::criteria::{IdentifySpec, identify_tfs};
use tfs::data::Record;
use tfs::dynamics::{SimulateOptions, simulate_model_on_record};
use tfs::library::{Library, Model};
use tfs::plot::{LineChart, Series};
use tfs::signal::{Excitation as _, NoiseKind, Sine, Sweep, SweepKind};

use crate::common::{
    Opts, basin_figure, coef, curve, dev, f4, model_json, model_wells, num, pct, progress,
};
use crate::report::{Study, Table};

/// Table 3: ζ, α, β, γ.
const TABLE3: [f64; 4] = [1.0, 44.46, -5.82, 0.12];
/// Time scale: the paper's physical band 2–12 Hz is mapped onto the model's time unit by 0.2.
const FREQ_SCALE: f64 = 0.2;
/// Sampling interval (s of model time).
const DT: f64 = 0.01;
/// Six training sweeps over the scaled 2–12 Hz band: (duration s, amplitude mm/s²).
const TRAIN: [(f64, f64); 6] = [
    (60.0, 20.0),
    (90.0, 30.0),
    (120.0, 40.0),
    (60.0, 50.0),
    (90.0, 60.0),
    (120.0, 80.0),
];
/// Test sweep over the scaled 4–8 Hz band: (duration, amplitude).
const TEST: (f64, f64) = (120.0, 25.0);
/// Eight harmonic deployment tests from S1: (frequency Hz in model time, amplitude mm/s²).
const DEPLOY: [(f64, f64); 8] = [
    (1.6, 150.0),
    (1.6, 60.0),
    (1.2, 120.0),
    (1.2, 40.0),
    (0.8, 70.0),
    (0.8, 25.0),
    (0.5, 60.0),
    (0.5, 20.0),
];
const DEPLOY_T: f64 = 40.0;
const LIBRARY: &str = "x^1..5, x', xb_acc";
const SEARCH: (f64, f64) = (-30.0, 80.0);

fn truth() -> Result<Model> {
    let lib = Library::parse("x, x^2, x^3, x', xb_acc", &["x"])?;
    let [z, a, b, g] = TABLE3;
    Ok(Model::from_coefficients(
        &lib,
        &[vec![-a, -b, -g, -z, -1.0]],
        "truth: Eq. 19 with Table 3",
    )?)
}

/// Simulates `model` from rest at S1 under `u`; returns (t, x).
fn simulate(model: &Model, name: &str, u: Vec<f64>) -> Result<(Vec<f64>, Vec<f64>)> {
    let n = u.len();
    let t: Vec<f64> = (0..n).map(|k| k as f64 * DT).collect();
    let rec = Record::new(
        name,
        t.clone(),
        vec![("x".into(), vec![0.0; n]), ("xb_acc".into(), u)],
    )?;
    let tr = simulate_model_on_record(model, &rec, &SimulateOptions::default())
        .with_context(|| format!("simulating {name}"))?;
    Ok((t, tr.x[0].clone()))
}

fn sweep(f0: f64, f1: f64, d: f64, a: f64) -> Result<Vec<f64>> {
    let n = (d / DT).round() as usize + 1;
    let t: Vec<f64> = (0..n).map(|k| k as f64 * DT).collect();
    Ok(Sweep::new(SweepKind::Linear, f0, f1, d, a, 0.0)?.sample(&t))
}

fn sine(f: f64, a: f64) -> Result<Vec<f64>> {
    let n = (DEPLOY_T / DT).round() as usize + 1;
    let t: Vec<f64> = (0..n).map(|k| k as f64 * DT).collect();
    Ok(Sine::new(f, a, 0.0, 0.0)?.sample(&t))
}

/// A measured record: truth response with 60 dB white noise on x and xb_acc.
fn measured(model: &Model, name: &str, u: Vec<f64>, seed: u64) -> Result<Record> {
    let (t, x) = simulate(model, name, u.clone())?;
    let nx = tfs::signal::noise::noise_for(&x, 60.0, NoiseKind::White, seed)?;
    let nu = tfs::signal::noise::noise_for(&u, 60.0, NoiseKind::White, seed + 1)?;
    let xm: Vec<f64> = x.iter().zip(&nx).map(|(a, b)| a + b).collect();
    let um: Vec<f64> = u.iter().zip(&nu).map(|(a, b)| a + b).collect();
    Ok(Record::new(
        name,
        t,
        vec![
            ("x".into(), xm),
            ("xb_acc".into(), um),
            ("x_clean".into(), x),
        ],
    )?)
}

/// Deployed: the last 10% of the run lies beyond the unstable equilibrium.
fn deployed(x: &[f64], x_u: f64) -> bool {
    let k = x.len() * 9 / 10;
    x[k..].iter().all(|&v| v > x_u)
}

/// The training sweeps (durations times `scale`, `f` Hz, noise seeds 900 + 7i) with what each
/// did (deployed past the unstable state `x_u`, largest x), and the test sweep (`g` Hz).
fn experiment_records(
    truth: &Model,
    x_u: f64,
    scale: f64,
    (f0, f1): (f64, f64),
    (g0, g1): (f64, f64),
) -> Result<(Vec<Record>, Vec<Value>, Record)> {
    let mut train = Vec::new();
    let mut train_info = Vec::new();
    for (i, &(d, a)) in TRAIN.iter().enumerate() {
        let r = measured(
            truth,
            &format!("train{}", i + 1),
            sweep(f0, f1, d * scale, a)?,
            900 + 7 * i as u64,
        )?;
        let xc = r.column("x_clean").unwrap_or_default();
        train_info.push(json!({"record": r.source(), "duration": d * scale, "amplitude": a, "deployed": deployed(xc, x_u), "x_max": xc.iter().cloned().fold(f64::NEG_INFINITY, f64::max)}));
        train.push(r);
    }
    let test = measured(truth, "test", sweep(g0, g1, TEST.0 * scale, TEST.1)?, 990)?;
    Ok((train, train_info, test))
}

/// Table 3: the identified coefficients of Eq. 19 beside the truth's (the paper's), the
/// equation, and the training sweeps' JSON (`train_info`).
fn table3(st: &mut Study, model: &Model, train_info: Vec<Value>) -> Result<()> {
    let ours = [
        -coef(model, "x", "x'"),
        -coef(model, "x", "x"),
        -coef(model, "x", "x^2"),
        -coef(model, "x", "x^3"),
    ];
    let others: Vec<String> = crate::common::terms(model, "x")
        .into_iter()
        .filter(|(n, _)| !["x'", "x", "x^2", "x^3", "xb_acc"].contains(&n.as_str()))
        .map(|(n, c)| format!("{n}: {}", f4(c)))
        .collect();
    let mut t3 = Table::new(
        "table3",
        "Table 3: coefficients of Eq. 19 (the paper's are the truth here)",
        &["source", "ζ", "α", "β", "γ", "other terms", "xb_acc coef"],
    );
    t3.row(vec![
        "paper = truth".into(),
        f4(TABLE3[0]),
        f4(TABLE3[1]),
        f4(TABLE3[2]),
        f4(TABLE3[3]),
        "none".into(),
        "-1".into(),
    ]);
    t3.row(vec![
        "ours (T-F-S, 60 dB)".into(),
        f4(ours[0]),
        f4(ours[1]),
        f4(ours[2]),
        f4(ours[3]),
        if others.is_empty() {
            "none".into()
        } else {
            others.join("; ")
        },
        f4(coef(model, "x", "xb_acc")),
    ]);
    st.table(t3)?;
    st.text(format!(
        "Equation identified: `{}`",
        model.equation_string()
    ));
    st.set("table3", json!({"paper": TABLE3, "ours": ours.iter().map(|v| num(*v)).collect::<Vec<_>>(), "other_terms": others, "equation": model.equation_string(), "model": model_json(model)}));
    st.set("training", json!(train_info));
    Ok(())
}

/// Fig. 9: the identified model's response to the test sweep (`g` Hz) against the measured one:
/// amplitude spectra and their resonance peaks, the sweep's first seconds, the resonance check.
fn frequency_response(
    st: &mut Study,
    model: &Model,
    test: &Record,
    (g0, g1): (f64, f64),
) -> Result<()> {
    let (_, xm) = simulate(
        model,
        "test-model",
        test.column("xb_acc").unwrap_or_default().to_vec(),
    )?;
    let (fr, a_meas) = tfs::signal::amplitude_spectrum(test.column("x").unwrap_or_default(), DT)?;
    let (_, a_mod) = tfs::signal::amplitude_spectrum(&xm, DT)?;
    let peak = |a: &[f64]| -> f64 {
        fr.iter()
            .zip(a)
            .filter(|(f, _)| **f >= 0.5 * g0 && **f <= 1.5 * g1)
            .max_by(|x, y| x.1.total_cmp(y.1))
            .map_or(f64::NAN, |p| *p.0)
    };
    let (fm, fmod) = (peak(&a_meas), peak(&a_mod));
    let res_err = (fmod - fm).abs() / fm;
    let r_mse =
        tfs::dynamics::rmse_ratio(test.column("x").unwrap_or_default(), &xm).unwrap_or(f64::NAN);
    let band = |a: &[f64]| -> Vec<(f64, f64)> {
        fr.iter()
            .zip(a)
            // no DC bin: its near-zero amplitude would stretch the log axis by decades
            .filter(|(f, _)| **f > 0.0 && **f <= 4.0)
            .map(|(f, v)| (*f, *v))
            .collect()
    };
    let ch = LineChart::new(
        "Fig. 9c: frequency response on the test sweep, measured vs model",
        "f (Hz, model time)",
        "amplitude spectrum of x (mm, log)",
    )
    .log_y(true)
    .with_series(Series::line("measured (truth + 60 dB noise)", band(&a_meas)).color(0))
    .with_series(Series::dashed("identified model", band(&a_mod)).color(1))
    .with_vline(
        fm,
        format!("resonance: measured {fm:.3} Hz, model {fmod:.3} Hz"),
    );
    st.figure("fig9c_frequency_response", "Fig. 9c: amplitude spectra of the measured and model responses to the test sweep (the peak is the resonance; the second-harmonic content shows above the band)", ch)?;
    // 120 s of a sine drawn whole is a solid block: the figure shows the waveform over its first
    // seconds and says in the title how the sweep goes on (a linear sweep at constant amplitude).
    let tt = test.t();
    let xb = test.column("xb_acc").unwrap_or_default();
    let t_end = tt.last().copied().unwrap_or(0.0);
    let shown = 12.0_f64.min(t_end);
    let ch = LineChart::new(
        format!(
            "Fig. 9a: test sweep, first {shown:.0} s of {t_end:.0} s (linear {g0:.2} → {g1:.2} Hz, constant amplitude)"
        ),
        "t (s, model time)",
        "base acceleration xb_acc (mm/s²)",
    )
    .with_series(
        Series::line(
            "xb_acc (measured)",
            tt.iter()
                .zip(xb)
                .take_while(|(t, _)| **t <= shown)
                .map(|(a, b)| (*a, *b))
                .collect(),
        )
        .color(0),
    );
    st.figure(
        "fig9a_test_excitation",
        "Fig. 9a: the test sweep's first seconds (the whole record at this scale would be a solid block)",
        ch,
    )?;
    st.compare(
        "Fig. 9 resonance frequency",
        &format!("{} Hz (measured)", f4(fm)),
        &format!("{} Hz ({})", f4(fmod), dev(fmod, fm)),
        "≈ 5% error",
        Some(res_err <= 0.05),
        "within 5% of the measured resonance",
    );
    st.set("fig9", json!({"resonance_measured_hz": num(fm), "resonance_model_hz": num(fmod), "resonance_error": num(res_err), "test_r_mse": num(r_mse)}));
    Ok(())
}

/// Fig. 10: the eight harmonic deployment tests from S1 (`s_t`, the truth's stable states;
/// `u_t`, its unstable ones), the truth's outcome against the model's, a figure each. Returns
/// the model's wells.
fn deployment_tests(
    st: &mut Study,
    truth: &Model,
    model: &Model,
    s_t: &[f64],
    u_t: &[f64],
) -> Result<WellInfo> {
    let mwells = model_wells(model, "x", SEARCH)?;
    let xu_m = mwells
        .unstable()
        .iter()
        .cloned()
        .find(|u| *u > s_t[0])
        .unwrap_or(f64::INFINITY);
    let mut t10 = Table::new(
        "deployment",
        "Fig. 10: harmonic deployment tests from S1 (deployed = the last 10% of the run beyond the unstable equilibrium)",
        &[
            "test",
            "frequency (Hz)",
            "amplitude (mm/s²)",
            "truth deployed",
            "model deployed",
            "correct",
            "truth max |v| (mm/s)",
            "truth max x (mm)",
        ],
    );
    let mut correct = 0;
    let mut tests = Vec::new();
    for (i, &(f, a)) in DEPLOY.iter().enumerate() {
        let u = sine(f, a)?;
        let (t, xt) = simulate(truth, &format!("deploy{}", i + 1), u.clone())?;
        let (_, xmod) = simulate(model, &format!("deploy{}-model", i + 1), u)?;
        let (dt_, dm) = (deployed(&xt, u_t[0]), deployed(&xmod, xu_m));
        correct += usize::from(dt_ == dm);
        let vmax = xt
            .windows(2)
            .map(|w| ((w[1] - w[0]) / DT).abs())
            .fold(0.0, f64::max);
        let xmax = xt.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
        let yn = |b: bool| if b { "yes" } else { "no" }.to_string();
        t10.row(vec![
            format!("{}", i + 1),
            f4(f),
            f4(a),
            yn(dt_),
            yn(dm),
            yn(dt_ == dm),
            f4(vmax),
            f4(xmax),
        ]);
        tests.push(json!({"freq": f, "amplitude": a, "truth_deployed": dt_, "model_deployed": dm, "correct": dt_ == dm}));
        let step = (t.len() / 2000).max(1);
        let s = |y: &[f64]| -> Vec<(f64, f64)> {
            t.iter()
                .zip(y)
                .step_by(step)
                .map(|(a, b)| (*a, *b))
                .collect()
        };
        let ch = LineChart::new(
            format!(
                "Fig. 10, test {}: {f} Hz, {a} mm/s² — truth {}, model {}",
                i + 1,
                if dt_ { "deploys" } else { "stays" },
                if dm { "deploys" } else { "stays" }
            ),
            "t (s, model time)",
            "x (mm)",
        )
        .with_series(Series::line("truth (simulated)", s(&xt)).color(0))
        .with_series(Series::dashed("identified model (predicted)", s(&xmod)).color(1))
        .with_series(
            Series::dashed(
                format!("unstable equilibrium {:.2} mm", u_t[0]),
                vec![(0.0, u_t[0]), (DEPLOY_T, u_t[0])],
            )
            .color(3),
        );
        st.figure(
            &format!("fig10_test{}", i + 1),
            &format!(
                "Fig. 10, test {}: harmonic base excitation {f} Hz, {a} mm/s² from S1",
                i + 1
            ),
            ch,
        )?;
    }
    st.table(t10)?;
    st.compare(
        "Fig. 10 deployment tests predicted",
        "the truth's outcome of each test",
        &format!("{correct}/8"),
        "8/8",
        Some(correct == 8),
        "all eight as the truth does",
    );
    st.set("deployment", json!({"tests": tests, "correct": correct}));
    Ok(mwells)
}

/// The minimum-energy deployment S1 → S2 of the truth and of the model (wells `twells`,
/// `mwells`) against each one's quasi-static barrier, with both basin maps.
fn med_section(
    st: &mut Study,
    o: &Opts,
    truth: &Model,
    twells: &WellInfo,
    model: &Model,
    mwells: &WellInfo,
) -> Result<()> {
    let n = o.pick(31, 121);
    let mut cfg = BasinConfig::new(n, n, (-10.0, 50.0), (-150.0, 150.0));
    cfg.t_max = 60.0;
    let tsys = truth.compile()?;
    let msys = model.compile()?;
    let tmap = basin_sdof(&tsys, twells, &cfg, None).context("truth basin")?;
    let tmed = med_sdof(&tsys, twells, &tmap, &cfg, 0, 1).context("truth MED")?;
    let mres = (|| -> Result<_> {
        let map = basin_sdof(&msys, mwells, &cfg, None)?;
        let cmp = compare(&map, &tmap)?;
        let med = med_sdof(&msys, mwells, &map, &cfg, 0, 1)?;
        Ok((map, cmp, med))
    })();
    let mut tm = Table::new(
        "med_experiment",
        "MED S1 → S2: dynamic (BOA boundary) vs quasi-static barrier",
        &[
            "system",
            "E_MED (dynamic)",
            "x0",
            "v0",
            "quasi-static barrier",
            "E_MED / barrier",
            "BOA error vs truth",
        ],
    );
    tm.row(vec![
        "truth".into(),
        f4(tmed.energy),
        f4(tmed.x0),
        f4(tmed.v0),
        f4(tmed.quasi_static_barrier),
        f4(tmed.energy / tmed.quasi_static_barrier),
        "—".into(),
    ]);
    let names = |w: &WellInfo| -> Vec<String> {
        w.stable()
            .iter()
            .enumerate()
            .map(|(k, s)| format!("S{} (x = {:.2} mm)", k + 1, s))
            .collect()
    };
    let axes = ("initial displacement x0 (mm)", "initial velocity v0 (mm/s)");
    st.figure(
        "fig_med_boa_truth",
        "§4: basins of the truth with the MED point",
        basin_figure(
            &tmap,
            "§4: BOA of the Table 3 truth",
            axes,
            &names(twells),
            None,
            vec![(tmed.x0, tmed.v0, format!("MED {:.0}", tmed.energy))],
        ),
    )?;
    match &mres {
        Ok((map, cmp, med)) => {
            tm.row(vec![
                "model".into(),
                f4(med.energy),
                f4(med.x0),
                f4(med.v0),
                f4(med.quasi_static_barrier),
                f4(med.energy / med.quasi_static_barrier),
                pct(cmp.error),
            ]);
            st.figure(
                "fig_med_boa_model",
                "§4: basins of the identified model; dark cells disagree with the truth",
                basin_figure(
                    map,
                    &format!(
                        "§4: BOA of the identified model — BOA error {}",
                        pct(cmp.error)
                    ),
                    axes,
                    &names(mwells),
                    Some(&cmp.disagree),
                    vec![(med.x0, med.v0, format!("MED {:.0}", med.energy))],
                ),
            )?;
        }
        Err(e) => tm.row(vec![
            "model".into(),
            format!("failed: {e:#}"),
            String::new(),
            String::new(),
            String::new(),
            String::new(),
            String::new(),
        ]),
    }
    st.table(tm)?;
    let ratio = mres
        .as_ref()
        .map(|r| r.2.energy / r.2.quasi_static_barrier)
        .unwrap_or(f64::NAN);
    st.compare(
        "§4 MED dynamic vs quasi-static",
        "—",
        &format!("E_MED/barrier = {}", f4(ratio)),
        "80.39% reduction",
        None,
        "not comparable (see report)",
    );
    st.text("The paper's 80.39% compares the MED of the *dynamic* model with the deployment energy of the separately measured *quasi-static* force curve (Fig. 8c, stiffer because of PET viscoelasticity). That curve is not tabulated, and in a single model the MED can never be below its own quasi-static barrier (energy only decreases along unforced damped motion), so we report E_MED/barrier for the truth and the model instead; values close to 1 mean deployment by an initial displacement, as the paper observes.");
    let med_j = |m: &tfs::basin::Med| json!({"energy": num(m.energy), "x0": num(m.x0), "v0": num(m.v0), "quasi_static_barrier": num(m.quasi_static_barrier)});
    st.set("med", json!({"truth": med_j(&tmed), "model": mres.as_ref().ok().map(|r| med_j(&r.2)), "model_boa_error": mres.as_ref().ok().map(|r| num(r.1.error)), "model_error": mres.as_ref().err().map(|e| format!("{e:#}")), "ratio_model": num(ratio)}));
    Ok(())
}

/// The restoring force of the truth and of the identified model (cf. Fig. 8e).
fn force_figure(st: &mut Study, truth: &Model, model: &Model) -> Result<()> {
    let r = model.restoring("x")?;
    let rt = truth.restoring("x")?;
    let ch = LineChart::new(
        "§4 (cf. Fig. 8e): restoring force, truth vs identified model",
        "x (mm)",
        "restoring force per unit mass (mm/s²)",
    )
    .with_series(
        Series::line(
            "truth (Eq. 19, Table 3)",
            curve(-5.0, 45.0, 201, |x| rt.force(x)),
        )
        .color(0),
    )
    .with_series(
        Series::dashed("identified model", curve(-5.0, 45.0, 201, |x| r.force(x))).color(1),
    );
    st.figure(
        "fig8e_force",
        "§4: restoring force of the Table 3 truth and of the identified model",
        ch,
    )?;
    Ok(())
}

/// Study 5.
pub fn study_experiment(st: &mut Study, o: &Opts) -> Result<()> {
    let pb = progress(6, "§4 exp.");
    let truth = truth()?;
    let twells = model_wells(&truth, "x", SEARCH)?;
    let (s_t, u_t) = (twells.stable().to_vec(), twells.unstable().to_vec());
    if s_t.len() != 2 || u_t.is_empty() {
        return Err(anyhow!(
            "the Table 3 truth should be bistable; stable {s_t:?}, unstable {u_t:?}"
        ));
    }
    let scale = o.pick(0.5, 1.0);
    let (f0, f1) = (2.0 * FREQ_SCALE, 12.0 * FREQ_SCALE);
    let (g0, g1) = (4.0 * FREQ_SCALE, 8.0 * FREQ_SCALE);
    st.text(format!(
        "Synthetic truth of the form of Eq. 19: x'' + {}x' + {}x {:+}x^2 {:+}x^3 = −xb_acc (Table 3). Units: x in mm, t in s of *model time*. Its equilibria: stable S1 = {:.3} mm and S2 = {:.3} mm, unstable {:.3} mm (x(α + βx + γx²) = 0, roots (5.82 ± 3.54)/0.24); linear natural frequencies √α/2π = {:.3} Hz at S1 and {:.3} Hz at S2. Time scale: the paper's excitation band (2–12 Hz training, 4–8 Hz test) is multiplied by {FREQ_SCALE} so that it brackets these resonances the way the real sweeps bracket the rig's: training sweeps {f0:.1}–{f1:.1} Hz, test sweep {g0:.1}–{g1:.1} Hz. Six training sweeps (duration s, amplitude mm/s²) {:?}, test {:?}, harmonic deployment tests (Hz, mm/s²) {:?} of {DEPLOY_T} s from rest at S1; 60 dB white noise on x and xb_acc; 100 Hz sampling; library `{LIBRARY}`.{}",
        TABLE3[0], TABLE3[1], TABLE3[2], TABLE3[3], s_t[0], s_t[1], u_t[0],
        TABLE3[1].sqrt() / (2.0 * std::f64::consts::PI),
        (TABLE3[1] + 2.0 * TABLE3[2] * s_t[1] + 3.0 * TABLE3[3] * s_t[1] * s_t[1]).sqrt() / (2.0 * std::f64::consts::PI),
        TRAIN, TEST, DEPLOY,
        if o.quick { " Quick mode: sweeps at half length, 31×31 basin grid." } else { "" }
    ));
    pb.set_message("data");
    let (train, train_info, test) = experiment_records(&truth, u_t[0], scale, (f0, f1), (g0, g1))?;
    pb.inc(1);
    pb.set_message("identify");
    let id = identify_tfs(&train, &IdentifySpec::new(&["x"], LIBRARY))
        .context("T-F-S identification")?;
    let model = id.model;
    pb.inc(1);
    table3(st, &model, train_info)?;
    pb.set_message("test sweep");
    frequency_response(st, &model, &test, (g0, g1))?;
    pb.inc(1);
    pb.set_message("deployment tests");
    let mwells = deployment_tests(st, &truth, &model, &s_t, &u_t)?;
    pb.inc(1);
    pb.set_message("MED");
    med_section(st, o, &truth, &twells, &model, &mwells)?;
    force_figure(st, &truth, &model)?;
    pb.inc(1);
    pb.finish_and_clear();
    Ok(())
}
