//! Cell and chain dynamics: one-cell chain = cell, energy conservation, equilibria, momentum balance.

use std::sync::Arc;
use tfs_dynamics::{Dopri5, Integrator, SampledInput, SecondOrderSystem};
use tfs_origami::{CellSystem, Chain, KreslingCell, KreslingParams, Truth};

fn cell(gamma: f64, c: f64) -> Arc<KreslingCell> {
    Arc::new(
        KreslingCell::new(KreslingParams {
            gamma0_deg: gamma,
            c,
            ..KreslingParams::default()
        })
        .unwrap(),
    )
}

#[test]
fn chain_of_one_equals_the_cell_exactly() {
    for truth in [Truth::Truss, Truth::Surrogate] {
        let single = CellSystem::new(cell(30.0, 2.0), truth).unwrap();
        let chain = Chain::new(vec![single.clone()]).unwrap();
        assert_eq!(chain.truth_name(), single.truth_name());
        let mut a1 = [0.0];
        let mut a2 = [0.0];
        for i in 0..500 {
            let x = -0.2 + 2.2 * i as f64 / 499.0;
            let v = (i as f64 * 0.37).sin() * 3.0;
            let u = (i as f64 * 0.11).cos() * 5.0;
            single.accel(0.0, &[x], &[v], &[u], &mut a1);
            chain.accel(0.0, &[x], &[v], &[u], &mut a2);
            assert_eq!(a1[0].to_bits(), a2[0].to_bits());
        }
        // The single-cell equation itself: x'' = −(c/m)x' − F(x)/m − xb_acc.
        let (x, v, u) = (1.2, 0.3, -0.7);
        single.accel(0.0, &[x], &[v], &[u], &mut a1);
        let f = single.force_law().force(x);
        assert!((a1[0] - (-2.0 * v - f - u)).abs() < 1e-13);
        // Trajectories agree bit for bit.
        let dt = 0.01;
        let t: Vec<f64> = (0..500).map(|k| k as f64 * dt).collect();
        let inp = SampledInput::new(
            0.0,
            dt,
            vec![t.iter().map(|t| 3.0 * (4.0 * t).sin()).collect()],
        )
        .unwrap();
        let r1 = Dopri5::default()
            .integrate(&single, &inp, &[0.0], &[0.0], &t)
            .unwrap();
        let r2 = Dopri5::default()
            .integrate(&chain, &inp, &[0.0], &[0.0], &t)
            .unwrap();
        assert_eq!(r1.x, r2.x);
    }
}

#[test]
fn undamped_cell_conserves_energy_over_100_periods() {
    let sys = CellSystem::new(cell(30.0, 0.0), Truth::Truss).unwrap();
    let c = match sys.force_law() {
        tfs_origami::CellForce::Truss(c) => c.clone(),
        _ => unreachable!(),
    };
    let s2 = c.stable()[1];
    let omega = c.stiffness(s2).sqrt();
    let period = 2.0 * std::f64::consts::PI / omega;
    let (x0, v0) = (s2 - 0.15, 0.0);
    assert!(
        sys.energy(x0, v0) < c.potential(c.unstable()[0]),
        "must stay in the deployed well"
    );
    let n = 2001;
    let t: Vec<f64> = (0..n)
        .map(|k| 100.0 * period * k as f64 / (n - 1) as f64)
        .collect();
    let tr = Dopri5::with_tol(1e-13, 1e-15)
        .integrate(&sys, &SampledInput::zero(1), &[x0], &[v0], &t)
        .unwrap();
    let e0 = sys.energy(x0, v0);
    let scale = e0; // V(s2) = 0, so e0 is the oscillation energy
    let mut worst: f64 = 0.0;
    for k in 0..n {
        worst = worst.max((sys.energy(tr.x[0][k], tr.v[0][k]) - e0).abs() / scale);
    }
    eprintln!("relative energy drift over 100 periods: {worst:e}");
    assert!(worst < 1e-8, "relative energy drift {worst:e}");
    // It really oscillates (crosses the equilibrium many times).
    let crossings = tr.x[0]
        .windows(2)
        .filter(|w| (w[0] - s2) * (w[1] - s2) < 0.0)
        .count();
    assert!(crossings > 150, "{crossings}");
}

#[test]
fn undamped_cell_conserves_energy_through_the_stop() {
    // Starting folded with kinetic energy below the barrier: bounces on the stop at h = 0.
    let sys = CellSystem::new(cell(30.0, 0.0), Truth::Truss).unwrap();
    let t: Vec<f64> = (0..1001).map(|k| k as f64 * 0.05).collect();
    let (x0, v0) = (0.3, -0.5);
    let tr = Dopri5::with_tol(1e-12, 1e-14)
        .integrate(&sys, &SampledInput::zero(1), &[x0], &[v0], &t)
        .unwrap();
    let e0 = sys.energy(x0, v0);
    let min_x = tr.x[0].iter().cloned().fold(f64::INFINITY, f64::min);
    assert!(min_x < 0.0 && min_x > -0.01, "min x {min_x}");
    for k in 0..t.len() {
        let e = sys.energy(tr.x[0][k], tr.v[0][k]);
        assert!((e - e0).abs() < 1e-7 * e0, "k = {k}: {e} vs {e0}");
    }
}

#[test]
fn two_cell_chain_equilibria_and_momentum_balance() {
    let c1 = CellSystem::new(cell(20.0, 1.0), Truth::Truss).unwrap();
    let c2 = CellSystem::new(cell(28.5, 1.0), Truth::Truss).unwrap();
    let chain = Chain::new(vec![c1.clone(), c2.clone()]).unwrap();
    let eq = chain.equilibria();
    let stable: Vec<_> = eq.iter().filter(|e| e.stable).collect();
    // monostable × bistable = 2 stable equilibria.
    assert_eq!(stable.len(), 2);
    let mut a = [0.0; 2];
    for e in &eq {
        chain.accel(0.0, &e.x, &[0.0, 0.0], &[0.0], &mut a);
        assert!(a[0].abs() < 1e-8 && a[1].abs() < 1e-8, "{e:?} {a:?}");
        assert!((e.x[1] - e.h[0] - e.h[1]).abs() < 1e-15);
    }
    // Internal forces cancel: Σ m_i a_i = −F_1(h_1) − c_1 h_1' − Σ m_i u.
    let (x, v, u) = ([1.1, 2.0], [0.3, -0.4], [0.9]);
    chain.accel(0.0, &x, &v, &u, &mut a);
    let total = c1.mass() * a[0] + c2.mass() * a[1];
    let expect = -c1.force_law().force(x[0]) - c1.damping() * v[0] - (c1.mass() + c2.mass()) * u[0];
    assert!((total - expect).abs() < 1e-12, "{total} vs {expect}");
    // Undamped, unforced two-cell chain conserves energy.
    let c1u = CellSystem::new(cell(20.0, 0.0), Truth::Truss).unwrap();
    let c2u = CellSystem::new(cell(28.5, 0.0), Truth::Truss).unwrap();
    let ch = Chain::new(vec![c1u, c2u]).unwrap();
    let x0 = [stable[0].x[0] + 0.05, stable[0].x[1] - 0.03];
    let t: Vec<f64> = (0..1001).map(|k| k as f64 * 0.05).collect();
    let tr = Dopri5::with_tol(1e-12, 1e-14)
        .integrate(&ch, &SampledInput::zero(1), &x0, &[0.0, 0.0], &t)
        .unwrap();
    let e0 = ch.energy(&x0, &[0.0, 0.0]);
    let de = (ch.energy(
        &[tr.x[0][1000], tr.x[1][1000]],
        &[tr.v[0][1000], tr.v[1][1000]],
    ) - e0)
        .abs();
    assert!(de < 1e-8 * e0.abs().max(1e-3), "{de}");
}

#[test]
fn truth_labels_parse_and_print() {
    assert_eq!("truss".parse::<Truth>().unwrap(), Truth::Truss);
    assert_eq!(" Surrogate ".parse::<Truth>().unwrap(), Truth::Surrogate);
    let e = "poly".parse::<Truth>().unwrap_err().to_string();
    assert!(e.contains("'poly'") && e.contains("surrogate"));
    assert_eq!(Truth::Surrogate.label(), "surrogate");
    assert_eq!(serde_json::to_string(&Truth::Truss).unwrap(), "\"truss\"");
    let s = CellSystem::new(cell(30.0, 2.0), Truth::Surrogate).unwrap();
    assert_eq!(s.truth_name(), "surrogate{5,6,7}");
    assert!(Chain::new(vec![]).is_err());
}
