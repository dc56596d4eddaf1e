//! The coarse-to-fine maps against a fine fixed-step reference (every start integrated with half
//! the step, no early exit): at least 99.5 % of the cells agree, and every cell more than two
//! cells away from a basin boundary of the reference agrees. Several 1-DOF models (the paper's
//! Table 1, double wells from lightly to more damped, an asymmetric well pair, a tristable
//! quintic) and two chains on slices. Grids of 160 nodes a side, so the refinement starts from
//! its coarsest lattice (every 8th node), as on a full-size map.

use rayon::prelude::*;
use tfs_basin::{
    BasinConfig, BasinMap, ChainWells, Label, Method, Polynomial1Dof, Slice, WellInfo, basin_chain,
    basin_sdof,
};
use tfs_dynamics::SecondOrderSystem;

const N: usize = 160;

/// Share of agreeing cells, and the number of cells more than two cells from a boundary of
/// the reference (their 5 × 5 neighbourhood has one label) with how many of them disagree.
fn agreement(reference: &BasinMap, map: &BasinMap) -> (f64, usize, usize) {
    let (nx, ny) = (reference.nx, reference.ny);
    let (mut same, mut far, mut far_wrong) = (0, 0, 0);
    for j in 0..ny {
        for i in 0..nx {
            let l = reference.label(i, j);
            let ok = l == map.label(i, j);
            same += usize::from(ok);
            let interior = (j.saturating_sub(2)..=(j + 2).min(ny - 1)).all(|b| {
                (i.saturating_sub(2)..=(i + 2).min(nx - 1)).all(|a| reference.label(a, b) == l)
            });
            if interior {
                far += 1;
                far_wrong += usize::from(!ok);
            }
        }
    }
    (same as f64 / (nx * ny) as f64, far, far_wrong)
}

fn reference_cfg(cfg: &BasinConfig, t_max: f64) -> BasinConfig {
    let mut r = cfg.clone();
    r.method = Method::EveryCell;
    r.dt = cfg.dt / 2.0;
    r.early_exit = false;
    r.t_max = t_max;
    r
}

fn check(name: &str, reference: &BasinMap, map: &BasinMap) {
    assert_eq!(reference.unsettled_count, 0, "{name}: reference unsettled");
    let (share, far, far_wrong) = agreement(reference, map);
    assert!(share >= 0.995, "{name}: agreement {share}");
    assert_eq!(
        far_wrong, 0,
        "{name}: {far_wrong} of {far} interior cells differ"
    );
    // The refinement must have saved work, and the map must hold more than one basin.
    assert!(
        map.integrated < N * N,
        "{name}: {} integrated",
        map.integrated
    );
    assert!(
        map.shares.iter().filter(|&&s| s > 0.02).count() >= 2,
        "{name}: {:?}",
        map.shares
    );
}

fn sdof_case(
    name: &str,
    model: Polynomial1Dof,
    x: (f64, f64),
    v: (f64, f64),
    search: (f64, f64),
    t_ref: f64,
) {
    let wells = WellInfo::from_polynomial(&model, search).unwrap();
    let cfg = BasinConfig::new(N, N, x, v);
    let map = basin_sdof(&model, &wells, &cfg, None).unwrap();
    let reference = basin_sdof(&model, &wells, &reference_cfg(&cfg, t_ref), None).unwrap();
    check(name, &reference, &map);
}

/// `k (x − a)(x − b)(x − c)` as power coefficients.
fn cubic(k: f64, a: f64, b: f64, c: f64) -> Vec<f64> {
    vec![
        -k * a * b * c,
        k * (a * b + b * c + a * c),
        -k * (a + b + c),
        k,
    ]
}

#[test]
fn table1_cell() {
    sdof_case(
        "table 1",
        Polynomial1Dof::table1_60db(),
        (0.0, 2.0),
        (-3.0, 3.0),
        (-1.0, 3.0),
        40.0,
    );
}

#[test]
fn double_wells() {
    for (c, x, v, t_ref) in [
        (0.4, (0.0, 2.0), (-3.0, 3.0), 60.0),
        (0.25, (-2.0, 2.0), (-2.5, 2.5), 80.0),
        (0.8, (-2.5, 2.5), (-4.0, 4.0), 40.0),
    ] {
        let model = Polynomial1Dof::new(c, cubic(1.0, -1.0, 0.0, 1.0)).unwrap();
        sdof_case(
            &format!("double well c = {c}"),
            model,
            x,
            v,
            (-3.0, 3.0),
            t_ref,
        );
    }
}

#[test]
fn asymmetric_and_tristable_wells() {
    let asym = Polynomial1Dof::new(0.3, cubic(2.0, -0.8, 0.3, 1.5)).unwrap();
    sdof_case(
        "asymmetric",
        asym,
        (-1.5, 2.5),
        (-3.0, 3.0),
        (-3.0, 4.0),
        60.0,
    );
    // x (x² − 1)(x² − 4): stable at −2, 0, 2.
    let tri = Polynomial1Dof::new(0.35, vec![0.0, 4.0, 0.0, -5.0, 0.0, 1.0]).unwrap();
    sdof_case(
        "tristable",
        tri,
        (-3.0, 3.0),
        (-5.0, 5.0),
        (-4.0, 4.0),
        60.0,
    );
}

/// A serial two-mass chain: cell 1 (ground to mass 1) monostable `k1 x + k3 x³`, cell 2 (mass 1
/// to mass 2) a double well in the relative displacement, viscous damping in both cells.
struct Chain {
    c: f64,
}

fn f1(x: f64) -> f64 {
    x + 0.5 * x * x * x
}
fn f2(r: f64) -> f64 {
    -r + r * r * r
}

impl SecondOrderSystem for Chain {
    fn dofs(&self) -> usize {
        2
    }
    fn accel(&self, _t: f64, x: &[f64], v: &[f64], _u: &[f64], a: &mut [f64]) {
        let (r, rv) = (x[1] - x[0], v[1] - v[0]);
        let cell2 = f2(r) + self.c * rv;
        a[0] = -f1(x[0]) - self.c * v[0] + cell2;
        a[1] = -cell2;
    }
}

fn chain_wells() -> ChainWells {
    let pot = |x: &[f64]| {
        let r = x[1] - x[0];
        0.5 * x[0] * x[0] + 0.125 * x[0].powi(4) - 0.5 * r * r + 0.25 * r.powi(4)
    };
    // Equilibria: f1(x1) = f2(r) = 0, so x1 = 0 and r ∈ {−1, 0, 1}; r = 0 is the saddle.
    let barrier = ChainWells::barrier_from_saddles(pot, &[vec![0.0, 0.0]]).unwrap();
    ChainWells::new(
        vec![vec![0.0, -1.0], vec![0.0, 1.0]],
        vec![1.0, 1.0],
        pot,
        Some(barrier),
    )
    .unwrap()
}

#[test]
fn chains_on_slices() {
    let wells = chain_wells();
    for (c, slice, x, v) in [
        // The paper's slice from S1: both masses shifted by Δx, both moving at v0.
        (0.3, Slice::paper(&[0.0, -1.0]), (-1.0, 3.0), (-3.0, 3.0)),
        // A general slice: mass 2 displaced, mass 1 given a velocity.
        (0.5, general_slice(), (-0.5, 3.5), (-3.0, 3.0)),
    ] {
        let sys = Chain { c };
        let cfg = BasinConfig::new(N, N, x, v);
        let map = basin_chain(&sys, &wells, &slice, &cfg, None).unwrap();
        let reference =
            basin_chain(&sys, &wells, &slice, &reference_cfg(&cfg, 60.0), None).unwrap();
        check(&format!("chain c = {c}"), &reference, &map);
    }
}

/// The same chain as a compiled model file, with a stiff one-sided stop on cell 1
/// (`200·below(x1, −0.6)`: contact when mass 1 is pushed 0.6 below its rest position), so the
/// dynamics have a kink the slice's corners reach.
#[test]
fn chain_with_a_stop_compiled_from_a_model() {
    let model = tfs_library::Model::from_json_str(
        r#"{"format":"tfs-model/1","dofs":["x1","x2"],"equations":[
        {"dof":"x1","terms":[{"term":"x1","coef":-1.0},{"term":"x1^3","coef":-0.5},
            {"term":"x1'","coef":-0.3},{"term":"(x2-x1)","coef":-1.0},
            {"term":"(x2-x1)^3","coef":1.0},{"term":"(x2-x1)'","coef":0.3},
            {"term":"below(x1, -0.6)","coef":200.0}]},
        {"dof":"x2","terms":[{"term":"(x2-x1)","coef":1.0},{"term":"(x2-x1)^3","coef":-1.0},
            {"term":"(x2-x1)'","coef":-0.3}]}]}"#,
    )
    .unwrap();
    let sys = model.compile().unwrap();
    let pot = |x: &[f64]| {
        let r = x[1] - x[0];
        let pen = (-0.6 - x[0]).max(0.0);
        0.5 * x[0] * x[0] + 0.125 * x[0].powi(4) - 0.5 * r * r
            + 0.25 * r.powi(4)
            + 100.0 * pen * pen
    };
    let barrier = ChainWells::barrier_from_saddles(pot, &[vec![0.0, 0.0]]).unwrap();
    let wells = ChainWells::new(
        vec![vec![0.0, -1.0], vec![0.0, 1.0]],
        vec![1.0, 1.0],
        pot,
        Some(barrier),
    )
    .unwrap();
    let slice = Slice::paper(&[0.0, -1.0]);
    let cfg = BasinConfig::new(N, N, (-1.2, 2.5), (-3.0, 3.0));
    let map = basin_chain(&sys, &wells, &slice, &cfg, None).unwrap();
    let reference = basin_chain(&sys, &wells, &slice, &reference_cfg(&cfg, 60.0), None).unwrap();
    check("chain with a stop", &reference, &map);
}

fn general_slice() -> Slice {
    let mut s = Slice::paper(&[0.0, -1.0]);
    s.axes[0].dx = vec![0.0, 1.0];
    s.axes[1].dv = vec![1.0, 0.0];
    s
}

/// Refined, every-cell and scalar maps on 1 and 3 threads: the same labels, and the two
/// every-start methods the same as each other everywhere (same arithmetic per start).
#[test]
fn thread_count_and_method_do_not_change_integrated_labels() {
    let model = Polynomial1Dof::new(0.3, cubic(1.0, -1.0, 0.0, 1.0)).unwrap();
    let wells = WellInfo::from_polynomial(&model, (-3.0, 3.0)).unwrap();
    let mut cfg = BasinConfig::new(97, 89, (-2.0, 2.0), (-2.0, 2.0));
    let on = |threads: usize, cfg: &BasinConfig| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| basin_sdof(&model, &wells, cfg, None).unwrap())
    };
    let refined = [on(1, &cfg), on(3, &cfg)];
    assert_eq!(refined[0].labels, refined[1].labels);
    assert_eq!(refined[0].integrated, refined[1].integrated);
    cfg.method = Method::EveryCell;
    let every = [on(1, &cfg), on(3, &cfg)];
    assert_eq!(every[0].labels, every[1].labels);
    cfg.method = Method::Scalar;
    let scalar = on(2, &cfg);
    assert_eq!(scalar.labels, every[0].labels);
    // The refined map differs from the every-start map at most where it filled a cell.
    assert!(refined[0].integrated < 97 * 89);
    let (share, _, far_wrong) = agreement(&every[0], &refined[0]);
    assert!(share > 0.995 && far_wrong == 0, "{share} {far_wrong}");
    // A chain too.
    let wells = chain_wells();
    let sys = Chain { c: 0.4 };
    let slice = general_slice();
    let ccfg = BasinConfig::new(70, 66, (-0.5, 3.5), (-3.0, 3.0));
    let chain_on = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| basin_chain(&sys, &wells, &slice, &ccfg, None).unwrap())
    };
    assert_eq!(chain_on(1).labels, chain_on(3).labels);
}

/// A start integrated in a SIMD block gets the label the lone-start classifier (a scalar
/// trajectory) gives it, on every start of grids of several models.
#[test]
fn lone_starts_match_the_blocks() {
    let models = [
        Polynomial1Dof::table1_60db(),
        Polynomial1Dof::new(0.2, cubic(1.0, -1.0, 0.0, 1.0)).unwrap(),
        Polynomial1Dof::new(0.35, vec![0.0, 4.0, 0.0, -5.0, 0.0, 1.0]).unwrap(),
    ];
    for model in &models {
        let wells = WellInfo::from_polynomial(model, (-3.0, 3.0)).unwrap();
        let mut cfg = BasinConfig::new(23, 19, (-2.0, 2.0), (-3.0, 3.0));
        cfg.method = Method::EveryCell;
        let map = basin_sdof(model, &wells, &cfg, None).unwrap();
        let lone: Vec<Label> = (0..cfg.nx * cfg.ny)
            .into_par_iter()
            .map(|c| {
                let (x, v) = (cfg.x_at(c % cfg.nx), cfg.v_at(c / cfg.nx));
                tfs_basin::classify_sdof(model, &wells, x, v, &cfg)
            })
            .collect();
        assert_eq!(lone, map.labels);
    }
}
