//! Coefficient intervals are honest: over repeated noise draws, the 95 % intervals of a linear
//! oscillator's coefficients cover the truth at about the stated rate, and they are informative
//! (narrow compared with the coefficients).

use tfs_criteria::{IdentifySpec, identify_tfs};
use tfs_data::Record;
use tfs_dynamics::{Rk4Scratch, SecondOrderSystem, rk4_step};
use tfs_signal::{Excitation, NoiseKind, Sweep, SweepKind};

/// x'' = −k·x − c·x' − xb_acc.
struct Linear {
    k: f64,
    c: f64,
}

impl SecondOrderSystem for Linear {
    fn dofs(&self) -> usize {
        1
    }
    fn inputs(&self) -> usize {
        1
    }
    fn accel(&self, _t: f64, x: &[f64], v: &[f64], u: &[f64], a: &mut [f64]) {
        a[0] = -self.k * x[0] - self.c * v[0] - u[0];
    }
}

fn record(sys: &Linear, f0: f64, f1: f64, dur: f64, amp: f64, snr: f64, seed: u64) -> Record {
    let fs = 100.0;
    let ex = Sweep::new(SweepKind::Linear, f0, f1, dur, amp, 2.0).unwrap();
    let dt = 1.0 / fs;
    let n = (dur * fs).round() as usize + 1;
    let t: Vec<f64> = (0..n).map(|i| i as f64 * dt).collect();
    let mut x = vec![0.0; n];
    let (mut xs, mut vs) = ([0.0], [0.0]);
    let mut sc = Rk4Scratch::new(1);
    for i in 1..n {
        let t0 = t[i - 1];
        let u = |s: f64| [ex.value(s)];
        rk4_step(
            sys,
            t0,
            dt,
            &mut xs,
            &mut vs,
            &u(t0),
            &u(t0 + 0.5 * dt),
            &u(t0 + dt),
            &mut sc,
        );
        x[i] = xs[0];
    }
    let mut acc = ex.sample(&t);
    let nx = tfs_signal::noise::noise_for(&x, snr, NoiseKind::White, seed).unwrap();
    let na = tfs_signal::noise::noise_for(&acc, snr, NoiseKind::White, seed ^ 0x5eed).unwrap();
    x.iter_mut().zip(nx).for_each(|(a, b)| *a += b);
    acc.iter_mut().zip(na).for_each(|(a, b)| *a += b);
    Record::new(
        format!("lin{seed}"),
        t,
        vec![("x".into(), x), ("xb_acc".into(), acc)],
    )
    .unwrap()
}

#[test]
fn intervals_cover_the_truth_at_about_the_stated_rate() {
    coverage(0);
}

/// The same with weighted frequency-domain rows (feasible GLS): the cluster-jackknife intervals
/// must stay honest when the weights come from the data.
#[test]
fn weighted_rows_keep_the_intervals_honest() {
    coverage(2);
}

fn coverage(reweight: usize) {
    let sys = Linear { k: 4.0, c: 0.4 };
    let truth: [(&str, f64); 3] = [("x", -4.0), ("x'", -0.4), ("xb_acc", -1.0)];
    let mut spec = IdentifySpec::new(&["x"], "x, x', xb_acc");
    spec.tfs.criterion3.reweight = reweight;
    let (mut covered, mut total, mut rel_width) = (0, 0, 0.0);
    // Lowest bootstrap inclusion of a true term pinned down to better than ±25 %.
    let mut min_incl: f64 = 1.0;
    let draws = 20;
    for seed in 0..draws {
        let recs: Vec<Record> = [
            (0.05, 1.0, 80.0, 2.0),
            (0.1, 0.8, 60.0, 3.0),
            (0.05, 1.2, 70.0, 2.5),
        ]
        .iter()
        .enumerate()
        .map(|(i, &(f0, f1, d, a))| record(&sys, f0, f1, d, a, 30.0, 1000 * seed + i as u64))
        .collect();
        let id = identify_tfs(&recs, &spec).unwrap();
        let eq = &id.model.equations[0];
        for (name, want) in truth {
            let t = eq
                .terms
                .iter()
                .find(|t| t.term.to_string() == name)
                .unwrap_or_else(|| {
                    panic!(
                        "seed {seed}: term {name} missing from {}",
                        id.model.equation_string()
                    )
                });
            let [lo, hi] = t.interval.expect("interval");
            let p = t.inclusion.expect("inclusion");
            assert!((0.0..=1.0).contains(&p));
            if (hi - lo) / 2.0 < 0.25 * want.abs() {
                min_incl = min_incl.min(p);
            }
            total += 1;
            if lo <= want && want <= hi {
                covered += 1;
            }
            rel_width += (hi - lo) / 2.0 / want.abs();
        }
    }
    let rate = covered as f64 / total as f64;
    let mean_rel = rel_width / total as f64;
    eprintln!("coverage {covered}/{total} = {rate:.2}, mean relative half-width {mean_rel:.4}");
    // 95 % within the sampling error of 60 intervals. With weighted rows, intervals on the
    // jackknife's clusters less one (not each coefficient's effective degrees of freedom)
    // covered 52/60.
    assert!(
        rate >= 0.9,
        "95% intervals covered the truth in only {covered}/{total}"
    );
    // A term the intervals pin down is one that resampling keeps.
    eprintln!("lowest inclusion of a well-determined true term {min_incl:.2}");
    assert!(
        min_incl >= 0.9,
        "a well-determined true term was kept in only {min_incl} of the bootstrap resamples"
    );
    // Informative: much narrower than the coefficients themselves.
    assert!(
        mean_rel < 0.1,
        "intervals too wide to be useful: {mean_rel}"
    );
}
