//! Basin maps of models with internal states (a Maxwell element, Bouc–Wen hysteresis) on a
//! double well: the states start at rest with every start, the SIMD blocks, the scalar path and
//! the lone-start classifier give each start the same label, and a label is the well an
//! independent adaptive integration of the same start ends in.

use tfs_basin::{BasinConfig, Label, Method, WellInfo, basin_sdof, classify_sdof};
use tfs_dynamics::{Dopri5, Integrator, SampledInput, SecondOrderSystem};
use tfs_library::{CompiledModel, Model};

/// `x'' = x − x³ − 0.3 x' + coef·memory`.
fn double_well(memory: &str, coef: f64) -> CompiledModel {
    let json = format!(
        r#"{{"format":"tfs-model/1","dofs":["x"],"equations":[{{"dof":"x","terms":[
        {{"term":"x","coef":1.0}},{{"term":"x^3","coef":-1.0}},{{"term":"x'","coef":-0.3}},
        {{"term":"{memory}","coef":{coef}}}]}}]}}"#
    );
    Model::from_json_str(&json).unwrap().compile().unwrap()
}

fn wells() -> WellInfo {
    WellInfo::from_force(
        |x| x * x * x - x,
        |x| 0.25 * x.powi(4) - 0.5 * x * x,
        (-3.0, 3.0),
        1.0,
    )
    .unwrap()
}

#[test]
fn memory_states_start_at_rest_and_every_path_agrees() {
    let wells = wells();
    for (memory, coef) in [("maxwell(x', 0.5)", -0.4), ("bouc_wen(x', 2, 1)", -0.3)] {
        let sys = double_well(memory, coef);
        assert_eq!(
            (SecondOrderSystem::dofs(&sys), sys.internal_states()),
            (2, 1)
        );
        let mut cfg = BasinConfig::new(29, 23, (-2.0, 2.0), (-2.0, 2.0));
        cfg.t_max = 60.0;
        cfg.method = Method::EveryCell;
        let every = basin_sdof(&sys, &wells, &cfg, None).unwrap();
        cfg.method = Method::Scalar;
        let scalar = basin_sdof(&sys, &wells, &cfg, None).unwrap();
        assert_eq!(every.labels, scalar.labels, "{memory}");
        let lone: Vec<Label> = (0..cfg.nx * cfg.ny)
            .map(|c| {
                classify_sdof(
                    &sys,
                    &wells,
                    cfg.x_at(c % cfg.nx),
                    cfg.v_at(c / cfg.nx),
                    &cfg,
                )
            })
            .collect();
        assert_eq!(lone, every.labels, "{memory}");
        // Both wells are reached, and a sample of starts ends where an adaptive integration
        // from the same start (state at rest) ends.
        let wells_hit = |k| {
            every
                .labels
                .iter()
                .filter(|&&l| l == Label::State(k))
                .count()
        };
        assert!(
            wells_hit(0) > 20 && wells_hit(1) > 20,
            "{memory}: {:?}",
            (wells_hit(0), wells_hit(1))
        );
        let t: Vec<f64> = (0..=600).map(|k| 0.1 * k as f64).collect();
        for c in (0..cfg.nx * cfg.ny).step_by(37) {
            let Label::State(k) = every.labels[c] else {
                continue;
            };
            let (x0, v0) = (cfg.x_at(c % cfg.nx), cfg.v_at(c / cfg.nx));
            let tr = Dopri5::default()
                .integrate(&sys, &SampledInput::zero(0), &[x0, 0.0], &[v0, 0.0], &t)
                .unwrap();
            let end = *tr.x[0].last().unwrap();
            let target = wells.stable()[k];
            assert!(
                (end - target).abs() < 0.1,
                "{memory}: start ({x0}, {v0}) labelled well {target}, integration ends at {end}"
            );
        }
    }
}
