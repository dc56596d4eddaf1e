//! Shared helpers: the surrogate truth (paper Table 1), data sets and
//! the error measures of the issue.
#![allow(dead_code)]

pub mod synthetic;

use synthetic::{NoiseSpec, Surrogate, SweepSpec, surrogate_record};
use tfs_data::Record;
use tfs_library::{Model, Term};
use tfs_signal::NoiseKind;

pub const TRUTH: Surrogate = Surrogate {
    c: 1.99,
    a: [12.12, -18.03, 6.56],
};

pub const TRAIN: [(f64, f64, f64, f64); 4] = [
    (0.05, 1.5, 100.0, 3.0),
    (0.05, 1.5, 60.0, 4.0),
    (0.1, 1.2, 80.0, 5.0),
    (0.05, 2.0, 120.0, 6.0),
];
pub const TEST: (f64, f64, f64, f64) = (0.08, 1.4, 90.0, 4.5);

/// Training records; `scale` shortens every sweep (1.0 = the lengths).
pub fn train(snr: Option<(f64, NoiseKind)>, scale: f64, count: usize) -> Vec<Record> {
    TRAIN
        .iter()
        .take(count)
        .enumerate()
        .map(|(i, &(f0, f1, d, a))| {
            let sw = SweepSpec {
                f0,
                f1,
                duration: d * scale,
                amplitude: a,
            };
            let noise = snr.map(|(s, kind)| NoiseSpec {
                snr_db: s,
                kind,
                seed: 100 + i as u64,
            });
            surrogate_record(&format!("train{}", i + 1), &TRUTH, sw, 200.0, noise).unwrap()
        })
        .collect()
}

pub struct Errors {
    pub damping_rel: f64,
    pub force_rel_rms: f64,
    pub stable: Vec<f64>,
    pub xb_acc: f64,
}

/// The measures for a 1-DOF model `x'' = Σ coef·term`.
pub fn errors(model: &Model) -> Errors {
    let eq = &model.equations[0];
    let mut c = 0.0;
    let mut poly = [0.0f64; 12];
    let mut xb = 0.0;
    for t in &eq.terms {
        let name = t.term.to_string();
        if name == "x'" {
            c = -t.coef;
        } else if name == "xb_acc" {
            xb = t.coef;
        } else if t.term.is_position_only("x") {
            let k = t.term.degree().unwrap() as usize;
            poly[k] -= t.coef;
        } else {
            panic!("unexpected term {name} = {}", t.coef);
        }
    }
    let f = |h: f64| {
        poly.iter()
            .enumerate()
            .map(|(k, a)| a * h.powi(k as i32))
            .sum::<f64>()
    };
    let n = 181;
    let (mut num, mut den) = (0.0, 0.0);
    for i in 0..n {
        let h = 1.8 * i as f64 / (n - 1) as f64;
        num += (f(h) - TRUTH.force(h)).powi(2);
        den += TRUTH.force(h).powi(2);
    }
    // Stable states: sign changes of F from − to + on a fine grid over [−0.3, 2.2].
    let mut stable = Vec::new();
    let m = 25000;
    let mut prev = f(-0.3);
    for i in 1..=m {
        let h = -0.3 + 2.5 * i as f64 / m as f64;
        let v = f(h);
        if prev < 0.0 && v >= 0.0 {
            stable.push(h);
        }
        // A double root at 0 (F ∝ h⁵) changes sign − to + too.
        prev = v;
    }
    let _ = Term::constant();
    Errors {
        damping_rel: (c - TRUTH.c).abs() / TRUTH.c,
        force_rel_rms: (num / den).sqrt(),
        stable,
        xb_acc: xb,
    }
}

/// Truth stable states of the surrogate: 0 and the larger root of a5 + a6 h + a7 h² = 0 where F' > 0.
pub fn truth_stable() -> Vec<f64> {
    let [a5, a6, a7] = TRUTH.a;
    let disc = (a6 * a6 - 4.0 * a7 * a5).sqrt();
    let r2 = (-a6 + disc) / (2.0 * a7);
    vec![0.0, r2]
}

pub fn stable_error(found: &[f64]) -> f64 {
    let truth = truth_stable();
    if found.len() != truth.len() {
        return f64::INFINITY;
    }
    found
        .iter()
        .zip(&truth)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max)
}
