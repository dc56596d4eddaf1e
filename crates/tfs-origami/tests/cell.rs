//! Kresling cell: reference geometry, states, surrogate coefficients, table accuracy, F = dV/dh.

use std::f64::consts::PI;
use tfs_origami::{CellOptions, KreslingCell, KreslingParams, Surrogate, SurrogateSpec};

fn params(gamma: f64) -> KreslingParams {
    KreslingParams {
        gamma0_deg: gamma,
        ..KreslingParams::default()
    }
}

/// Independent direct solve: global scan of U(h, ·) then bisection on the torque T.
fn direct_force(cell: &KreslingCell, h: f64) -> (f64, f64) {
    let n = 7200;
    let mut best = (0.0, f64::INFINITY);
    for i in 0..n {
        let th = -PI + 2.0 * PI * (i as f64 + 0.5) / n as f64;
        let u = cell.energy(h, th);
        if u < best.1 {
            best = (th, u);
        }
    }
    let d = 2.0 * PI / n as f64;
    let (mut a, mut b) = (best.0 - 2.0 * d, best.0 + 2.0 * d);
    let ta = cell.torque(h, a);
    assert!(ta * cell.torque(h, b) < 0.0, "no bracket at h = {h}");
    for _ in 0..200 {
        let m = 0.5 * (a + b);
        if m <= a || m >= b {
            break;
        }
        if (cell.torque(h, m) < 0.0) == (ta < 0.0) {
            a = m;
        } else {
            b = m;
        }
    }
    let th = 0.5 * (a + b);
    // F = ∂U/∂h at fixed θ by a 4th-order central difference (independent of the closed form).
    let e = 1e-4;
    let f = (-cell.energy(h + 2.0 * e, th) + 8.0 * cell.energy(h + e, th)
        - 8.0 * cell.energy(h - e, th)
        + cell.energy(h - 2.0 * e, th))
        / (12.0 * e);
    (th, f)
}

#[test]
fn b0_satisfies_law_of_cosines_and_inscribed_hexagon() {
    for g in [20.0, 28.5, 30.0, 35.0] {
        let p = params(g);
        let b0 = p.b0();
        let gr = g.to_radians();
        // Triangle (a0, b0, c0) with γ0 opposite c0.
        let lhs = p.c0 * p.c0;
        let rhs = p.a0 * p.a0 + b0 * b0 - 2.0 * p.a0 * b0 * gr.cos();
        assert!((lhs - rhs).abs() < 1e-12, "γ0 = {g}: {lhs} vs {rhs}");
    }
    // γ0 = 30°, R = c0: the flat triangle is inscribed in the hexagon's circumcircle.
    let p = params(30.0);
    let phi0 = (p.a0 / 2.0).asin();
    assert!((p.b0() - 2.0 * (phi0 + PI / 6.0).sin()).abs() < 1e-12);
}

#[test]
fn paper_cell_states_and_barrier() {
    let cell = KreslingCell::new(params(30.0)).unwrap();
    let s = cell.summary();
    assert_eq!(s.classification, "bistable");
    assert_eq!(s.stable.len(), 2);
    assert_eq!(s.stable[0], 0.0);
    assert!((s.stable[1] - 1.582).abs() < 1e-3, "{:?}", s.stable);
    assert_eq!(s.unstable.len(), 1);
    assert!((s.unstable[0] - 1.156).abs() < 1e-3, "{:?}", s.unstable);
    // The stable states are the stress-free configurations (closed form).
    let rest = cell.rest_states();
    assert_eq!(rest.len(), 2);
    assert!(rest[0].0.abs() < 1e-7);
    assert!((s.stable[1] - rest[1].0).abs() < 1e-9);
    // ... and the branch passes through them with zero energy.
    for (h, th) in rest {
        assert!((cell.theta(h) - th).abs() < 1e-7);
        assert!(cell.potential(h).abs() < 1e-9);
    }
    // Barrier: both wells have V = 0, so forward = backward = V(u).
    let b = s.barrier.unwrap();
    assert!((b - cell.potential(s.unstable[0])).abs() < 1e-12);
    assert!((s.barriers[0].backward - b).abs() < 1e-8);
    assert!(b > 0.3 && b < 0.5);
    let json = serde_json::to_value(&s).unwrap();
    for key in ["b0", "stable", "unstable", "barrier"] {
        assert!(json.get(key).is_some(), "missing key {key}");
    }
}

#[test]
fn classification_of_the_chain_cells() {
    let c20 = KreslingCell::new(params(20.0)).unwrap();
    assert_eq!(c20.summary().classification, "monostable");
    assert_eq!(c20.summary().barrier, None);
    assert!(c20.rest_states().is_empty());
    let c285 = KreslingCell::new(params(28.5)).unwrap();
    let s = c285.summary();
    assert_eq!(s.classification, "bistable");
    // γ0 = 28.5°: both stable states are stress free (closed form), h = 0 is not stable.
    let rest = c285.rest_states();
    assert_eq!(rest.len(), 2);
    for (st, (h, _)) in s.stable.iter().zip(&rest) {
        assert!((st - h).abs() < 1e-8, "{st} vs {h}");
    }
    assert!(s.unstable.contains(&0.0));
}

#[test]
fn surrogate_matches_table_1() {
    let cell = KreslingCell::new(params(30.0)).unwrap();
    let s = Surrogate::fit(&cell, &SurrogateSpec::default()).unwrap();
    let table1 = [12.12, -18.03, 6.56];
    let design = [12.126, -18.033, 6.552];
    for k in 0..3 {
        assert!(
            ((s.coefs[k] - table1[k]) / table1[k]).abs() < 0.01,
            "coef {k}: {} vs Table 1 {}",
            s.coefs[k],
            table1[k]
        );
        assert!(((s.coefs[k] - design[k]) / design[k]).abs() < 0.003);
    }
    // The truss force is linear in k (k_a = k_b): doubling k doubles the coefficients.
    let cell2 = KreslingCell::new(KreslingParams {
        k_a: 18.6,
        k_b: 18.6,
        ..params(30.0)
    })
    .unwrap();
    let s2 = Surrogate::fit(&cell2, &SurrogateSpec::default()).unwrap();
    for k in 0..3 {
        assert!((s2.coefs[k] / s.coefs[k] - 2.0).abs() < 1e-9);
    }
    // Surrogate V is the antiderivative of its F.
    let h = 1.3;
    let e = 1e-5;
    let fd = (s.potential(h + e) - s.potential(h - e)) / (2.0 * e);
    assert!((fd - s.force(h)).abs() < 1e-8);
}

#[test]
fn table_matches_direct_solves_at_random_heights() {
    for g in [30.0, 28.5, 20.0] {
        let cell = KreslingCell::new(params(g)).unwrap();
        let scale = cell.force_scale();
        assert!(
            cell.table_error() < 1e-9 * scale,
            "γ0 = {g}: {}",
            cell.table_error()
        );
        let u_ref = {
            let (th0, _) = direct_force(&cell, 0.0);
            cell.energy(0.0, th0)
        };
        let mut state = 0x2545F4914F6CDD1Du64 ^ g.to_bits();
        for _ in 0..200 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let h = (state >> 11) as f64 / (1u64 << 53) as f64 * cell.h_max();
            let (th, f) = direct_force(&cell, h);
            assert!((cell.theta(h) - th).abs() < 1e-8, "θ at h = {h}");
            // Relative 1e-8 (FD of the energy is good to ~1e-10 here).
            assert!(
                (cell.force(h) - f).abs() < 1e-8 * (1.0 + f.abs()),
                "γ0 = {g}, h = {h}: {} vs {f}",
                cell.force(h)
            );
            let v = cell.energy(h, th) - u_ref;
            assert!(
                (cell.potential(h) - v).abs() < 1e-8 * (1.0 + v.abs()),
                "V at h = {h}"
            );
            // The crate's own direct solve agrees with the table to the table error.
            let bp = cell.branch_point(h).unwrap();
            assert!((bp.force - cell.force(h)).abs() <= 2.0 * cell.table_error() + 1e-13 * scale);
        }
    }
}

#[test]
fn force_is_the_derivative_of_the_potential() {
    let cell = KreslingCell::new(params(30.0)).unwrap();
    let e = 1e-5;
    for i in 0..400 {
        let h = -0.3 + 4.5 * i as f64 / 399.0; // includes the stop and beyond the table
        if h.abs() < 2.0 * e {
            continue;
        }
        let fd = (cell.potential(h + e) - cell.potential(h - e)) / (2.0 * e);
        let tol = 1e-6 * (1.0 + cell.force(h).abs());
        assert!(
            (fd - cell.force(h)).abs() < tol,
            "h = {h}: {fd} vs {}",
            cell.force(h)
        );
        let kd = (cell.force(h + e) - cell.force(h - e)) / (2.0 * e);
        assert!(
            (kd - cell.stiffness(h)).abs() < 1e-4 * (1.0 + cell.stiffness(h).abs()),
            "h = {h}"
        );
    }
}

#[test]
fn folded_stop_and_mirror_well() {
    let cell = KreslingCell::new(params(30.0)).unwrap();
    let s2 = cell.stable()[1];
    // The bare truss model is odd: a mirror well at −s2.
    assert!(cell.bare_force(-s2).abs() < 1e-9);
    assert!((cell.bare_force(-1.0) + cell.force(1.0)).abs() < 1e-15);
    // With the stop: strongly restoring for h < 0, no well there.
    assert!(cell.force(-s2) < -0.9 * cell.k_stop() * s2);
    assert!(cell.potential(-0.1) > 0.5 * cell.k_stop() * 0.01);
    let custom = KreslingCell::with_options(
        params(30.0),
        CellOptions {
            k_stop: Some(1234.0),
            ..CellOptions::default()
        },
    )
    .unwrap();
    assert_eq!(custom.k_stop(), 1234.0);
}

#[test]
fn bad_parameters_are_rejected_with_names() {
    let e = KreslingCell::new(KreslingParams {
        a0: -1.0,
        ..params(30.0)
    })
    .unwrap_err();
    assert!(e.to_string().contains("'a0'"));
    let e = KreslingCell::new(params(95.0)).unwrap_err();
    assert!(e.to_string().contains("gamma0_deg"));
    let e = KreslingCell::new(KreslingParams {
        a0: 3.0,
        ..params(30.0)
    })
    .unwrap_err();
    assert!(e.to_string().contains("a0·sin"));
    assert!(cell_curve_rejects_bad_range());
}

fn cell_curve_rejects_bad_range() -> bool {
    let cell = KreslingCell::new(params(30.0)).unwrap();
    let c = cell.curve(0.0, 1.7, 5).unwrap();
    assert_eq!(c.h.len(), 5);
    cell.curve(1.0, 0.0, 5).is_err()
}

mod prop {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]
        /// For any admissible γ0 and h, the tabulated F is dV/dh and agrees with a direct solve.
        #[test]
        fn force_is_dv_dh_and_matches_direct(g in 18.0f64..34.0, frac in 0.01f64..0.99) {
            let cell = KreslingCell::new(params(g)).unwrap();
            let h = frac * cell.h_max();
            let e = 1e-5;
            let fd = (cell.potential(h + e) - cell.potential(h - e)) / (2.0 * e);
            prop_assert!((fd - cell.force(h)).abs() < 1e-6 * (1.0 + cell.force(h).abs()));
            let (_, f) = direct_force(&cell, h);
            prop_assert!((cell.force(h) - f).abs() < 1e-8 * (1.0 + f.abs()));
        }
    }
}
