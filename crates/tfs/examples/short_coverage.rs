//! Interval coverage on short records: a family of forced oscillators (hardening and softening
//! Duffing, Helmholtz, Van der Pol, quadratic damping, linear; parameters, forcing, start, length
//! and rate drawn from a seed), one record each with white noise on `x`, offered a library that
//! holds terms whose true value is zero. Counts how often a kept true term's 95 % interval covers
//! its value and how often a kept zero term's covers zero; with `--full` every library term is
//! kept (threshold 0, no elimination, records used as they are), which measures the intervals
//! without the selection. Beside coverage: the true terms kept within 5 % of their value, the
//! spurious terms (zero terms kept with an interval clear of zero, or none) and the records with
//! every true term within 5 % and no spurious term.
//!
//! ```text
//! cargo run --example short_coverage -- [--snr 40] [--seeds 1-6] [--noise-seeds 1-3]
//!     [--only NAME] [--full] [--no-elimination] [--show] [--out DIR]
//! ```
//!
//! `--no-elimination` keeps the selection but not the backward elimination by the term test,
//! which tells a term the selection drops from one the term test removes.

#[path = "../tests/common/short_systems.rs"]
mod short_systems;

use short_systems::{KINDS, Tally, draw};
use tfs::identify::{IdentifyOptions, identify, plan};
use tfs::records::Offsets;

fn range(text: &str) -> Vec<u64> {
    match text.split_once('-') {
        Some((a, b)) => (a.parse().unwrap()..=b.parse().unwrap()).collect(),
        None => text.split(',').map(|v| v.parse().unwrap()).collect(),
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let arg = |flag: &str| {
        args.iter()
            .position(|a| a == flag)
            .and_then(|i| args.get(i + 1).cloned())
    };
    let snrs: Vec<f64> = arg("--snr")
        .unwrap_or("40".into())
        .split(',')
        .map(|v| v.parse().unwrap())
        .collect();
    let seeds = range(&arg("--seeds").unwrap_or("1-6".into()));
    let noise_seeds = range(&arg("--noise-seeds").unwrap_or("1-3".into()));
    let only = arg("--only");
    // Every record written as `DIR/<system>-<seed>-n<noise>-<snr>dB.csv` with its library.
    let out = arg("--out");
    let full = args.iter().any(|a| a == "--full");
    let no_elimination = args.iter().any(|a| a == "--no-elimination");
    let show = args.iter().any(|a| a == "--show");
    let mut totals: Vec<(&str, Tally)> = Vec::new();
    // (coef − truth)/SE of every term with an interval, SE from the half-width over t(0.975, ν).
    let mut zs: Vec<(String, f64)> = Vec::new();
    for kind in 0..KINDS {
        for &seed in &seeds {
            let sys = draw(kind, seed);
            if only.as_deref().is_some_and(|o| !sys.name.contains(o)) {
                continue;
            }
            let truth = sys.truth();
            for &snr in &snrs {
                for &ns in &noise_seeds {
                    let rec = sys.record(snr, 1000 * seed + ns);
                    if let Some(dir) = &out {
                        let file =
                            format!("{}-{seed}-n{ns}-{snr}dB.csv", sys.name.replace(' ', "_"));
                        std::fs::create_dir_all(dir).unwrap();
                        tfs::data::write_csv(format!("{dir}/{file}"), &rec).unwrap();
                        std::fs::write(format!("{dir}/{file}.lib"), format!("{}\n", sys.library))
                            .unwrap();
                    }
                    // The records have no offsets: with `--full` they are used as they are, so
                    // that the truth is the law of the data fitted.
                    let opts = IdentifyOptions {
                        library: Some(sys.library.into()),
                        offsets: if full { Offsets::Keep } else { Offsets::Auto },
                        ..IdentifyOptions::default()
                    };
                    let mut p = plan(&opts, rec.names(), rec.source()).unwrap();
                    if full {
                        p.spec.tfs.fit.threshold = Some(0.0);
                    }
                    if full || no_elimination {
                        p.spec.tfs.uncertainty.elimination_rounds = 0;
                    }
                    let id = match identify(vec![rec], Vec::new(), &opts, &p) {
                        Ok(id) => id,
                        Err(e) => {
                            println!("{} seed {seed} noise {ns}: error {e}", sys.name);
                            let mut t = Tally::default();
                            t.add_nothing(&truth);
                            match totals.iter_mut().find(|(n, _)| *n == sys.name) {
                                Some(e) => e.1 = e.1.merged(&t),
                                None => totals.push((sys.name, t)),
                            }
                            continue;
                        }
                    };
                    let mut t = Tally::default();
                    t.add(&truth, &id.model);
                    let eq = id.model.equation("x").unwrap();
                    let mut line = Vec::new();
                    for mt in &eq.terms {
                        let name = mt.term.to_string();
                        let c = truth
                            .iter()
                            .find(|(n, _)| *n == name)
                            .map_or(0.0, |(_, c)| *c);
                        let mark = match mt.interval {
                            Some([lo, hi]) if lo <= c && c <= hi => "",
                            Some(_) => "!",
                            None => "?",
                        };
                        if let Some([lo, hi]) = mt.interval {
                            let half = 0.5 * (hi - lo);
                            zs.push((name.clone(), (mt.coef - c) / half));
                        }
                        line.push(format!(
                            "{mark}{name} {:.4} [{}] (truth {c:.4})",
                            mt.coef,
                            mt.interval
                                .map_or("-".into(), |[lo, hi]| format!("{lo:.4}, {hi:.4}"))
                        ));
                    }
                    println!(
                        "{:<18} {seed:>2} n{ns} {snr:>3} dB {:>4.1} s {:>3} Hz {:>13}  {}",
                        sys.name,
                        sys.dur,
                        sys.fs,
                        format!("{:?}", id.offsets.mode),
                        line.join("; ")
                    );
                    if show {
                        println!("    {}\n    {}", id.model.equation_string(), id.offsets.why);
                    }
                    match totals.iter_mut().find(|(n, _)| *n == sys.name) {
                        Some(e) => e.1 = e.1.merged(&t),
                        None => totals.push((sys.name, t)),
                    }
                }
            }
        }
    }
    println!();
    println!(
        "{:<18} {:>16} {:>8} {:>8} {:>16} {:>8} {:>8} {:>14} {:>9} {:>14}",
        "system",
        "true covered",
        "dropped",
        "no int.",
        "zero covered",
        "no int.",
        "offered",
        "true within 5%",
        "spurious",
        "records right"
    );
    let mut all = Tally::default();
    for (name, t) in &totals {
        print_row(name, t);
        all = all.merged(t);
    }
    print_row("total", &all);
    // Error over half-width: |e/h| ≤ 1 is coverage; for honest t intervals about 0.4–0.5 rms.
    let mut a: Vec<f64> = zs.iter().map(|(_, z)| z.abs()).collect();
    a.sort_by(f64::total_cmp);
    if !a.is_empty() {
        let q = |p: f64| a[((p * a.len() as f64) as usize).min(a.len() - 1)];
        println!(
            "|error|/half-width over {} intervals: median {:.2}, 90 % {:.2}, 95 % {:.2}, max {:.2}",
            a.len(),
            q(0.5),
            q(0.9),
            q(0.95),
            a[a.len() - 1]
        );
    }
}

fn print_row(name: &str, t: &Tally) {
    let pct = |a: usize, b: usize| {
        if b == 0 {
            "-".to_string()
        } else {
            format!("{a}/{b} {:.0}%", 100.0 * a as f64 / b as f64)
        }
    };
    let true_terms = t.true_with_interval + t.true_no_interval + t.true_dropped;
    println!(
        "{:<18} {:>16} {:>8} {:>8} {:>16} {:>8} {:>8} {:>14} {:>9} {:>14}",
        name,
        pct(t.true_covered, t.true_with_interval),
        t.true_dropped,
        t.true_no_interval,
        pct(t.zero_covered, t.zero_with_interval),
        t.zero_no_interval,
        t.zero_offered,
        pct(t.true_within, true_terms),
        t.spurious,
        pct(t.records_right, t.records)
    );
}
