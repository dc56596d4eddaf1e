//! Times `identify_tfs` on the records written by `cargo xtask peers` (profiling aid), or scores
//! it on every peers case.
//!
//! `cargo run --release -p tfs-criteria --example profile_peers -- target/peers/data/white30 [reps] [classical]`
//!
//! `cargo run --release -p tfs-criteria --example profile_peers -- score [target/peers/data]`
//! prints, per noise case and library, the x^5..7 coefficients and the restoring-force relative
//! RMS error over 0 ≤ h ≤ 1.8 against the surrogate truth 12.145h⁵ − 18.0618h⁶ + 6.5625h⁷.

use std::time::Instant;

#[path = "../tests/common/synthetic.rs"]
mod synthetic;

use tfs_criteria::{IdentifySpec, identify_sindy, identify_tfs};
use tfs_data::Record;
use tfs_library::{Model, Term};

/// The surrogate restoring force (per unit mass) of the peers records.
fn truth(h: f64) -> f64 {
    12.145 * h.powi(5) - 18.0618 * h.powi(6) + 6.5625 * h.powi(7)
}

/// The peers system (m = 1, c = 2, the surrogate force of [`truth`]).
fn peers_truth() -> synthetic::Surrogate {
    synthetic::Surrogate {
        c: 2.0,
        a: [12.145, -18.0618, 6.5625],
    }
}

/// A 200 Hz sweep record `(f0, f1, duration, amplitude)` of `sys`, with noise `(SNR dB, kind,
/// seed)` or clean.
fn sweep(
    sys: &synthetic::Surrogate,
    name: &str,
    (f0, f1, duration, amplitude): (f64, f64, f64, f64),
    noise: Option<(f64, tfs_signal::NoiseKind, u64)>,
) -> Result<Record, Box<dyn std::error::Error>> {
    use synthetic::{NoiseSpec, SweepSpec, surrogate_record};
    let sw = SweepSpec {
        f0,
        f1,
        duration,
        amplitude,
    };
    let ns = noise.map(|(snr_db, kind, seed)| NoiseSpec { snr_db, kind, seed });
    surrogate_record(name, sys, sw, 200.0, ns)
}

/// Relative RMS error of the model's restoring force over 0 ≤ h ≤ 1.8.
fn force_error(m: &Model) -> f64 {
    let Ok(r) = m.restoring("x") else {
        return f64::NAN;
    };
    let (mut num, mut den) = (0.0, 0.0);
    for i in 0..361 {
        let h = 1.8 * i as f64 / 360.0;
        num += (r.force(h) - truth(h)).powi(2);
        den += truth(h).powi(2);
    }
    (num / den).sqrt()
}

/// Option overrides from the environment (`TFS_REWEIGHT=passes`, `TFS_PRUNE=rounds`,
/// `TFS_EIV=draws` of the errors-in-variables correction, `TFS_GUARD=octaves` above the
/// cut-off, `TFS_RESELECT=0` for one choice of settings, `TFS_KAPPA0=k` for a fixed κ0 (no calibration), …); `TFS_TIMING` prints stage times;
/// `TFS_SAVE=dir` (Monte-Carlo mode) writes each seed's model there, and `TFS_SEED0=n` starts
/// its seeds at `n` (to look at one draw again).
fn tweak(spec: &mut IdentifySpec) {
    if let Some(v) = std::env::var("TFS_REWEIGHT")
        .ok()
        .and_then(|s| s.parse().ok())
    {
        spec.tfs.criterion3.reweight = v;
    }
    let list = |k: &str| -> Option<Vec<f64>> {
        std::env::var(k)
            .ok()
            .map(|s| s.split(',').filter_map(|v| v.parse().ok()).collect())
    };
    if let Some(d) = list("TFS_DELTAS") {
        spec.tfs.criterion3.deltas = d;
    }
    if let Some(w) = list("TFS_WINDOWS") {
        spec.tfs.criterion3.window_counts = w.into_iter().map(|v| v as usize).collect();
    }
    if let Ok(v) = std::env::var("TFS_RESELECT") {
        spec.tfs.fit.reselect_for_support = v != "0";
    }
    if std::env::var("TFS_NODEBIAS").is_ok() {
        spec.tfs.criterion3.debias = false;
    }
    if let Some(g) = list("TFS_GUARD") {
        spec.tfs.criterion3.guard_octaves = g.first().copied().unwrap_or(0.0);
    }
    if let Some(c) = list("TFS_CUTOFF") {
        spec.tfs.criterion3.cutoff_hz = c.first().copied();
    }
    if let Some(g) = list("TFS_GATE") {
        spec.tfs.criterion3.min_bin_snr = g.first().copied().filter(|v| *v > 0.0);
    }
    if let Some(e) = list("TFS_EIV") {
        spec.tfs.fit.noise_correction_draws = e.first().map_or(0, |v| *v as usize);
    }
    if let Some(k) = list("TFS_KAPPA0") {
        if let Some(&k) = k.first() {
            spec.tfs.criterion1.kappa0 = tfs_criteria::Kappa0Choice::Fixed(k);
        }
    }
    if let Some(p) = list("TFS_PRUNE") {
        spec.tfs.uncertainty.elimination_rounds = p.first().map_or(0, |v| *v as usize);
    }
}

fn read(dir: &str) -> Result<Vec<Record>, Box<dyn std::error::Error>> {
    Ok((1..=4)
        .map(|i| tfs_data::read_csv(format!("{dir}/train{i}.csv")))
        .collect::<Result<Vec<_>, _>>()?)
}

fn score(root: &str) -> Result<(), Box<dyn std::error::Error>> {
    let dofs = ["x".to_string()];
    let coef = |m: &Model, t: &str| {
        Term::parse(t, &dofs)
            .ok()
            .and_then(|t| m.coef("x", &t).ok())
            .unwrap_or(0.0)
    };
    println!("| case | library | x^5 | x^6 | x^7 | x' | xb_acc | force err | ms |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for case in ["white60", "white30", "white20", "pink30", "white10"] {
        let recs = read(&format!("{root}/{case}"))?;
        for (lname, lib) in [
            ("5..7", "x^5..7, x', xb_acc"),
            ("1..7", "x^1..7, x', xb_acc"),
        ] {
            let mut spec = IdentifySpec::new(&["x"], lib);
            tweak(&mut spec);
            let t = Instant::now();
            let id = identify_tfs(&recs, &spec)?;
            let el = t.elapsed().as_secs_f64() * 1e3;
            let m = &id.model;
            println!(
                "| {case} | {lname} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.2}% | {el:.0} |",
                coef(m, "x^5"),
                coef(m, "x^6"),
                coef(m, "x^7"),
                coef(m, "x'"),
                coef(m, "xb_acc"),
                100.0 * force_error(m)
            );
            if std::env::var("TFS_VERBOSE").is_ok() {
                println!("    {}", m.equation_string());
                for d in &id.trace.dofs {
                    if let Some(c1) = &d.criterion1 {
                        println!("    est SNR {:?}", c1.estimated_snr_db);
                    }
                    println!("    δ {} w {}", d.settings.delta, d.settings.windows);
                    for b in &d.bins {
                        println!(
                            "    bins {} cutoff {:.2} band {:?} noise share {:.3}",
                            b.kept_bins, b.cutoff_hz, b.band_hz, b.in_band_noise_share
                        );
                    }
                }
            }
        }
    }
    Ok(())
}

/// Monte Carlo over noise seeds on the four peers sweeps simulated afresh: mean and spread of
/// the coefficients (bias against variance). `which` = "both", "x" or "acc" (where noise goes).
fn monte_carlo(
    kind: &str,
    snr: f64,
    seeds: u64,
    which: &str,
) -> Result<(), Box<dyn std::error::Error>> {
    let sys = peers_truth();
    let sweeps = [
        (0.05, 1.5, 100.0, 3.0),
        (0.05, 1.5, 60.0, 4.0),
        (0.1, 1.2, 80.0, 5.0),
        (0.05, 2.0, 120.0, 6.0),
    ];
    let nk = if kind == "pink" {
        tfs_signal::NoiseKind::Pink
    } else {
        tfs_signal::NoiseKind::White
    };
    let dofs = ["x".to_string()];
    let lib = std::env::var("TFS_LIB").unwrap_or_else(|_| "x^5..7, x', xb_acc".into());
    let mut spec = IdentifySpec::new(&["x"], &lib);
    tweak(&mut spec);
    let names = ["x^5", "x^6", "x^7", "x'", "xb_acc"];
    let mut all = Vec::new();
    let first: u64 = std::env::var("TFS_SEED0")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(0);
    for seed in first..first + seeds {
        let mut recs = Vec::new();
        for (i, &(f0, f1, duration, amplitude)) in sweeps.iter().enumerate() {
            let sw = (f0, f1, duration, amplitude);
            let noisy = sweep(
                &sys,
                &format!("r{i}"),
                sw,
                Some((snr, nk, 1000 * seed + 17 * i as u64)),
            )?;
            let r = if which == "both" {
                noisy
            } else if let Some(spec) = which.strip_prefix("band") {
                // "band<lo>-<hi>": only the x noise between lo and hi Hz (acc noise kept).
                let (lo, hi) = spec.split_once('-').unwrap();
                let (lo, hi): (f64, f64) = (lo.parse()?, hi.parse()?);
                let clean = sweep(&sys, &format!("r{i}"), sw, None)?;
                let cx = clean.column("x").unwrap();
                let n: Vec<f64> = noisy
                    .column("x")
                    .unwrap()
                    .iter()
                    .zip(cx)
                    .map(|(a, b)| a - b)
                    .collect();
                let lp = |f: f64| tfs_signal::band::low_pass(&n, 0.005, f);
                let (nh, nl) = (lp(hi), lp(lo));
                let x: Vec<f64> = (0..n.len()).map(|k| cx[k] + nh[k] - nl[k]).collect();
                Record::new(
                    format!("r{i}"),
                    clean.t().to_vec(),
                    vec![
                        ("x".into(), x),
                        ("xb_acc".into(), noisy.column("xb_acc").unwrap().to_vec()),
                    ],
                )?
            } else {
                let clean = sweep(&sys, &format!("r{i}"), sw, None)?;
                let (xs, acs) = if which == "x" {
                    (&noisy, &clean)
                } else {
                    (&clean, &noisy)
                };
                Record::new(
                    format!("r{i}"),
                    clean.t().to_vec(),
                    vec![
                        ("x".into(), xs.column("x").unwrap().to_vec()),
                        ("xb_acc".into(), acs.column("xb_acc").unwrap().to_vec()),
                    ],
                )?
            };
            recs.push(r);
        }
        let t0 = Instant::now();
        let id = identify_tfs(&recs, &spec)?;
        if std::env::var("TFS_TIMING").is_ok() {
            // A second, warm call: the first also pays for FFT planning and the thread pool.
            let t1 = Instant::now();
            let warm = identify_tfs(&recs, &spec)?;
            println!(
                "  time: cold {:.1} ms, warm {:.1} ms; warm stages {:?}",
                1e3 * (t1 - t0).as_secs_f64(),
                1e3 * t1.elapsed().as_secs_f64(),
                warm.trace.timing_ms
            );
        }
        if std::env::var("TFS_VERBOSE").is_ok() {
            println!("  {}", id.model.equation_string());
            for w in &id.trace.dofs[0].settings.why {
                println!("  - {w}");
            }
            println!("  verdict: {}", id.trace.dofs[0].assembly_verdict);
        }
        let c: Vec<f64> = names
            .iter()
            .map(|t| {
                Term::parse(t, &dofs)
                    .ok()
                    .and_then(|t| id.model.coef("x", &t).ok())
                    .unwrap_or(0.0)
            })
            .collect();
        if let Ok(dir) = std::env::var("TFS_SAVE") {
            // Each seed's model, for scoring outside (e.g. `tfs basin --truth kresling:surrogate`).
            std::fs::create_dir_all(&dir)?;
            id.model.write_path(format!("{dir}/seed{seed}.json"))?;
        }
        let fe = force_error(&id.model);
        let st = &id.trace.dofs[0].settings;
        let cuts: Vec<String> = id.trace.dofs[0]
            .bins
            .iter()
            .map(|b| format!("{:.1}", b.cutoff_hz))
            .collect();
        println!(
            "seed {seed}: {c:.3?} force err {:.2}% (δ {} w {}; cut-offs {})",
            100.0 * fe,
            st.delta,
            st.windows,
            cuts.join(" ")
        );
        all.push((c, fe));
    }
    let n = all.len() as f64;
    for (j, nm) in names.iter().enumerate() {
        let m = all.iter().map(|a| a.0[j]).sum::<f64>() / n;
        let sd = (all.iter().map(|a| (a.0[j] - m).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        println!("{nm}: mean {m:.4} sd {sd:.4}");
    }
    let fe: Vec<f64> = all.iter().map(|a| a.1).collect();
    let rms = (fe.iter().map(|v| v * v).sum::<f64>() / n).sqrt();
    println!(
        "force err rms {:.2}%  mean {:.2}%",
        100.0 * rms,
        100.0 * fe.iter().sum::<f64>() / n
    );
    Ok(())
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    match args.get(1).map(String::as_str) {
        Some("spec") => spec_mode(&args),
        Some("bands") => bands_mode(&args),
        Some("noisecheck") => noisecheck_mode(&args),
        Some("mc") => mc_mode(&args),
        Some("dump") => dump_mode(&args),
        Some("score") => score_mode(&args),
        _ => timing_mode(&args),
    }
}

/// `spec <dir>`: each record's noise floor slope, cut-off bin and spectrum over the floor.
fn spec_mode(args: &[String]) -> Result<(), Box<dyn std::error::Error>> {
    let dir = args.get(2).cloned().unwrap_or_default();
    for r in read(&dir)? {
        let x = r.column("x").unwrap();
        let n = x.len();
        let f = tfs_signal::fft::plan_forward(2 * n);
        let mut buf = f.make_input_vec();
        buf[..n].copy_from_slice(x);
        for i in 0..n {
            buf[2 * n - 1 - i] = x[i];
        }
        let mut sp = f.make_output_vec();
        f.process(&mut buf, &mut sp).unwrap();
        let p: Vec<f64> = sp.iter().map(|c| c.norm_sqr()).collect();
        let fl = tfs_signal::NoiseFloor::fit(&p);
        let (a, b) = (fl.log_a, fl.beta);
        let (kc, _, _) = tfs_signal::choose_cutoff(&p, 1);
        let df = 1.0 / (2.0 * n as f64 * r.dt());
        println!(
            "{}: beta {b:.3} kc {kc} ({:.2} Hz)",
            r.source(),
            kc as f64 * df
        );
        let m = 128;
        let mut line = String::new();
        let mut k0 = (0.5 / df) as usize;
        while (k0 as f64) * df < 20.0 {
            let mean = p[k0..k0 + m].iter().sum::<f64>() / m as f64;
            let fl = (k0..k0 + m)
                .map(|i| (a + b * (i as f64).ln()).exp())
                .sum::<f64>()
                / m as f64;
            line += &format!(" {:.1}:{:.2}", k0 as f64 * df, mean / fl);
            k0 += m;
        }
        println!("  {line}");
    }
    Ok(())
}

/// `bands <dir>`: each record's reconstruction band as the pipeline sees it.
fn bands_mode(args: &[String]) -> Result<(), Box<dyn std::error::Error>> {
    let dir = args.get(2).cloned().unwrap_or_default();
    for r in read(&dir)? {
        let x = r.column("x").unwrap();
        // As the pipeline sees it: cut to a fast FFT length first.
        let x = &x[..tfs_signal::smooth_len(x.len())];
        let b = tfs_signal::band::reconstruct(x, r.dt(), None).band;
        println!(
            "{}: cutoff {:.2} beta {:.3} noise_var {:.3e} total {:.3e} share {:.4}",
            r.source(),
            b.cutoff_hz,
            b.floor_beta,
            b.noise_var,
            b.total_noise_var(),
            b.in_band_noise_share
        );
    }
    Ok(())
}

/// `noisecheck [white|pink] [snr]`: the reconstruction's estimated in-band noise against the
/// actual one, on fresh sweeps.
fn noisecheck_mode(args: &[String]) -> Result<(), Box<dyn std::error::Error>> {
    // In-band noise of the reconstruction: estimated (band.noise_var) vs actual.
    let kind = if args.get(2).is_some_and(|s| s == "pink") {
        tfs_signal::NoiseKind::Pink
    } else {
        tfs_signal::NoiseKind::White
    };
    let snr: f64 = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(10.0);
    let sys = peers_truth();
    for (i, &(f0, f1, duration, amplitude)) in [(0.05, 1.5, 100.0, 3.0), (0.1, 1.2, 80.0, 5.0)]
        .iter()
        .enumerate()
    {
        let sw = (f0, f1, duration, amplitude);
        let noisy = sweep(&sys, "n", sw, Some((snr, kind, 17 * i as u64)))?;
        let clean = sweep(&sys, "c", sw, None)?;
        let sn = tfs_signal::band::reconstruct(noisy.column("x").unwrap(), noisy.dt(), None);
        let sc = tfs_signal::band::reconstruct(
            clean.column("x").unwrap(),
            clean.dt(),
            Some(sn.band.cutoff_hz),
        );
        let n = sn.x.len();
        let (a, b) = (n / 10, n - n / 10);
        let var = |u: &[f64], v: &[f64]| {
            (a..b).map(|k| (u[k] - v[k]).powi(2)).sum::<f64>() / (b - a) as f64
        };
        let dr = tfs_signal::band::noise_draw(&sn.band, n, 1).unwrap();
        let z = vec![0.0; n];
        println!(
            "rec {i}: cutoff {:.2} Hz; x: est {:.3e} actual {:.3e} draw {:.3e}; v: actual {:.3e} draw {:.3e}",
            sn.band.cutoff_hz,
            sn.band.noise_var,
            var(&sn.x, &sc.x),
            var(&dr.x, &z),
            var(&sn.v, &sc.v),
            var(&dr.v, &z)
        );
    }
    Ok(())
}

/// `mc [kind] [snr] [seeds] [which]`: Monte Carlo over noise seeds (see [`monte_carlo`]).
fn mc_mode(args: &[String]) -> Result<(), Box<dyn std::error::Error>> {
    let kind = args.get(2).cloned().unwrap_or_else(|| "pink".into());
    let snr: f64 = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(30.0);
    let seeds: u64 = args.get(4).and_then(|s| s.parse().ok()).unwrap_or(8);
    let which = args.get(5).cloned().unwrap_or_else(|| "both".into());
    monte_carlo(&kind, snr, seeds, &which)
}

/// `dump [root]`: every coefficient, interval and inclusion of every peers case and both
/// libraries to full precision, to diff two builds.
fn dump_mode(args: &[String]) -> Result<(), Box<dyn std::error::Error>> {
    // Every coefficient, interval and inclusion of every case and both peers libraries to
    // full precision: diff two dumps to see whether a change moved any fit.
    let root = args
        .get(2)
        .cloned()
        .unwrap_or_else(|| "target/peers/data".into());
    for case in ["white60", "white30", "white20", "pink30", "white10"] {
        let recs = read(&format!("{root}/{case}"))?;
        for lib in ["x^1..7, x', xb_acc", "poly(x, x'; 1..7), xb_acc"] {
            let mut spec = IdentifySpec::new(&["x"], lib);
            tweak(&mut spec);
            let id = identify_tfs(&recs, &spec)?;
            println!("{case} [{lib}]");
            for t in &id.model.equation("x")?.terms {
                println!(
                    "  {} {:e} {:?} {:?}",
                    t.term, t.coef, t.interval, t.inclusion
                );
            }
            let d = &id.trace.dofs[0];
            let qs: Vec<usize> = d.bins.iter().map(|b| b.decimation).collect();
            if let Some(c1) = &d.criterion1 {
                println!(
                    "  κ {:.6} raw {:.6} κ0 {:.6} high {}",
                    c1.kappa.standardised, c1.kappa.raw, c1.kappa0, c1.high_snr
                );
            }
            println!(
                "  δ {} w {} q {qs:?} thr {:e} verdict {}",
                d.settings.delta, d.settings.windows, d.settings.threshold, d.assembly_verdict
            );
        }
    }
    Ok(())
}

/// `score [root]`: the coefficients and force error per case and library (see [`score`]).
fn score_mode(args: &[String]) -> Result<(), Box<dyn std::error::Error>> {
    let root = args
        .get(2)
        .cloned()
        .unwrap_or_else(|| "target/peers/data".into());
    score(&root)
}

/// The default mode: times `identify_tfs` on one case `reps` times.
fn timing_mode(args: &[String]) -> Result<(), Box<dyn std::error::Error>> {
    let dir = args
        .get(1)
        .cloned()
        .unwrap_or_else(|| "target/peers/data/white30".into());
    let reps: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(3);
    let classical = args.get(3).is_some_and(|s| s == "classical");
    let recs = read(&dir)?;
    let lib = if classical {
        "poly(x, x'; 1..7), xb_acc"
    } else {
        "x^1..7, x', xb_acc"
    };
    let mut spec = IdentifySpec::new(&["x"], lib);
    tweak(&mut spec);
    for _ in 0..reps {
        let t = Instant::now();
        let id = identify_tfs(&recs, &spec)?;
        let el = t.elapsed().as_secs_f64() * 1e3;
        println!("tfs {el:.1} ms: {}", id.model.equation_string());
        if let Ok(eq) = id.model.equation("x") {
            let inc: Vec<String> = eq
                .terms
                .iter()
                .map(|t| format!("{} {:?}", t.term, t.inclusion))
                .collect();
            println!("   inclusion: {}", inc.join(", "));
        }
        for (k, v) in &id.trace.timing_ms {
            println!("   {k}: {v:.1}");
        }
        for d in &id.trace.dofs {
            if let Some(c1) = &d.criterion1 {
                println!(
                    "   κ = {:.2}, κ0 = {:.2}, high {}",
                    c1.kappa.standardised, c1.kappa0, c1.high_snr
                );
            }
            println!(
                "   settings δ {} w {}",
                d.settings.delta, d.settings.windows
            );
            for b in &d.bins {
                println!(
                    "   bins {} cutoff {:.2} band {:?}",
                    b.kept_bins, b.cutoff_hz, b.band_hz
                );
            }
            for a in &d.assembly {
                println!(
                    "   step n_terms {} rows {} mu {:.4} sigma {:.4}",
                    a.n_terms, a.rows, a.mu, a.sigma
                );
            }
            println!("   verdict {}", d.assembly_verdict);
        }
    }
    let t = Instant::now();
    let s = identify_sindy(
        &recs,
        &IdentifySpec::new(&["x"], "poly(x, x'; 1..7), xb_acc"),
    )?;
    println!(
        "sindy {:.1} ms: {}",
        t.elapsed().as_secs_f64() * 1e3,
        s.model.equation_string()
    );
    Ok(())
}
