//! Dataset generation: columns, truth labels, noise level, clean derivatives, blow-up errors.

use tfs_origami::{
    CellSpec, DatasetConfig, Excitation, KreslingParams, NoiseKind, SurrogateSpec, SystemSpec,
    Truth, generate,
};

fn short(system: SystemSpec) -> DatasetConfig {
    DatasetConfig {
        system,
        excitations: vec![
            Excitation::Sweep {
                f0: 0.5,
                f1: 3.0,
                amplitude: 3.0,
                log: false,
                ramp: 0.5,
            },
            Excitation::Sine {
                freq: 1.0,
                amplitude: 2.0,
                phase: 0.0,
                ramp: 0.5,
            },
        ],
        duration: 10.0,
        dt: 0.01,
        snr_db: Some(30.0),
        seed: 11,
        ..DatasetConfig::default()
    }
}

#[test]
fn single_cell_dataset_columns_noise_and_metadata() {
    let cfg = short(SystemSpec::Kresling(CellSpec {
        truth: Truth::Surrogate,
        ..CellSpec::default()
    }));
    let ds = generate(&cfg).unwrap();
    assert_eq!(ds.records.len(), 2);
    assert_eq!(ds.meta.truth, "surrogate{5,6,7}");
    assert_eq!(ds.meta.surrogate_coefs[0].len(), 3);
    let json = serde_json::to_string(&ds.meta).unwrap();
    assert!(json.contains("\"truth\":\"surrogate{5,6,7}\""));
    let back: tfs_origami::DatasetMeta = serde_json::from_str(&json).unwrap();
    assert_eq!(back, ds.meta);
    for r in &ds.records {
        assert_eq!(r.len(), 1001);
        for c in [
            "x",
            "xb_acc",
            "x_clean",
            "x_vel_clean",
            "x_acc_clean",
            "xb_acc_clean",
        ] {
            assert!(r.column(c).is_some(), "missing {c}");
        }
        // Realised SNR of the noise on x and xb_acc is 30 dB (mean-square reference).
        for (m, c) in [("x", "x_clean"), ("xb_acc", "xb_acc_clean")] {
            let (m, c) = (r.column(m).unwrap(), r.column(c).unwrap());
            let ps: f64 = c.iter().map(|v| v * v).sum();
            let pn: f64 = m.iter().zip(c).map(|(a, b)| (a - b) * (a - b)).sum();
            assert!((10.0 * (ps / pn).log10() - 30.0).abs() < 1e-6);
        }
        // Clean velocity/acceleration are the derivatives of the clean displacement.
        let (x, v, a) = (
            r.column("x_clean").unwrap(),
            r.column("x_vel_clean").unwrap(),
            r.column("x_acc_clean").unwrap(),
        );
        let dt = r.dt();
        for k in 1..r.len() - 1 {
            assert!(((x[k + 1] - x[k - 1]) / (2.0 * dt) - v[k]).abs() < 1e-3 * (1.0 + v[k].abs()));
            assert!(((v[k + 1] - v[k - 1]) / (2.0 * dt) - a[k]).abs() < 2e-2 * (1.0 + a[k].abs()));
        }
        // The structure actually moves.
        let (lo, hi) = (
            x.iter().cloned().fold(0.0, f64::min),
            x.iter().cloned().fold(0.0, f64::max),
        );
        eprintln!("x range [{lo}, {hi}]");
        assert!(hi - lo > 0.05);
    }
    // Same seed, same data; another seed, other noise.
    let again = generate(&cfg).unwrap();
    assert_eq!(again.records[0].column("x"), ds.records[0].column("x"));
    let other = generate(&DatasetConfig {
        seed: 12,
        ..cfg.clone()
    })
    .unwrap();
    assert_ne!(other.records[0].column("x"), ds.records[0].column("x"));
    assert_eq!(
        other.records[0].column("x_clean"),
        ds.records[0].column("x_clean")
    );
}

#[test]
fn chain_dataset_with_pink_noise() {
    let cell = |g: f64| CellSpec {
        params: KreslingParams {
            gamma0_deg: g,
            c: 1.0,
            ..KreslingParams::default()
        },
        ..CellSpec::default()
    };
    let mut cfg = short(SystemSpec::Chain {
        cells: vec![cell(20.0), cell(28.5)],
    });
    cfg.noise = NoiseKind::Pink;
    cfg.excitations.truncate(1);
    let ds = generate(&cfg).unwrap();
    assert_eq!(ds.meta.truth, "truss,truss");
    let r = &ds.records[0];
    for c in [
        "x1",
        "x2",
        "xb_acc",
        "x1_clean",
        "x2_clean",
        "x2_vel_clean",
        "x2_acc_clean",
        "xb_acc_clean",
    ] {
        assert!(r.column(c).is_some(), "missing {c}");
    }
    // Started at the lowest stable equilibrium.
    let x0 = &ds.meta.records[0].x0;
    assert_eq!(x0.len(), 2);
    assert!((r.column("x1_clean").unwrap()[0] - x0[0]).abs() < 1e-15);
}

#[test]
fn blow_up_and_bad_config_are_errors() {
    // A surrogate with only {h^5, h^6} has V → −∞ for large h: a strong sweep escapes.
    let spec = CellSpec {
        truth: Truth::Surrogate,
        surrogate: SurrogateSpec {
            powers: vec![5, 6],
            ..SurrogateSpec::default()
        },
        ..CellSpec::default()
    };
    let mut cfg = short(SystemSpec::Kresling(spec));
    cfg.excitations = vec![Excitation::Sine {
        freq: 0.5,
        amplitude: 50.0,
        phase: 0.0,
        ramp: 0.0,
    }];
    let e = generate(&cfg).unwrap_err().to_string();
    assert!(e.contains("record 0") && e.contains("blew up"), "{e}");
    let e = generate(&DatasetConfig {
        dt: -1.0,
        ..DatasetConfig::default()
    })
    .unwrap_err()
    .to_string();
    assert!(e.contains("'dt'"), "{e}");
    let e = generate(&DatasetConfig {
        x0: Some(vec![0.0, 1.0]),
        ..DatasetConfig::default()
    })
    .unwrap_err()
    .to_string();
    assert!(e.contains("'x0'"), "{e}");
}

#[test]
fn excitation_cli_strings() {
    let e: Excitation = "sweep:0.5,5,4".parse().unwrap();
    assert_eq!(
        e,
        Excitation::Sweep {
            f0: 0.5,
            f1: 5.0,
            amplitude: 4.0,
            log: false,
            ramp: 0.0
        }
    );
    let e: Excitation = "sweep:1,8,2,log,ramp=1.5".parse().unwrap();
    assert_eq!(
        e,
        Excitation::Sweep {
            f0: 1.0,
            f1: 8.0,
            amplitude: 2.0,
            log: true,
            ramp: 1.5
        }
    );
    let e: Excitation = "sine:1.2,3,phase=0.5".parse().unwrap();
    assert_eq!(
        e,
        Excitation::Sine {
            freq: 1.2,
            amplitude: 3.0,
            phase: 0.5,
            ramp: 0.0
        }
    );
    for bad in ["sweep:1,2", "sine:1", "chirp:1,2,3", "sine:a,2", "sweep"] {
        let err = bad.parse::<Excitation>().unwrap_err().to_string();
        assert!(err.contains(bad), "{err}");
    }
    // JSON form used in configs.
    let j = serde_json::to_string(&e).unwrap();
    assert!(j.contains("\"kind\":\"sine\""));
}
