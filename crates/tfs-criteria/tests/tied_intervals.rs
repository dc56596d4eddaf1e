//! The tied chain fit's intervals are honest: over repeated noise draws, the 95 % intervals of a
//! two-mass chain's coefficients (a linear ground spring and damper, a hardening coupling spring
//! and a coupling damper shared by both equations) cover the truth at about the stated rate,
//! and the partner equation's intervals mirror the owner's.

use tfs_criteria::{IdentifySpec, TieOptions, identify_tfs_tied};
use tfs_data::Record;
use tfs_dynamics::{Rk4Scratch, SecondOrderSystem, rk4_step};
use tfs_signal::{Excitation, NoiseKind, Sweep, SweepKind};

const K1: f64 = 4.0;
const C1: f64 = 0.3;
const K2: f64 = 6.0;
const K3: f64 = 8.0;
const C2: f64 = 0.2;

/// x1'' = −K1 x1 − C1 x1' + K2 h + K3 h³ + C2 h' − u, x2'' = −K2 h − K3 h³ − C2 h' − u, h = x2 − x1.
struct Chain;

impl SecondOrderSystem for Chain {
    fn dofs(&self) -> usize {
        2
    }
    fn inputs(&self) -> usize {
        1
    }
    fn accel(&self, _t: f64, x: &[f64], v: &[f64], u: &[f64], a: &mut [f64]) {
        let (h, hd) = (x[1] - x[0], v[1] - v[0]);
        let f = K2 * h + K3 * h.powi(3) + C2 * hd;
        a[0] = -K1 * x[0] - C1 * v[0] + f - u[0];
        a[1] = -f - u[0];
    }
}

fn record(f0: f64, f1: f64, dur: f64, amp: f64, snr: f64, seed: u64) -> Record {
    let fs = 100.0;
    let ex = Sweep::new(SweepKind::Linear, f0, f1, dur, amp, 2.0).unwrap();
    let dt = 1.0 / fs;
    let n = (dur * fs).round() as usize + 1;
    let t: Vec<f64> = (0..n).map(|i| i as f64 * dt).collect();
    let mut x = [vec![0.0; n], vec![0.0; n]];
    let (mut xs, mut vs) = ([0.0; 2], [0.0; 2]);
    let mut sc = Rk4Scratch::new(2);
    for i in 1..n {
        let t0 = t[i - 1];
        let u = |s: f64| [ex.value(s)];
        rk4_step(
            &Chain,
            t0,
            dt,
            &mut xs,
            &mut vs,
            &u(t0),
            &u(t0 + 0.5 * dt),
            &u(t0 + dt),
            &mut sc,
        );
        x[0][i] = xs[0];
        x[1][i] = xs[1];
    }
    let mut acc = ex.sample(&t);
    let mut cols = Vec::new();
    for (d, xd) in x.iter_mut().enumerate() {
        let nz =
            tfs_signal::noise::noise_for(xd, snr, NoiseKind::White, seed + 7 * d as u64).unwrap();
        xd.iter_mut().zip(nz).for_each(|(a, b)| *a += b);
        cols.push((format!("x{}", d + 1), xd.clone()));
    }
    let na = tfs_signal::noise::noise_for(&acc, snr, NoiseKind::White, seed ^ 0x5eed).unwrap();
    acc.iter_mut().zip(na).for_each(|(a, b)| *a += b);
    cols.push(("xb_acc".into(), acc));
    Record::new(format!("chain{seed}"), t, cols).unwrap()
}

#[test]
fn tied_intervals_cover_the_truth_at_about_the_stated_rate() {
    const LIB1: &str = "x1, x1', (x2-x1), (x2-x1)^3, (x2-x1)', xb_acc";
    const LIB2: &str = "(x2-x1), (x2-x1)^3, (x2-x1)', xb_acc";
    let mut spec = IdentifySpec::new(&["x1", "x2"], LIB1);
    spec.dof_libraries = vec![LIB1.to_string(), LIB2.to_string()];
    let truth: [(&str, &str, f64); 9] = [
        ("x1", "x1", -K1),
        ("x1", "x1'", -C1),
        ("x1", "(x2-x1)", K2),
        ("x1", "(x2-x1)^3", K3),
        ("x1", "(x2-x1)'", C2),
        ("x1", "xb_acc", -1.0),
        ("x2", "(x2-x1)", -K2),
        ("x2", "(x2-x1)^3", -K3),
        ("x2", "xb_acc", -1.0),
    ];
    let (mut covered, mut total, mut rel_width) = (0, 0, 0.0);
    let draws = 16;
    for seed in 0..draws {
        let recs: Vec<Record> = [
            (0.05, 1.5, 80.0, 1.5),
            (0.1, 1.2, 60.0, 2.0),
            (0.05, 1.8, 70.0, 1.8),
            (0.1, 1.5, 60.0, 2.5),
        ]
        .iter()
        .enumerate()
        .map(|(i, &(f0, f1, d, a))| record(f0, f1, d, a, 30.0, 1000 * seed + 10 * i as u64))
        .collect();
        let id = identify_tfs_tied(&recs, &spec, &TieOptions::default()).unwrap();
        for (dof, name, want) in truth {
            let eq = id.model.equation(dof).unwrap();
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
            assert!(lo <= t.coef && t.coef <= hi);
            total += 1;
            if lo <= want && want <= hi {
                covered += 1;
            }
            rel_width += (hi - lo) / 2.0 / want.abs();
        }
        // A tied partner's interval is the owner's mirrored (equal masses: factor −1).
        let iv = |dof: &str| {
            id.model
                .equation(dof)
                .unwrap()
                .terms
                .iter()
                .find(|t| t.term.to_string() == "(x2-x1)^3")
                .and_then(|t| t.interval)
                .unwrap()
        };
        let (a, b) = (iv("x1"), iv("x2"));
        assert!(
            (a[0] + b[1]).abs() < 1e-9 * a[0].abs().max(1.0)
                && (a[1] + b[0]).abs() < 1e-9 * a[1].abs().max(1.0),
            "{a:?} vs {b:?}"
        );
    }
    let rate = covered as f64 / total as f64;
    let mean_rel = rel_width / total as f64;
    eprintln!("coverage {covered}/{total} = {rate:.2}, mean relative half-width {mean_rel:.4}");
    assert!(
        rate >= 0.9,
        "95% intervals covered the truth in only {covered}/{total}"
    );
    assert!(
        mean_rel < 0.2,
        "intervals too wide to be useful: {mean_rel}"
    );
}
