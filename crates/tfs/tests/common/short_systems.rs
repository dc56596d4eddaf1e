//! A family of short-record oscillators for interval coverage: each draw is one forced oscillator
//! `x'' = Σ c·θ + force` (parameters, forcing, start, length and rate drawn from a seed), recorded
//! once with white noise on `x`, and offered a library holding terms whose true value is zero.
//! Shared by `tests/interval_coverage.rs` and `examples/short_coverage.rs`.

#![allow(dead_code)]

use tfs::data::Record;
use tfs::library::{Library, Model};
use tfs::signal::NoiseKind;
use tfs::signal::noise::add_noise_seeded;

/// SplitMix64: a small, fixed generator for the parameter draws.
pub struct Rng(u64);

impl Rng {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }
    fn uniform(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * self.next()
    }
    fn pick<T: Copy>(&mut self, xs: &[T]) -> T {
        xs[((self.next() * xs.len() as f64) as usize).min(xs.len() - 1)]
    }
}

/// The right-hand side `x'' = f(x, x', force)`.
type Rhs = Box<dyn Fn(f64, f64, f64) -> f64 + Send + Sync>;

/// One drawn oscillator and how it is recorded.
pub struct System {
    /// The oscillator's kind.
    pub name: &'static str,
    /// The library offered (true terms and terms whose true value is zero).
    pub library: &'static str,
    /// True terms `(term, coefficient)`; every other library term is zero.
    pub terms: Vec<(&'static str, f64)>,
    rhs: Rhs,
    /// Forcing `Σ a·cos(w·t + φ)`.
    forcing: Vec<(f64, f64, f64)>,
    x0: f64,
    /// Record length (s) and sampling rate (Hz).
    pub dur: f64,
    pub fs: f64,
}

/// Kinds of oscillator in the family.
pub const KINDS: usize = 6;

/// The oscillator of `kind` drawn from `seed`.
pub fn draw(kind: usize, seed: u64) -> System {
    let mut r = Rng(seed.wrapping_mul(7919).wrapping_add(101 * kind as u64 + 5));
    let dur = r.uniform(12.0, 30.0);
    let fs = r.pick(&[50.0, 100.0, 200.0]);
    let sign = if r.next() < 0.5 { -1.0 } else { 1.0 };
    let k = r.uniform(1.0, 5.0);
    let w = r.uniform(0.6, 1.5) * k.sqrt();
    let ph = r.uniform(0.0, std::f64::consts::TAU);
    let (name, library, terms, rhs, amp, x0): (_, _, Vec<(&str, f64)>, Rhs, f64, f64) = match kind {
        0 => {
            let b = r.uniform(0.2, 1.0) * k;
            let c = r.uniform(0.03, 0.15) * k.sqrt();
            (
                "hardening Duffing",
                "x, x^2, x^3, x', x^2*x', force",
                vec![("x", -k), ("x^3", -b), ("x'", -c)],
                Box::new(move |x, v, f| -k * x - b * x * x * x - c * v + f),
                r.uniform(0.3, 1.0) * k,
                sign * r.uniform(0.3, 1.0),
            )
        }
        1 => {
            // Escape beyond |x| = √(k/b) ≥ 2: motion kept within about 1.
            let b = r.uniform(0.05, 0.2) * k;
            let c = r.uniform(0.05, 0.15) * k.sqrt();
            (
                "softening spring",
                "x, x^2, x^3, x', abs(x')*x', force",
                vec![("x", -k), ("x^3", b), ("x'", -c)],
                Box::new(move |x, v, f| -k * x + b * x * x * x - c * v + f),
                r.uniform(0.1, 0.25) * k,
                sign * r.uniform(0.3, 0.8),
            )
        }
        2 => {
            let a = r.uniform(0.3, 0.8) * k;
            let c = r.uniform(0.03, 0.15) * k.sqrt();
            (
                "Helmholtz",
                "x, x^2, x^3, x', force",
                vec![("x", -k), ("x^2", -a), ("x'", -c)],
                Box::new(move |x, v, f| -k * x - a * x * x - c * v + f),
                r.uniform(0.05, 0.15) * k,
                sign * r.uniform(0.1, 0.3),
            )
        }
        3 => {
            let mu = r.uniform(0.2, 1.0) * k.sqrt();
            (
                "Van der Pol",
                "x, x^2, x^3, x', x^2*x', force",
                vec![("x", -k), ("x'", mu), ("x^2*x'", -mu)],
                Box::new(move |x, v, f| -k * x + mu * v - mu * x * x * v + f),
                r.uniform(0.3, 1.0) * k,
                sign * r.uniform(0.5, 2.0),
            )
        }
        4 => {
            let c = r.uniform(0.1, 0.5);
            (
                "quadratic damping",
                "x, x^2, x^3, x', abs(x')*x', force",
                vec![("x", -k), ("abs(x')*x'", -c)],
                Box::new(move |x, v, f| -k * x - c * v.abs() * v + f),
                r.uniform(0.3, 1.0) * k,
                sign * r.uniform(0.5, 1.5),
            )
        }
        _ => {
            let c = r.uniform(0.03, 0.2) * k.sqrt();
            (
                "linear",
                "x, x^2, x^3, x', force",
                vec![("x", -k), ("x'", -c)],
                Box::new(move |x, v, f| -k * x - c * v + f),
                r.uniform(0.3, 1.0) * k,
                sign * r.uniform(0.0, 1.0),
            )
        }
    };
    let mut terms = terms;
    terms.push(("force", 1.0));
    System {
        name,
        library,
        terms,
        rhs,
        forcing: vec![(amp, w, ph)],
        x0,
        dur,
        fs,
    }
}

impl System {
    fn force(&self, t: f64) -> f64 {
        self.forcing
            .iter()
            .map(|&(a, w, p)| a * (w * t + p).cos())
            .sum()
    }

    /// The clean displacement at the samples (RK4, 20 substeps a sample) and the force.
    fn simulate(&self) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let dt = 1.0 / self.fs;
        let n = (self.dur * self.fs).round() as usize + 1;
        let sub = 20;
        let h = dt / sub as f64;
        let (mut x, mut v) = (self.x0, 0.0);
        let f = |t: f64, x: f64, v: f64| (v, (self.rhs)(x, v, self.force(t)));
        let mut xs = Vec::with_capacity(n);
        for k in 0..n {
            xs.push(x);
            for j in 0..sub {
                let t = k as f64 * dt + j as f64 * h;
                let (k1x, k1v) = f(t, x, v);
                let (k2x, k2v) = f(t + h / 2.0, x + h / 2.0 * k1x, v + h / 2.0 * k1v);
                let (k3x, k3v) = f(t + h / 2.0, x + h / 2.0 * k2x, v + h / 2.0 * k2v);
                let (k4x, k4v) = f(t + h, x + h * k3x, v + h * k3v);
                x += h / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x);
                v += h / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v);
            }
        }
        let t: Vec<f64> = (0..n).map(|k| k as f64 * dt).collect();
        let force = t.iter().map(|&t| self.force(t)).collect();
        (t, xs, force)
    }

    /// The record `t, x, force`, white noise at `snr_db` on `x` drawn from `noise_seed`.
    pub fn record(&self, snr_db: f64, noise_seed: u64) -> Record {
        let (t, clean, force) = self.simulate();
        assert!(
            clean.iter().all(|v| v.is_finite() && v.abs() < 10.0),
            "{} escaped",
            self.name
        );
        let x = add_noise_seeded(&clean, snr_db, NoiseKind::White, noise_seed).unwrap();
        Record::new(
            format!("{}.csv", self.name.replace(' ', "_")),
            t,
            vec![("x".into(), x), ("force".into(), force)],
        )
        .unwrap()
    }

    /// Every library term's name (canonical) and true value (zero for the terms not in the law).
    pub fn truth(&self) -> Vec<(String, f64)> {
        let canonical = |s: &str| Library::parse(s, &["x"]).unwrap().terms()[0].to_string();
        Library::parse(self.library, &["x"])
            .unwrap()
            .terms()
            .iter()
            .map(|t| {
                let name = t.to_string();
                let c = self
                    .terms
                    .iter()
                    .find(|(n, _)| canonical(n) == name)
                    .map_or(0.0, |(_, c)| *c);
                (name, c)
            })
            .collect()
    }
}

/// Counts of one or more identifications against the truth.
#[derive(Debug, Default, Clone, Copy)]
pub struct Tally {
    /// True terms kept with an interval, and how many of those cover the true value.
    pub true_with_interval: usize,
    pub true_covered: usize,
    /// True terms dropped, or kept without an interval.
    pub true_dropped: usize,
    pub true_no_interval: usize,
    /// Zero terms kept with an interval, and how many of those cover zero.
    pub zero_with_interval: usize,
    pub zero_covered: usize,
    /// Zero terms kept without an interval.
    pub zero_no_interval: usize,
    /// Zero terms offered (kept or not).
    pub zero_offered: usize,
    /// True terms kept within [`TOLERANCE`] of their value (relative).
    pub true_within: usize,
    /// Zero terms kept whose interval excludes zero, or that have none (spurious terms).
    pub spurious: usize,
    /// Records, and those with every true term kept within [`TOLERANCE`] and no spurious term.
    pub records: usize,
    pub records_right: usize,
}

/// The relative error within which a kept true term counts as right.
pub const TOLERANCE: f64 = 0.05;

impl Tally {
    /// Adds the terms of `model` against `truth` (every library term, zero where not in the law;
    /// a constant term, when the fit adds one, counts as a zero term).
    pub fn add(&mut self, truth: &[(String, f64)], model: &Model) {
        let eq = model.equation("x").unwrap();
        let before = (self.true_within, self.spurious);
        self.records += 1;
        for (name, c) in truth {
            let kept = eq.terms.iter().find(|t| t.term.to_string() == *name);
            if *c == 0.0 {
                self.zero_offered += 1;
            }
            match (kept, *c == 0.0) {
                (None, false) => self.true_dropped += 1,
                (None, true) => {}
                (Some(t), zero) => {
                    if !zero && ((t.coef - c) / c).abs() <= TOLERANCE {
                        self.true_within += 1;
                    }
                    self.add_interval(t.interval, *c, zero);
                }
            }
        }
        for t in &eq.terms {
            if t.term.is_constant() {
                self.zero_offered += 1;
                self.add_interval(t.interval, 0.0, true);
            }
        }
        let n_true = truth.iter().filter(|(_, c)| *c != 0.0).count();
        if self.true_within - before.0 == n_true && self.spurious == before.1 {
            self.records_right += 1;
        }
    }

    /// Adds one kept term's interval `iv` against its true value `c` (`zero`: a term not in the
    /// law, spurious when its interval excludes zero or it has none).
    fn add_interval(&mut self, iv: Option<[f64; 2]>, c: f64, zero: bool) {
        match iv {
            None if zero => {
                self.zero_no_interval += 1;
                self.spurious += 1;
            }
            None => self.true_no_interval += 1,
            Some([lo, hi]) => {
                let covered = usize::from(lo <= c && c <= hi);
                if zero {
                    self.zero_with_interval += 1;
                    self.zero_covered += covered;
                    self.spurious += 1 - covered;
                } else {
                    self.true_with_interval += 1;
                    self.true_covered += covered;
                }
            }
        }
    }

    /// Adds an identification that kept nothing (`tfs identify` refuses to write `x'' = 0`):
    /// every true term dropped, no zero term claimed.
    pub fn add_nothing(&mut self, truth: &[(String, f64)]) {
        self.records += 1;
        for (_, c) in truth {
            if *c == 0.0 {
                self.zero_offered += 1;
            } else {
                self.true_dropped += 1;
            }
        }
    }

    /// The sum of two tallies.
    pub fn merged(mut self, o: &Tally) -> Tally {
        self.true_with_interval += o.true_with_interval;
        self.true_covered += o.true_covered;
        self.true_dropped += o.true_dropped;
        self.true_no_interval += o.true_no_interval;
        self.zero_with_interval += o.zero_with_interval;
        self.zero_covered += o.zero_covered;
        self.zero_no_interval += o.zero_no_interval;
        self.zero_offered += o.zero_offered;
        self.true_within += o.true_within;
        self.spurious += o.spurious;
        self.records += o.records;
        self.records_right += o.records_right;
        self
    }
}
