//! Integration tests: wells in closed form, an independent RK4 reference, determinism,
//! symmetry, chain ↔ S-DOF equivalence, MED on the boundary, and error paths.

use std::sync::atomic::{AtomicUsize, Ordering};

use rayon::prelude::*;
use tfs_basin::{
    BasinConfig, BasinError, BasinMap, ChainWells, Label, Method, Polynomial1Dof, Slice, WellInfo,
    basin_chain, basin_sdof, boa_error, classify_chain, classify_sdof, compare, dt_convergence,
    med_chain, med_sdof,
};
use tfs_dynamics::SecondOrderSystem;

fn table1() -> (Polynomial1Dof, WellInfo) {
    let m = Polynomial1Dof::table1_60db();
    let w = WellInfo::from_polynomial(&m, (-3.0, 3.0)).unwrap();
    (m, w)
}

fn grid(n: usize) -> BasinConfig {
    BasinConfig::new(n, n, (-1.0, 2.5), (-3.0, 3.0))
}

/// Duffing `x'' + c x' − x + x³ = 0` (double well at ±1, saddle at 0).
fn duffing(c: f64) -> Polynomial1Dof {
    Polynomial1Dof::new(c, vec![0.0, -1.0, 0.0, 1.0]).unwrap()
}

#[test]
fn table1_equilibria_match_closed_form() {
    let (m, w) = table1();
    // f = x^5 (12.12 − 18.03 x + 6.56 x²): roots 0 and (18.03 ± √(18.03² − 4·6.56·12.12)) / (2·6.56).
    let disc = (18.03f64 * 18.03 - 4.0 * 6.56 * 12.12).sqrt();
    let (u, s2) = ((18.03 - disc) / 13.12, (18.03 + disc) / 13.12);
    assert_eq!(w.stable().len(), 2);
    assert!(w.stable()[0].abs() < 1e-12);
    assert!((w.stable()[1] - s2).abs() < 1e-12);
    assert_eq!(w.unstable().len(), 1);
    assert!((w.unstable()[0] - u).abs() < 1e-12);
    let v = |x: f64| 12.12 / 6.0 * x.powi(6) - 18.03 / 7.0 * x.powi(7) + 6.56 / 8.0 * x.powi(8);
    assert!((w.potential(u) - v(u)).abs() < 1e-12);
    assert!((w.quasi_static_barrier(0, 1).unwrap() - v(u)).abs() < 1e-12);
    assert!((m.force(1.3) - 1.3f64.powi(5) * (12.12 - 18.03 * 1.3 + 6.56 * 1.69)).abs() < 1e-12);
    // The S1 well is bounded by the search end on the left and u on the right.
    assert_eq!(w.wells()[0].hi, w.unstable()[0]);
    assert!(w.wells()[0].barrier < v(u) && w.wells()[0].barrier > v(u) - 1e-6);
}

/// A wall at an end of the search range moves out while the potential rises: the double well's
/// −1 searched on [−1, 3] gets the saddle's height as its barrier (V = 0 is reached at −√2), not
/// V just past −1, barely above the bottom; so a start at −1 with v = 0.6 (E = −0.07) is trapped.
#[test]
fn a_well_at_a_search_end_gets_the_saddle_as_its_barrier() {
    let w = WellInfo::from_polynomial(&duffing(0.4), (-1.0, 3.0)).unwrap();
    assert_eq!(w.stable().len(), 2);
    let left = w.wells()[0];
    assert_eq!(left.hi, 0.0);
    assert!((left.lo + 2f64.sqrt()).abs() < 1e-3, "{left:?}");
    assert!(left.barrier < 0.0 && left.barrier > -1e-6, "{left:?}");
    assert_eq!(w.trapped(-1.0, 0.6), Some(0));
    // Energy above the saddle is not trapped.
    assert_eq!(w.trapped(-1.0, 0.8), None);
}

/// The walk out of the search range stops before an equilibrium it finds there: wells at 0 and
/// ±2, saddles at ±1 (f = x⁵ − 5x³ + 4x) searched on [−0.5, 3]: the 0-well's left wall ends just
/// inside −1, the saddle beyond the range, and its barrier stays below V(±1).
#[test]
fn a_wall_moved_out_stops_at_an_equilibrium_beyond_the_range() {
    let m = Polynomial1Dof::new(0.4, vec![0.0, 4.0, 0.0, -5.0, 0.0, 1.0]).unwrap();
    let w = WellInfo::from_polynomial(&m, (-0.5, 3.0)).unwrap();
    assert_eq!(w.stable().len(), 2);
    assert_eq!(w.unstable().len(), 1);
    let v1 = w.potential(1.0);
    let zero = w.wells()[0];
    assert!(zero.lo > -1.0 && zero.lo < -1.0 + 1e-3, "{zero:?}");
    assert!(zero.barrier < v1 && zero.barrier > v1 - 1e-4, "{zero:?}");
    // Beyond x = −1 the start would fall into the −2 well, so it must not be trapped at 0.
    assert_eq!(w.trapped(-1.05, 0.0), None);
}

/// A root where the force touches zero without changing sign is an inflection of the potential,
/// not a wall. `f = x²(x + 0.5)(x − 1)(x − 2)` on [−1, 3]: wells at −0.5 and 2, a maximum at 1,
/// and at 0 (a scan point) `f ≈ x²` keeps its sign. A start at (0.5, 0) slides down and creeps
/// towards 0; its energy is below V(1), so it can never leave the −0.5 well. With 0 taken as a
/// wall it sat in no well and stayed "unsettled" (as a stop just below the fold of a Kresling
/// cell model whose lowest power is x^4 did, which put 68 % of a correct map in error).
#[test]
fn a_touching_root_is_inside_a_well_not_a_wall() {
    let m = Polynomial1Dof::new(1.0, vec![0.0, 0.0, 1.0, 0.5, -2.5, 1.0]).unwrap();
    let eq = tfs_dynamics::equilibria(|x| m.force(x), -1.0, 3.0, 20_000).unwrap();
    assert!(
        eq.iter().any(|e| e.x == 0.0 && !e.stable),
        "the scan finds the touching root: {eq:?}"
    );
    let w = WellInfo::from_polynomial(&m, (-1.0, 3.0)).unwrap();
    assert_eq!(w.stable().len(), 2);
    assert!((w.stable()[0] + 0.5).abs() < 1e-12 && (w.stable()[1] - 2.0).abs() < 1e-12);
    assert_eq!(w.unstable().len(), 1, "{:?}", w.unstable());
    assert!((w.unstable()[0] - 1.0).abs() < 1e-12);
    assert_eq!(w.wells()[0].hi, w.unstable()[0]);
    assert_eq!(w.well_of(0.5), Some(0));
    // 20 points each way: no start sits on the maximum at (1, 0), which stays there.
    let cfg = BasinConfig::new(20, 20, (-1.0, 1.5), (-1.0, 1.0));
    assert_eq!(classify_sdof(&m, &w, 0.5, 0.0, &cfg), Label::State(0));
    let map = basin_sdof(&m, &w, &cfg, None).unwrap();
    assert_eq!(map.unsettled_count, 0);
}

/// Independent reference: a plain scalar RK4 loop (written here, not the library's), run to a
/// long horizon; label by the side of the saddle, and require energy below the barrier.
fn reference_label(x0: f64, v0: f64, dt: f64, t: f64, u: f64, barrier: f64) -> Label {
    let f = |x: f64| x.powi(5) * (12.12 - 18.03 * x + 6.56 * x * x);
    let acc = |x: f64, v: f64| -1.99 * v - f(x);
    let (mut x, mut v) = (x0, v0);
    for _ in 0..(t / dt).round() as usize {
        let (k1x, k1v) = (v, acc(x, v));
        let (k2x, k2v) = (
            v + 0.5 * dt * k1v,
            acc(x + 0.5 * dt * k1x, v + 0.5 * dt * k1v),
        );
        let (k3x, k3v) = (
            v + 0.5 * dt * k2v,
            acc(x + 0.5 * dt * k2x, v + 0.5 * dt * k2v),
        );
        let (k4x, k4v) = (v + dt * k3v, acc(x + dt * k3x, v + dt * k3v));
        x += dt / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x);
        v += dt / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v);
    }
    let e =
        0.5 * v * v + 12.12 / 6.0 * x.powi(6) - 18.03 / 7.0 * x.powi(7) + 6.56 / 8.0 * x.powi(8);
    if e >= barrier {
        Label::Unsettled
    } else if x < u {
        Label::State(0)
    } else {
        Label::State(1)
    }
}

fn agreement_with_reference(n: usize) {
    let (m, w) = table1();
    let cfg = grid(n);
    let map = basin_sdof(&m, &w, &cfg, None).unwrap();
    assert_eq!(map.unsettled_count, 0);
    let u = w.unstable()[0];
    let barrier = w.potential(u);
    let reference: Vec<Label> = (0..n * n)
        .into_par_iter()
        .map(|k| reference_label(cfg.x_at(k % n), cfg.v_at(k / n), 0.005, 40.0, u, barrier))
        .collect();
    let agree = map
        .labels
        .iter()
        .zip(&reference)
        .filter(|(a, b)| a == b)
        .count();
    let share = agree as f64 / (n * n) as f64;
    assert!(share >= 0.999, "agreement {share}");
    // Both basins are present in sizeable shares.
    assert!(map.shares.iter().all(|&s| s > 0.05), "{:?}", map.shares);
}

/// 200×200 in the default suite (a few seconds in the optimised test profile).
#[test]
fn early_exit_map_agrees_with_independent_long_rk4_200() {
    agreement_with_reference(200);
}

/// The full 400×400 check; run with `cargo test -p tfs-basin -- --ignored`.
#[test]
#[ignore]
fn early_exit_map_agrees_with_independent_long_rk4_400() {
    agreement_with_reference(400);
}

#[test]
fn thread_count_does_not_change_the_map() {
    let (m, w) = table1();
    let cfg = grid(120);
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| basin_sdof(&m, &w, &cfg, None).unwrap())
    };
    let (one, two) = (run(1), run(2));
    assert_eq!(one.labels, two.labels);
    let mut seq = cfg.clone();
    seq.parallel = false;
    assert_eq!(basin_sdof(&m, &w, &seq, None).unwrap().labels, one.labels);
}

#[test]
fn early_exit_and_full_horizon_give_the_same_labels() {
    let (m, w) = table1();
    let cfg = grid(100);
    let mut full = cfg.clone();
    full.early_exit = false;
    full.t_max = 60.0;
    let a = basin_sdof(&m, &w, &cfg, None).unwrap();
    let b = basin_sdof(&m, &w, &full, None).unwrap();
    assert_eq!(b.unsettled_count, 0);
    assert_eq!(boa_error(&a, &b).unwrap(), 0.0);
}

#[test]
fn single_start_classification_matches_the_batched_grid() {
    let (m, w) = table1();
    let cfg = grid(37);
    let map = basin_sdof(&m, &w, &cfg, None).unwrap();
    for j in (0..37).step_by(3) {
        for i in 0..37 {
            assert_eq!(
                classify_sdof(&m, &w, cfg.x_at(i), cfg.v_at(j), &cfg),
                map.label(i, j)
            );
        }
    }
}

#[test]
fn step_halving_changes_almost_nothing() {
    let (m, w) = table1();
    let mut cfg = grid(100);
    cfg.dt = 0.02;
    let err = dt_convergence(&m, &w, &cfg).unwrap();
    assert!(err < 2e-3, "dt convergence error {err}");
}

#[test]
fn odd_symmetric_duffing_gives_point_symmetric_basins() {
    let sys = duffing(0.3);
    let w = WellInfo::from_polynomial(&sys, (-3.0, 3.0)).unwrap();
    assert_eq!(w.stable(), &[-1.0, 1.0]);
    let n = 61;
    let cfg = BasinConfig::new(n, n, (-2.0, 2.0), (-2.0, 2.0));
    let map = basin_sdof(&sys, &w, &cfg, None).unwrap();
    let flip = |l: Label| match l {
        Label::State(k) => Label::State(1 - k),
        other => other,
    };
    for j in 0..n {
        for i in 0..n {
            assert_eq!(map.label(i, j), flip(map.label(n - 1 - i, n - 1 - j)));
        }
    }
    assert!((map.shares[0] - map.shares[1]).abs() < 1e-12);
}

#[test]
fn monostable_system_has_one_basin() {
    let sys = Polynomial1Dof::new(0.5, vec![0.0, 2.0, 0.0, 1.0]).unwrap();
    let w = WellInfo::from_polynomial(&sys, (-4.0, 4.0)).unwrap();
    assert_eq!(w.stable().len(), 1);
    let map = basin_sdof(
        &sys,
        &w,
        &BasinConfig::new(20, 20, (-2.0, 2.0), (-2.0, 2.0)),
        None,
    )
    .unwrap();
    assert!(map.labels.iter().all(|&l| l == Label::State(0)));
    assert_eq!(map.shares, vec![1.0]);
}

#[test]
fn boa_error_counts_flipped_cells() {
    let (m, w) = table1();
    let a = basin_sdof(&m, &w, &grid(30), None).unwrap();
    assert_eq!(boa_error(&a, &a).unwrap(), 0.0);
    let mut b: BasinMap = a.clone();
    for k in [0usize, 7, 100, 899] {
        b.labels[k] = match b.labels[k] {
            Label::State(0) => Label::State(1),
            _ => Label::Unsettled,
        };
    }
    let c = compare(&a, &b).unwrap();
    assert!((c.error - 4.0 / 900.0).abs() < 1e-15);
    assert_eq!(c.disagree.iter().filter(|&&d| d).count(), 4);
    assert!(c.disagree[7] && !c.disagree[8]);
    let other = basin_sdof(&m, &w, &grid(31), None).unwrap();
    assert!(matches!(
        boa_error(&a, &other),
        Err(BasinError::MapMismatch { .. })
    ));
}

fn check_med_on_boundary(x_range: (f64, f64), v_range: (f64, f64)) {
    let (m, w) = table1();
    let cfg = BasinConfig::new(150, 150, x_range, v_range);
    let map = basin_sdof(&m, &w, &cfg, None).unwrap();
    let med = med_sdof(&m, &w, &map, &cfg, 0, 1).unwrap();
    assert!(med.energy.is_finite() && med.energy > 0.0);
    assert!((med.energy - (med.kinetic + med.potential)).abs() < 1e-12);
    // Energy never increases, so crossing the saddle needs at least the quasi-static barrier.
    assert!(
        med.energy >= med.quasi_static_barrier * (1.0 - 1e-6),
        "{med:?}"
    );
    // On the boundary: the MED start ends in S2; a start slightly closer to S1 on the same ray ends in S1.
    let s1 = w.stable()[0];
    assert_eq!(classify_sdof(&m, &w, med.x0, med.v0, &cfg), Label::State(1));
    let k = 1.0 - 1e-6;
    let inside = classify_sdof(&m, &w, s1 + k * (med.x0 - s1), k * med.v0, &cfg);
    assert_eq!(inside, Label::State(0), "{med:?}");
    // Nothing on the grid (inside S1's well) reaches S2 with less energy.
    for j in 0..cfg.ny {
        for i in 0..cfg.nx {
            let (x, v) = (cfg.x_at(i), cfg.v_at(j));
            if map.label(i, j) == Label::State(1) && w.well_of(x) == Some(0) {
                assert!(w.energy(x, v) - w.potential(s1) >= med.energy - 1e-9);
            }
        }
    }
}

#[test]
fn med_lies_on_the_basin_boundary_when_the_grid_reaches_the_saddle() {
    check_med_on_boundary((-1.0, 2.5), (-3.0, 3.0));
}

#[test]
fn med_lies_on_the_basin_boundary_when_the_grid_stops_short_of_the_saddle() {
    check_med_on_boundary((-1.0, 1.0), (-3.0, 3.0));
}

/// Two uncoupled Duffing cells as a 2-DOF "chain".
struct TwoDuffing(f64);
impl SecondOrderSystem for TwoDuffing {
    fn dofs(&self) -> usize {
        2
    }
    fn accel(&self, _t: f64, x: &[f64], v: &[f64], _u: &[f64], a: &mut [f64]) {
        for i in 0..2 {
            a[i] = -self.0 * v[i] + x[i] - x[i] * x[i] * x[i];
        }
    }
}

fn two_duffing_wells() -> ChainWells {
    let pot = |x: &[f64]| {
        x.iter()
            .map(|&y| 0.25 * y.powi(4) - 0.5 * y * y)
            .sum::<f64>()
    };
    let saddles = vec![
        vec![0.0, 1.0],
        vec![0.0, -1.0],
        vec![1.0, 0.0],
        vec![-1.0, 0.0],
    ];
    let barrier = ChainWells::barrier_from_saddles(pot, &saddles).unwrap();
    assert!((barrier + 0.25).abs() < 1e-15);
    let stable = vec![
        vec![-1.0, -1.0],
        vec![1.0, 1.0],
        vec![-1.0, 1.0],
        vec![1.0, -1.0],
    ];
    ChainWells::new(stable, vec![1.0, 1.0], pot, Some(barrier)).unwrap()
}

#[test]
fn chain_on_paper_slice_matches_single_cell() {
    // On the paper's slice both cells move identically, so each start must end where the
    // single Duffing cell from (−1 + Δx, v0) ends.
    let c = 0.4;
    let sys = TwoDuffing(c);
    let wells = two_duffing_wells();
    let slice = Slice::paper(&[-1.0, -1.0]);
    let cfg = BasinConfig::new(41, 41, (-0.5, 3.0), (-2.0, 2.0));
    let map = basin_chain(&sys, &wells, &slice, &cfg, None).unwrap();
    let single = duffing(c);
    let w1 = WellInfo::from_polynomial(&single, (-3.0, 3.0)).unwrap();
    let cfg1 = BasinConfig::new(41, 41, (-1.5, 2.0), (-2.0, 2.0));
    let map1 = basin_sdof(&single, &w1, &cfg1, None).unwrap();
    assert_eq!(map.labels, map1.labels);
    assert!(map.shares[0] > 0.1 && map.shares[1] > 0.1);
    assert_eq!(map.shares[2] + map.shares[3], 0.0);
    // Same starts through the single-start entry point.
    let (x, v) = slice.state(cfg.x_at(5), cfg.v_at(30));
    assert_eq!(classify_chain(&sys, &wells, &x, &v, &cfg), map.label(5, 30));
    // MED on the slice is twice the single cell's (two identical cells). The symmetric motion
    // must pass (0, 0), so E_in ≥ 2 · ¼; the single cell (restricted to x0 inside S1's well)
    // approaches its barrier ¼ from above.
    let med = med_chain(&sys, &wells, &slice, &map, &cfg, 0, 1).unwrap();
    let med1 = med_sdof(&single, &w1, &map1, &cfg1, 0, 1).unwrap();
    assert!(med.energy >= 0.5 * (1.0 - 1e-9), "{med:?}");
    assert!(
        med.energy <= 2.0 * med1.energy * (1.0 + 1e-9),
        "{med:?} vs {med1:?}"
    );
    assert!(
        (med.energy - 2.0 * med1.energy).abs() < 1e-3 * med.energy,
        "{med:?} vs {med1:?}"
    );
    assert!((med.c0 - (med1.x0 + 1.0)).abs() < 0.05 && (med.c1 - med1.v0).abs() < 0.05);
    assert_eq!(
        classify_chain(&sys, &wells, &med.x, &med.v, &cfg),
        Label::State(1)
    );
    assert!((med.quasi_static_barrier.unwrap() - 0.25).abs() < 1e-12);
}

#[test]
fn chain_threads_and_early_exit_do_not_change_the_map() {
    let sys = TwoDuffing(0.5);
    let wells = two_duffing_wells();
    // A general slice: x1 along axis 0, v2 along axis 1.
    let mut slice = Slice::paper(&[-1.0, -1.0]);
    slice.axes[0].dx = vec![1.0, 0.0];
    slice.axes[1].dv = vec![0.0, 1.0];
    let cfg = BasinConfig::new(30, 30, (-1.0, 3.0), (-2.5, 2.5));
    let run = |threads: usize, cfg: &BasinConfig| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| basin_chain(&sys, &wells, &slice, cfg, None).unwrap())
    };
    let a = run(1, &cfg);
    let b = run(2, &cfg);
    assert_eq!(a.labels, b.labels);
    let mut full = cfg.clone();
    full.early_exit = false;
    full.t_max = 80.0;
    let c = run(2, &full);
    assert_eq!(c.unsettled_count, 0);
    assert_eq!(a.labels, c.labels);
    // Uncoupled cells: each cell ends where a lone Duffing cell from its own start ends.
    let single = duffing(0.5);
    let w1 = WellInfo::from_polynomial(&single, (-3.0, 3.0)).unwrap();
    let states = wells.stable();
    for j in 0..cfg.ny {
        for i in 0..cfg.nx {
            let (x, v) = slice.state(cfg.x_at(i), cfg.v_at(j));
            let end = |k: usize| match classify_sdof(&single, &w1, x[k], v[k], &cfg) {
                Label::State(s) => w1.stable()[s],
                other => panic!("single cell {other:?}"),
            };
            let target = [end(0), end(1)];
            let expect = states.iter().position(|s| s[..] == target[..]).unwrap();
            assert_eq!(a.label(i, j), Label::State(expect), "cell ({i}, {j})");
        }
    }
    assert!(
        a.shares.iter().filter(|&&s| s > 0.0).count() >= 3,
        "{:?}",
        a.shares
    );
}

#[test]
fn progress_counts_cells_up_to_the_whole_grid() {
    let (m, w) = table1();
    for method in [Method::Refined, Method::EveryCell, Method::Scalar] {
        let calls = AtomicUsize::new(0);
        let last = AtomicUsize::new(0);
        let cb = |done: usize| {
            calls.fetch_add(1, Ordering::Relaxed);
            last.fetch_max(done, Ordering::Relaxed);
        };
        let mut cfg = BasinConfig::new(40, 53, (-1.0, 2.0), (-1.0, 1.0));
        cfg.method = method;
        basin_sdof(&m, &w, &cfg, Some(&cb)).unwrap();
        assert!(calls.load(Ordering::Relaxed) >= 2, "{method:?}");
        assert_eq!(last.load(Ordering::Relaxed), 40 * 53, "{method:?}");
    }
}

#[test]
fn bad_inputs_are_reported_not_panicked() {
    let (m, w) = table1();
    let mut cfg = grid(10);
    cfg.dt = 0.0;
    let e = basin_sdof(&m, &w, &cfg, None).unwrap_err();
    assert!(e.to_string().contains("dt"), "{e}");
    let mut cfg = grid(10);
    cfg.x_range = (1.0, 1.0);
    assert!(
        basin_sdof(&m, &w, &cfg, None)
            .unwrap_err()
            .to_string()
            .contains("x_range")
    );
    // Negative damping: energy grows, the early-exit proof is refused.
    let anti = Polynomial1Dof::new(-0.5, m.coeffs().to_vec()).unwrap();
    assert!(matches!(
        basin_sdof(&anti, &w, &grid(10), None),
        Err(BasinError::NotDissipative { .. })
    ));
    // A potential that is not the force's antiderivative.
    let e = WellInfo::from_force(|x| x, |x| x * x, (-1.0, 1.0), 1.0).unwrap_err();
    assert!(e.to_string().contains("potential"), "{e}");
    // No stable equilibrium.
    assert!(matches!(
        WellInfo::from_force(|x| -x, |x| -0.5 * x * x, (-1.0, 1.0), 1.0),
        Err(BasinError::NoStableEquilibrium { .. })
    ));
    let map = basin_sdof(&m, &w, &grid(20), None).unwrap();
    assert!(med_sdof(&m, &w, &map, &grid(20), 0, 5).is_err());
    assert!(Polynomial1Dof::new(1.0, vec![f64::NAN]).is_err());
}

/// A step beyond RK4's stability on the states the grid reaches is refused by name (it used to
/// label most starts diverged), on the model's own fastest rate: the double well reaches
/// |x| ≈ 2.3 from (2, 3), where the stiffness 3x² − 1 ≈ 15 gives a rate near 3.9 /s.
#[test]
fn unstable_step_is_refused_with_the_rate() {
    let sys = duffing(0.4);
    let w = WellInfo::from_polynomial(&sys, (-3.0, 3.0)).unwrap();
    let mut cfg = BasinConfig::new(20, 20, (0.0, 2.0), (-3.0, 3.0));
    let limit = tfs_basin::step_limit_sdof(&sys, &w, &cfg).unwrap();
    // Energy at (2, 3) is 6.5 = x⁴/4 − x²/2 at x ≈ 2.28: stiffness 3x² − 1 ≈ 14.6.
    let x_top = (1.0f64 + (1.0 + 4.0 * 6.5f64).sqrt()).sqrt();
    let expect = (3.0 * x_top * x_top - 1.0).sqrt();
    assert!(
        (limit.rate - expect).abs() < 0.05 * expect,
        "{limit:?} vs {expect}"
    );
    cfg.dt = 100.0;
    let e = basin_sdof(&sys, &w, &cfg, None).unwrap_err();
    assert!(matches!(e, BasinError::StepTooLong { .. }), "{e}");
    let text = e.to_string();
    assert!(
        text.contains("dt = 100") && text.contains("stable only for dt below"),
        "{text}"
    );
    // Just inside the limit the map runs; the default step is far inside it.
    cfg.dt = 0.9 * limit.max_dt();
    assert!(basin_sdof(&sys, &w, &cfg, None).is_ok());
    assert!(limit.max_dt() > 20.0 * 0.01);
}

/// Work a user cannot wait for is refused before it starts, naming the setting.
#[test]
fn absurd_step_counts_and_grids_are_refused() {
    let (m, w) = table1();
    let mut cfg = grid(200);
    cfg.dt = 1e-9;
    let e = basin_sdof(&m, &w, &cfg, None).unwrap_err().to_string();
    assert!(e.contains("`dt`") && e.contains("steps"), "{e}");
    let mut cfg = grid(10);
    cfg.nx = 100_000;
    cfg.ny = 100_000;
    let e = basin_sdof(&m, &w, &cfg, None).unwrap_err().to_string();
    assert!(e.contains("nx/ny"), "{e}");
}

/// An equilibrium exactly at an end of the search range is classified (the double well's
/// −1 on [−1, 3], the CLI's default range for `--x 0:2`), so starts going there settle.
#[test]
fn equilibrium_at_the_search_end_is_a_well() {
    let sys = duffing(0.4);
    let w = WellInfo::from_polynomial(&sys, (-1.0, 3.0)).unwrap();
    assert_eq!(w.stable(), &[-1.0, 1.0]);
    let map = basin_sdof(
        &sys,
        &w,
        &BasinConfig::new(30, 30, (0.0, 2.0), (-3.0, 3.0)),
        None,
    )
    .unwrap();
    assert_eq!(map.unsettled_count, 0);
    assert!(
        map.shares[0] > 0.3 && map.shares[1] > 0.3,
        "{:?}",
        map.shares
    );
}
