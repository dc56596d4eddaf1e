//! Evidence tool (not committed): the model file JSON (equations, intervals, inclusion, the
//! whole criteria trace without timings) of several identification runs, to diff two builds.
//! `cargo run --release -p tfs-criteria --example trace_dump -- <peers data dir>`

use tfs_criteria::{
    IdentifySpec, MassChoice, TieOptions, identify_sindy, identify_tfs, identify_tfs_tied,
};
use tfs_data::Record;
use tfs_origami::{
    CellSpec, DatasetConfig, Excitation, KreslingParams, NoiseKind, SystemSpec, Truth, generate,
};

fn read(dir: &str) -> Vec<Record> {
    (1..=4)
        .map(|i| tfs_data::read_csv(format!("{dir}/train{i}.csv")).unwrap())
        .collect()
}

fn strip(mut v: serde_json::Value) -> serde_json::Value {
    if let Some(t) = v.get_mut("trace").and_then(|t| t.as_object_mut()) {
        t.remove("timing_ms");
    }
    v
}

fn show(label: &str, model: &tfs_library::Model) {
    let v = strip(model.to_json_value().unwrap());
    println!("=== {label}\n{}", serde_json::to_string_pretty(&v).unwrap());
}

fn chain(snr: f64, seed: u64) -> Vec<Record> {
    let cell = |g: f64| CellSpec {
        params: KreslingParams {
            gamma0_deg: g,
            ..Default::default()
        },
        truth: Truth::Truss,
        ..Default::default()
    };
    let sweeps = [
        (0.05, 1.5, 50.0, 1.5),
        (0.05, 1.5, 30.0, 2.0),
        (0.1, 1.2, 40.0, 2.5),
        (0.05, 2.0, 60.0, 3.0),
    ];
    sweeps
        .iter()
        .enumerate()
        .map(|(i, &(f0, f1, d, a))| {
            let cfg = DatasetConfig {
                system: SystemSpec::Chain {
                    cells: vec![cell(20.0), cell(28.5)],
                },
                excitations: vec![Excitation::Sweep {
                    f0,
                    f1,
                    amplitude: a,
                    log: false,
                    ramp: 0.0,
                }],
                duration: d,
                dt: 0.005,
                snr_db: Some(snr),
                noise: NoiseKind::White,
                seed: seed + 31 * i as u64,
                x0: None,
                v0: None,
                rtol: 1e-9,
            };
            generate(&cfg).unwrap().records.remove(0)
        })
        .collect()
}

fn main() {
    let root = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "target/peers/data".into());
    for case in ["white60", "white30", "white20", "pink30", "white10"] {
        let recs = read(&format!("{root}/{case}"));
        for lib in ["x^1..7, x', xb_acc", "poly(x, x'; 1..7), xb_acc"] {
            let spec = IdentifySpec::new(&["x"], lib);
            let id = identify_tfs(&recs, &spec).unwrap();
            show(&format!("tfs {case} [{lib}]"), &id.model_with_trace());
        }
    }
    for case in ["white60", "white20"] {
        let recs = read(&format!("{root}/{case}"));
        let mut spec = IdentifySpec::new(&["x"], "x^1..7, x', xb_acc");
        spec.tfs.criterion2.prune = true;
        let id = identify_tfs(&recs, &spec).unwrap();
        show(&format!("tfs prune {case}"), &id.model_with_trace());
        let spec = IdentifySpec::new(&["x"], "poly(x, x'; 1..7), xb_acc");
        let id = identify_sindy(&recs, &spec).unwrap();
        show(&format!("sindy {case}"), &id.model_with_trace());
    }
    const LIB1: &str = "x1^1..7, x1', (x2-x1)^1..7, (x2-x1)', xb_acc";
    const LIB2: &str = "(x2-x1)^1..7, (x2-x1)', xb_acc";
    for (snr, seed) in [(60.0, 5u64), (30.0, 11)] {
        let recs = chain(snr, seed);
        let mut sp = IdentifySpec::new(&["x1", "x2"], LIB1);
        sp.dof_libraries = vec![LIB1.to_string(), LIB2.to_string()];
        let id = identify_tfs_tied(&recs, &sp, &TieOptions::default()).unwrap();
        show(&format!("tied {snr}"), &id.model_with_trace());
        let est = TieOptions::new(MassChoice::Estimate {
            candidates: vec![0.5, 1.0, 2.0],
        });
        let id = identify_tfs_tied(&recs, &sp, &est).unwrap();
        show(&format!("tied estimate {snr}"), &id.model_with_trace());
        let id = identify_tfs(&recs, &sp).unwrap();
        show(&format!("untied {snr}"), &id.model_with_trace());
    }
}
