//! Full-size agreement of the coarse-to-fine maps with a fine fixed-step reference (every start
//! integrated with a quarter of the step and no early exit), and the time of each method:
//!
//! ```text
//! cargo run --release -p tfs-basin --example agreement -- table1 1000
//! cargo run --release -p tfs-basin --example agreement -- double-well 1000
//! cargo run --release -p tfs-basin --example agreement -- chain 1000
//! ```
//!
//! Prints the share of agreeing cells, the cells more than two cells from a reference boundary
//! (their 5 × 5 neighbourhood has one label) and how many of those disagree.

use std::time::Instant;

use tfs_basin::{
    BasinConfig, BasinMap, ChainWells, Method, Polynomial1Dof, Slice, WellInfo, basin_chain,
    basin_sdof,
};
use tfs_library::Model;

fn agreement(reference: &BasinMap, map: &BasinMap) -> (usize, usize, usize) {
    let (nx, ny) = (reference.nx, reference.ny);
    let (mut differ, mut far, mut far_differ) = (0, 0, 0);
    for j in 0..ny {
        for i in 0..nx {
            let l = reference.label(i, j);
            let d = usize::from(l != map.label(i, j));
            differ += d;
            let interior = (j.saturating_sub(2)..=(j + 2).min(ny - 1)).all(|b| {
                (i.saturating_sub(2)..=(i + 2).min(nx - 1)).all(|a| reference.label(a, b) == l)
            });
            if interior {
                far += 1;
                far_differ += d;
            }
        }
    }
    (differ, far, far_differ)
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let case = args.get(1).map_or("table1", String::as_str);
    let n: usize = args.get(2).map_or(1000, |s| s.parse().expect("grid size"));
    let cfg = BasinConfig::new(n, n, (0.0, 2.0), (-3.0, 3.0));
    let mut reference = cfg.clone();
    reference.method = Method::EveryCell;
    reference.dt = cfg.dt / 4.0;
    reference.early_exit = false;
    reference.t_max = 60.0;
    let mut run: Box<dyn FnMut(&BasinConfig) -> BasinMap> = match case {
        "table1" | "double-well" => {
            let model = if case == "table1" {
                Polynomial1Dof::table1_60db()
            } else {
                Polynomial1Dof::new(0.4, vec![0.0, -1.0, 0.0, 1.0]).expect("model")
            };
            let wells = WellInfo::from_polynomial(&model, (-1.0, 3.0)).expect("wells");
            Box::new(move |c| basin_sdof(&model, &wells, c, None).expect("map"))
        }
        "chain" => {
            let model = Model::from_json_str(
                r#"{"format":"tfs-model/1","dofs":["x1","x2"],"equations":[
                {"dof":"x1","terms":[{"term":"x1","coef":-1.0},{"term":"x1^3","coef":-0.5},
                    {"term":"x1'","coef":-0.3},{"term":"(x2-x1)","coef":-1.0},
                    {"term":"(x2-x1)^3","coef":1.0},{"term":"(x2-x1)'","coef":0.3}]},
                {"dof":"x2","terms":[{"term":"(x2-x1)","coef":1.0},{"term":"(x2-x1)^3","coef":-1.0},
                    {"term":"(x2-x1)'","coef":-0.3}]}]}"#,
            )
            .expect("model");
            let sys = model.compile().expect("compiles");
            let pot = |x: &[f64]| {
                let r = x[1] - x[0];
                0.5 * x[0] * x[0] + 0.125 * x[0].powi(4) - 0.5 * r * r + 0.25 * r.powi(4)
            };
            let barrier = ChainWells::barrier_from_saddles(pot, &[vec![0.0, 0.0]]).expect("saddle");
            let wells = ChainWells::new(
                vec![vec![0.0, -1.0], vec![0.0, 1.0]],
                vec![1.0, 1.0],
                pot,
                Some(barrier),
            )
            .expect("wells");
            let slice = Slice::paper(&[0.0, -1.0]);
            Box::new(move |c| {
                let mut c = c.clone();
                c.x_range = (-1.0, 3.0);
                basin_chain(&sys, &wells, &slice, &c, None).expect("map")
            })
        }
        other => panic!("unknown case {other}: table1, double-well or chain"),
    };
    let mut timed = |name: &str, c: &BasinConfig| {
        let t = Instant::now();
        let map = run(c);
        println!(
            "{name:>10}: {:8.3} s, {} of {} starts integrated, unsettled {}",
            t.elapsed().as_secs_f64(),
            map.integrated,
            n * n,
            map.unsettled_count
        );
        map
    };
    let fine = timed("reference", &reference);
    for (name, method) in [
        ("scalar", Method::Scalar),
        ("every cell", Method::EveryCell),
        ("refined", Method::Refined),
    ] {
        let map = timed(
            name,
            &BasinConfig {
                method,
                ..cfg.clone()
            },
        );
        let (differ, far, far_differ) = agreement(&fine, &map);
        println!(
            "{:>10}  agreement with the reference {:.4} % ({differ} cells differ); {far} cells more \
             than two cells from a boundary, {far_differ} of them differ",
            "",
            100.0 * (1.0 - differ as f64 / (n * n) as f64)
        );
    }
}
