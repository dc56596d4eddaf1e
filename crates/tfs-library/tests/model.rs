//! Evaluation, model JSON, compiled model and potential tests.

use proptest::prelude::*;
use tfs_data::Record;
use tfs_library::{
    ColumnSet, CompiledModel, Equation, HistoryEntry, Library, LibraryError, Model, ModelTerm,
    RecordScore, StateLaw, Term,
};

fn record() -> Record {
    Record::new(
        "small",
        vec![0.0, 0.1, 0.2],
        vec![
            ("x1".into(), vec![1.0, -2.0, 0.5]),
            ("x2".into(), vec![3.0, 1.0, 0.0]),
            ("xb".into(), vec![0.5, 0.5, -1.0]),
            ("xb_acc".into(), vec![2.0, 0.0, -3.0]),
        ],
    )
    .unwrap()
}

#[test]
fn evaluation_matches_hand_values() {
    let rec = record();
    let cols = ColumnSet::new(&rec)
        .with("x1'", vec![0.5, -1.0, 2.0])
        .unwrap()
        .with("x2'", vec![1.0, 1.0, -1.0])
        .unwrap()
        .with("xb_vel", vec![0.0, 2.0, 1.0])
        .unwrap();
    let lib = Library::parse(
        "1, x1^2, (x2-x1)^3, (x1-xb)', x1'*abs(x1'), tanh(x2'/0.5), sign(x1), x1*x2'*xb_acc",
        &["x1", "x2"],
    )
    .unwrap();
    let m = lib.evaluate(&cols).unwrap();
    assert_eq!((m.nrows(), m.ncols()), (3, 8));
    let expected: [[f64; 8]; 3] = [
        [1.0, 1.0, 8.0, 0.5, 0.25, (2.0f64).tanh(), 1.0, 2.0],
        [1.0, 4.0, 27.0, -3.0, -1.0, (2.0f64).tanh(), -1.0, 0.0],
        [1.0, 0.25, -0.125, 1.0, 4.0, (-2.0f64).tanh(), 1.0, 1.5],
    ];
    for i in 0..3 {
        for j in 0..8 {
            assert!(
                (m[(i, j)] - expected[i][j]).abs() < 1e-14,
                "({i},{j}) {} vs {}",
                m[(i, j)],
                expected[i][j]
            );
        }
    }
    assert_eq!(
        lib.required_columns(),
        ["x1", "x2", "x1'", "xb_vel", "x2'", "xb_acc"]
    );
}

#[test]
fn missing_column_names_column_and_term() {
    let rec = record();
    let lib = Library::parse("x1, x1^2*x1'", &["x1"]).unwrap();
    match lib.evaluate(&rec) {
        Err(LibraryError::MissingColumn { column, term }) => {
            assert_eq!(column, "x1'");
            assert_eq!(term, "x1^2*x1'");
        }
        other => panic!("expected missing column, got {other:?}"),
    }
    let mut cs = ColumnSet::new(&rec);
    assert!(cs.insert("x1'", vec![1.0]).is_err());
    let cs = ColumnSet::new(&rec)
        .with("x1'", vec![f64::NAN, 0.0, 0.0])
        .unwrap();
    assert!(matches!(
        lib.evaluate(&cs),
        Err(LibraryError::NonFinite { row: 0, .. })
    ));
}

fn sample_model() -> Model {
    let lib = Library::parse("x', x^5, x^6, x^7, xb_acc", &["x"]).unwrap();
    let mut m =
        Model::from_coefficients(&lib, &[vec![-1.99, -12.12, 18.03, -6.56, -1.0]], "tfs").unwrap();
    m.equations[0].terms[0].interval = Some([-2.0, -1.98]);
    m.equations[0].terms[0].inclusion = Some(0.9);
    m.trace = serde_json::json!({"kappa": [1.0, 2.5]});
    m.history.push(HistoryEntry {
        step: "identify".into(),
        added: vec![],
        r_mse: vec![RecordScore {
            record: "a.csv".into(),
            r_mse: 0.01,
        }],
        details: serde_json::Value::Null,
    });
    m
}

/// The library offered for a DOF is read from the trace: `offered_library` where elimination
/// wrote one, else `library`; nothing for a trace without one, for another DOF, or for a list
/// that is not of term names.
#[test]
fn offered_library_reads_the_trace() {
    let mut m = sample_model();
    assert_eq!(m.offered_library("x"), None);
    m.trace = serde_json::json!({"dofs": [{"dof": "x", "library": ["x^5", "x'"]}]});
    assert_eq!(m.offered_library("x").unwrap(), ["x^5", "x'"]);
    assert_eq!(m.offered_library("y"), None);
    m.trace = serde_json::json!({"dofs": [{
        "dof": "x", "library": ["x^5"], "offered_library": ["x^5", "x^6", "x'"]
    }]});
    assert_eq!(m.offered_library("x").unwrap(), ["x^5", "x^6", "x'"]);
    m.trace = serde_json::json!({"dofs": [{"dof": "x", "library": ["x^5", 3]}]});
    assert_eq!(m.offered_library("x"), None);
}

#[test]
fn equation_string_is_readable() {
    let m = sample_model();
    assert_eq!(
        m.equation_string(),
        "x'' = -(1.990 ± 0.01000)·x' - 12.12·x^5 + 18.03·x^6 - 6.560·x^7 - 1.000·xb_acc"
    );
    assert_eq!(tfs_library::sig4(9.99996), "10.00");
    assert_eq!(tfs_library::sig4(223.46), "223.5");
}

#[test]
fn json_round_trip_and_validation() {
    let m = sample_model();
    let s = m.to_json_string().unwrap();
    let v: serde_json::Value = serde_json::from_str(&s).unwrap();
    assert_eq!(v["format"], "tfs-model/1");
    assert_eq!(v["equations"][0]["terms"][1]["term"], "x^5");
    assert_eq!(v["inputs"][0], "xb_acc");
    let back = Model::from_json_str(&s).unwrap();
    assert_eq!(back, m);

    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("m.json");
    m.write_path(&p).unwrap();
    assert_eq!(Model::from_path(&p).unwrap(), m);

    let bad = s.replace("tfs-model/1", "tfs-model/9");
    let e = Model::from_json_str(&bad).unwrap_err().to_string();
    assert!(e.starts_with("format:"), "{e}");
    let bad = s.replace("\"dof\": \"x\"", "\"dof\": \"y\"");
    let e = Model::from_json_str(&bad).unwrap_err().to_string();
    assert!(e.contains("equations[0].dof") && e.contains("'y'"), "{e}");
    let bad = s.replace("\"x^6\"", "\"x^^6\"");
    let e = Model::from_json_str(&bad).unwrap_err().to_string();
    assert!(e.contains("equations[0].terms[2].term"), "{e}");
    let bad = s.replace("\"xb_acc\"\n", "\"u\"\n");
    let e = Model::from_json_str(&bad).unwrap_err().to_string();
    assert!(e.contains("inputs") && e.contains("xb_acc"), "{e}");
    let e = Model::from_json_str("{\"format\": \"tfs-model/1\", \"dofs\": [\"x\"]}").unwrap_err();
    assert!(e.to_string().contains("equations"), "{e}");
    // Inputs may be omitted: they are derived.
    let minimal = r#"{"format":"tfs-model/1","dofs":["x"],"equations":[{"dof":"x","terms":[{"term":"u*x","coef":2}]}]}"#;
    assert_eq!(Model::from_json_str(minimal).unwrap().inputs, ["u"]);
}

fn random_model(seed: &[f64], dofs: &[&str]) -> Model {
    let spec = "1, x1, x2^3, (x2-x1)^2, (x1-xb)', x1'*abs(x2'), tanh(x2'/0.3), sign(x1), x1*u, (x2-x1)'*x2";
    let lib = Library::parse(spec, dofs).unwrap();
    let coefs: Vec<Vec<f64>> = (0..dofs.len())
        .map(|d| {
            (0..lib.len())
                .map(|j| seed[(d * lib.len() + j) % seed.len()])
                .collect()
        })
        .collect();
    Model::from_coefficients(&lib, &coefs, "random").unwrap()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn compiled_equals_slow_evaluation(
        seed in prop::collection::vec(-3.0f64..3.0, 20),
        state in prop::collection::vec(-2.0f64..2.0, 7),
    ) {
        let m = random_model(&seed, &["x1", "x2"]);
        let c = m.compile().unwrap();
        // Slow path: build one-row columns and evaluate each equation's terms.
        let names = ["x1", "x2", "x1'", "x2'"];
        let mut cols: Vec<(String, Vec<f64>)> = names.iter().zip(&state).map(|(n, v)| (n.to_string(), vec![*v])).collect();
        let mut u = vec![0.0; c.inputs()];
        for (k, name) in c.input_names().iter().enumerate() {
            let val = match name.as_str() { "xb" => state[4], "xb_vel" => state[5], "u" => state[6], other => panic!("{other}") };
            u[k] = val;
            cols.push((name.clone(), vec![val]));
        }
        let rec = Record::new("one", vec![0.0], cols).unwrap();
        let mut out = [0.0; 2];
        c.try_accel(&state[0..2], &state[2..4], &u, &mut out).unwrap();
        for (i, eq) in m.equations.iter().enumerate() {
            let slow: f64 = eq.terms.iter().map(|t| t.coef * tfs_library::evaluate_term(&t.term, &rec).unwrap()[0]).sum();
            prop_assert!((slow - out[i]).abs() <= 1e-12 * (1.0 + slow.abs()), "{} vs {}", slow, out[i]);
        }
    }

    #[test]
    fn json_round_trip_random(seed in prop::collection::vec(-1e6f64..1e6, 20)) {
        let m = random_model(&seed, &["x1", "x2"]);
        let back = Model::from_json_str(&m.to_json_string().unwrap()).unwrap();
        prop_assert_eq!(back, m);
    }

    #[test]
    fn potential_derivative_is_force(
        c in prop::collection::vec(-2.0f64..2.0, 6),
        x in -1.5f64..1.5,
    ) {
        let spec = "1, x, x^3, x^6, x', x^2*x'";
        let lib = Library::parse(spec, &["x"]).unwrap();
        let m = Model::from_coefficients(&lib, std::slice::from_ref(&c), "p").unwrap();
        let r = m.restoring("x").unwrap();
        prop_assert!(r.polynomial().is_some());
        prop_assert_eq!(r.potential(0.0), 0.0);
        // F = -(c0 + c1 x + c2 x^3 + c3 x^6) (velocity terms vanish at rest).
        let f = -(c[0] + c[1] * x + c[2] * x.powi(3) + c[3] * x.powi(6));
        prop_assert!((r.force(x) - f).abs() < 1e-12);
        let h = 1e-5;
        let fd = (r.potential(x + h) - r.potential(x - h)) / (2.0 * h);
        prop_assert!((fd - r.force(x)).abs() < 1e-7 * (1.0 + f.abs()));
        let kd = (r.force(x + h) - r.force(x - h)) / (2.0 * h);
        prop_assert!((kd - r.stiffness(x)).abs() < 1e-6 * (1.0 + kd.abs()));
    }

    #[test]
    fn nonpolynomial_potential_derivative_is_force(
        c in prop::collection::vec(-2.0f64..2.0, 4),
        x in prop_oneof![-1.5f64..-0.05, 0.05f64..1.5],
    ) {
        let lib = Library::parse("x, abs(x), x*sign(x)*x, tanh(x/0.2)*x", &["x"]).unwrap();
        let m = Model::from_coefficients(&lib, &[c], "p").unwrap();
        let r = m.restoring("x").unwrap();
        prop_assert!(r.polynomial().is_none());
        prop_assert_eq!(r.potential(0.0), 0.0);
        let h = 1e-4;
        let fd = (r.potential(x + h) - r.potential(x - h)) / (2.0 * h);
        prop_assert!((fd - r.force(x)).abs() < 1e-6, "{} vs {}", fd, r.force(x));
        let kd = (r.force(x + h) - r.force(x - h)) / (2.0 * h);
        prop_assert!((kd - r.stiffness(x)).abs() < 1e-5 * (1.0 + kd.abs()));
    }
}

#[test]
fn potential_closed_forms() {
    // Paper Eq. (16) convention: coefficient of x^5 is -alpha, so F = alpha x^5, V = alpha x^6 / 6.
    let lib = Library::parse("x^5, x'", &["x"]).unwrap();
    let m = Model::from_coefficients(&lib, &[vec![-3.0, -2.0]], "p").unwrap();
    assert!((m.restoring_force("x", 1.5).unwrap() - 3.0 * 1.5f64.powi(5)).abs() < 1e-12);
    assert!((m.potential("x", 1.5).unwrap() - 0.5 * 1.5f64.powi(6)).abs() < 1e-12);
    assert!((m.stiffness("x", 1.5).unwrap() - 15.0 * 1.5f64.powi(4)).abs() < 1e-12);
    // Dry-friction-like position terms: V for F = -c tanh(x/eps) is -c eps ln cosh(x/eps);
    // F = -c |x| gives V = -c x|x|/2; F = -c sign(x) gives V = -c |x|.
    let lib = Library::parse("tanh(x/0.01), abs(x), sign(x)", &["x"]).unwrap();
    for (j, closed) in [
        (
            0,
            Box::new(|x: f64| -0.01 * (x / 0.01f64).cosh().ln()) as Box<dyn Fn(f64) -> f64>,
        ),
        (1, Box::new(|x: f64| -x * x.abs() / 2.0)),
        (2, Box::new(|x: f64| -x.abs())),
    ] {
        let mut c = vec![0.0; 3];
        c[j] = 1.0;
        let m = Model::from_coefficients(&lib, &[c], "p").unwrap();
        for x in [-1.3, -0.004, 0.02, 0.7] {
            let v = m.potential("x", x).unwrap();
            assert!(
                (v - closed(x)).abs() < 1e-9,
                "term {j} x {x}: {v} vs {}",
                closed(x)
            );
        }
    }
    // A stop at x = -0.3 from below, x'' = k·below(x, -0.3): F = -k·max(0, -0.3 - x), and
    // V = k·(x + 0.3)²/2 below the stop, a wall (0 above it; the quadrature of the potential
    // crosses the kink at the stop, hence the looser tolerance).
    let lib = Library::parse("below(x, -0.3), above(x2, 0.2)", &["x", "x2"]).unwrap();
    let m = Model::from_coefficients(&lib, &[vec![40.0, 7.0], vec![0.0, 0.0]], "p").unwrap();
    for x in [-1.1f64, -0.5, -0.3, 0.0, 0.8] {
        let pen = (-0.3 - x).max(0.0);
        let f = m.restoring_force("x", x).unwrap();
        assert!((f + 40.0 * pen).abs() < 1e-12, "x {x}: F {f}");
        let v = m.potential("x", x).unwrap();
        assert!(
            (v - 20.0 * pen * pen).abs() < 1e-5 * (1.0 + v),
            "x {x}: V {v}"
        );
    }
    // Chain slice: x1'' = -k (x1-xb) - k2 (x1-x2)^3 ⇒ F(x1) = k x1 + k2 x1^3 with x2 = xb = 0.
    let lib = Library::parse("(x1-xb), (x2-x1)^3, x1'", &["x1", "x2"]).unwrap();
    let m = Model::from_coefficients(&lib, &[vec![-2.0, 5.0, -1.0], vec![0.0, -5.0, 0.0]], "p")
        .unwrap();
    assert!((m.restoring_force("x1", 0.5).unwrap() - (2.0 * 0.5 + 5.0 * 0.125)).abs() < 1e-12);
    assert!((m.restoring_force("x2", 0.5).unwrap() - 5.0 * 0.125).abs() < 1e-12);
    assert!(m.potential("x3", 0.5).is_err());
}

#[test]
fn model_new_orders_equations_and_checks_dofs() {
    let d = ["x1", "x2"];
    let t = |s: &str| Term::parse(s, &d).unwrap();
    let eqs = vec![
        Equation {
            dof: "x2".into(),
            terms: vec![ModelTerm::new(t("x2"), 1.0)],
        },
        Equation {
            dof: "x1".into(),
            terms: vec![ModelTerm::new(t("(x1-xb)'"), 1.0)],
        },
    ];
    let m = Model::new(vec!["x1".into(), "x2".into()], eqs.clone(), "t").unwrap();
    assert_eq!(m.equations[0].dof, "x1");
    assert_eq!(m.inputs, ["xb_vel"]);
    assert!(Model::new(vec!["x1".into()], eqs.clone(), "t").is_err());
    assert!(Model::new(vec!["x1".into(), "x2".into(), "x3".into()], eqs, "t").is_err());
}

/// `accel_jacobian` (the compiled coefficients, no regressors) gives what `eval_jacobian`
/// gives at the state `(x, v, u)`: the accelerations `a` and the Jacobians `ax`, `av`, to
/// rounding (a power is taken as `s^(k−1)·s` there).
fn same_as_accel_jacobian(
    cm: &CompiledModel,
    (x, v, u): (&[f64], &[f64], &[f64]),
    a: &[f64],
    ax: &[f64],
    av: &[f64],
) {
    let n = cm.system_dofs();
    let (mut a2, mut ax2, mut av2) = (vec![0.0; n], vec![0.0; n * n], vec![0.0; n * n]);
    cm.accel_jacobian(x, v, u, &mut a2, &mut ax2, &mut av2);
    let pairs = a2
        .iter()
        .zip(a)
        .chain(ax2.iter().zip(ax))
        .chain(av2.iter().zip(av));
    for (k, (p, q)) in pairs.enumerate() {
        assert!(
            (p - q).abs() <= 1e-12 * (1.0 + q.abs()),
            "entry {k}: {p} against {q}"
        );
    }
}

/// `eval_jacobian` agrees with `accel` (value), with the regressors times the coefficients, and
/// with central differences of `accel` (Jacobians), on a chain with relative, abs and tanh terms.
#[test]
fn compiled_jacobian_matches_central_differences() {
    let lib1 = Library::parse(
        "x1, x1^3, x1', x1'*abs(x1'), (x2-x1), (x2-x1)^2*(x2-x1)', tanh(x1'/0.3), xb_acc, below(x1, 0.5), x1'*above((x2-x1), -1)",
        &["x1", "x2"],
    )
    .unwrap();
    let lib2 = Library::parse(
        "(x2-x1), (x2-x1)^5, (x2-x1)', x2*x2'^2, above(x2, -0.9)",
        &["x1", "x2"],
    )
    .unwrap();
    let c1 = vec![-3.0, 0.7, -0.4, -0.2, 2.5, 0.9, -0.6, -1.0, 30.0, 0.4];
    let c2 = vec![-2.5, 0.3, -0.8, 0.05, -20.0];
    let m1 = Model::from_coefficients(&lib1, &[c1.clone(), vec![0.0; c1.len()]], "t").unwrap();
    let m2 = Model::from_coefficients(&lib2, &[vec![0.0; c2.len()], c2.clone()], "t").unwrap();
    let mut m = m1.clone();
    m.equations[1] = m2.equations[1].clone();
    let cm = m.compile().unwrap();
    let coefs = cm.coefficients();
    assert_eq!(coefs.len(), cm.n_terms());
    let (n, nt) = (cm.dofs(), cm.n_terms());
    let x = [0.37, -0.52];
    let v = [0.81, -0.29];
    let u: Vec<f64> = (0..cm.inputs()).map(|k| 0.4 + 0.1 * k as f64).collect();
    let (mut a, mut th, mut ax, mut av) = (
        vec![0.0; n],
        vec![0.0; nt],
        vec![0.0; n * n],
        vec![0.0; n * n],
    );
    cm.eval_jacobian(&coefs, &x, &v, &u, &mut a, &mut th, &mut ax, &mut av);
    same_as_accel_jacobian(&cm, (&x, &v, &u), &a, &ax, &av);
    let mut a_ref = vec![0.0; n];
    cm.accel(&x, &v, &u, &mut a_ref);
    let mut a_lin = vec![0.0; n];
    for j in 0..nt {
        a_lin[cm.equation_of(j)] += coefs[j] * th[j];
    }
    for i in 0..n {
        assert!(
            (a[i] - a_ref[i]).abs() < 1e-12,
            "a[{i}] {} vs {}",
            a[i],
            a_ref[i]
        );
        assert!((a_lin[i] - a_ref[i]).abs() < 1e-12);
    }
    let h = 1e-6;
    for k in 0..n {
        for (is_v, jac) in [(false, &ax), (true, &av)] {
            let (mut xp, mut xm, mut vp, mut vm) = (x, x, v, v);
            if is_v {
                vp[k] += h;
                vm[k] -= h;
            } else {
                xp[k] += h;
                xm[k] -= h;
            }
            let (mut ap, mut am) = (vec![0.0; n], vec![0.0; n]);
            cm.accel(&xp, &vp, &u, &mut ap);
            cm.accel(&xm, &vm, &u, &mut am);
            for i in 0..n {
                let fd = (ap[i] - am[i]) / (2.0 * h);
                let an = jac[i * n + k];
                assert!(
                    (fd - an).abs() < 1e-6 * (1.0 + fd.abs()),
                    "∂a_{i}/∂{}_{k}: analytic {an}, central difference {fd}",
                    if is_v { "v" } else { "x" }
                );
            }
        }
    }
}

/// `accel_lanes` gives every state of a component-major block exactly what `accel` gives it
/// (bit for bit; `accel` takes a shortcut for one power of a displacement, velocity or input,
/// `accel_lanes` the general factor loop), for every factor kind, relative coordinates to DOFs and inputs, powers up to
/// 13 (above 3 they are computed by repeated squaring, which must equal `powi`), and block
/// sizes that are and are not multiples of the eight-lane chunk.
#[test]
fn accel_lanes_equals_accel_bit_for_bit() {
    let lib1 = Library::parse(
        "1, x1, x1^4, x1^5*x2^7, x1^13, x1'*abs(x1'), (x2-x1)^6, (x1-xb)', tanh(x1'/0.3), sign(x2), xb_acc*x1, below(x1, 0.5), above((x2-x1), -1), x2', x1'^3, xb_acc, xb^2",
        &["x1", "x2"],
    )
    .unwrap();
    let lib2 = Library::parse("(x2-x1)^9, x2^11*x2', (x2-x1)'^3, 1", &["x1", "x2"]).unwrap();
    let c1: Vec<f64> = (0..lib1.len()).map(|j| 0.3 - 0.17 * j as f64).collect();
    let c2: Vec<f64> = (0..lib2.len()).map(|j| -1.1 + 0.4 * j as f64).collect();
    let m1 = Model::from_coefficients(&lib1, &[c1.clone(), vec![0.0; c1.len()]], "t").unwrap();
    let m2 = Model::from_coefficients(&lib2, &[vec![0.0; c2.len()], c2], "t").unwrap();
    let mut m = m1.clone();
    m.equations[1] = m2.equations[1].clone();
    let cm = m.compile().unwrap();
    let u: Vec<f64> = (0..cm.inputs()).map(|k| 0.4 - 0.3 * k as f64).collect();
    // A deterministic spread of states, including zeros, negatives and values above 1.
    let state = |l: usize, c: usize| ((l * 7 + c * 13) % 29) as f64 / 7.0 - 2.0;
    for lanes in [1usize, 5, 8, 13, 24] {
        let (n, m) = (cm.dofs(), lanes);
        let mut x = vec![0.0; n * m];
        let mut v = vec![0.0; n * m];
        for l in 0..m {
            for i in 0..n {
                x[i * m + l] = state(l, i);
                v[i * m + l] = state(l + 3, i + 5) * 0.7;
            }
        }
        let mut out = vec![f64::NAN; n * m];
        cm.accel_lanes(&x, &v, &u, &mut out);
        for l in 0..m {
            let xl: Vec<f64> = (0..n).map(|i| x[i * m + l]).collect();
            let vl: Vec<f64> = (0..n).map(|i| v[i * m + l]).collect();
            let mut one = vec![0.0; n];
            cm.accel(&xl, &vl, &u, &mut one);
            for i in 0..n {
                assert_eq!(
                    out[i * m + l].to_bits(),
                    one[i].to_bits(),
                    "lanes {lanes}, state {l}, dof {i}: {} vs {}",
                    out[i * m + l],
                    one[i]
                );
            }
        }
    }
}

/// A chain whose equations share a hysteretic coupling and each have their own memory state:
/// the model round-trips through JSON with its internal states, compiles to `n + m`
/// coordinates (the states are the auxiliary velocities, their rates the auxiliary
/// accelerations), and `eval_jacobian` (rows of the states included) and
/// `state_param_gradient` agree with central differences.
#[test]
fn internal_states_round_trip_and_differentiate() {
    let dofs = ["x1", "x2"];
    let t = |s: &str| Term::parse(s, &dofs).unwrap();
    let shared = "bouc_wen((x2-x1)', 40, -25)";
    let eqs = vec![
        Equation {
            dof: "x1".into(),
            terms: vec![
                ModelTerm::new(t("x1"), -4.0),
                ModelTerm::new(t(shared), 3.0),
                ModelTerm::new(t("maxwell(x1', 0.2)"), -1.5),
                ModelTerm::new(t("x1*dahl(x1', 15)"), 0.7),
                ModelTerm::new(t("xb_acc"), -1.0),
            ],
        },
        Equation {
            dof: "x2".into(),
            terms: vec![
                ModelTerm::new(t("x2"), -2.0),
                ModelTerm::new(t(shared), -3.0),
            ],
        },
    ];
    let m = Model::new(dofs.iter().map(|s| s.to_string()).collect(), eqs, "t").unwrap();
    assert_eq!(m.inputs, ["xb_acc"]);
    let states = m.internal_states();
    assert_eq!(states.len(), 3, "{states:?}");
    let back = Model::from_json_str(&m.to_json_string().unwrap()).unwrap();
    assert_eq!(back, m);
    assert!(
        m.to_json_string()
            .unwrap()
            .contains("bouc_wen((x2-x1)', 40, -25)")
    );
    let cm = m.compile().unwrap();
    assert_eq!((cm.dofs(), cm.states(), cm.system_dofs()), (2, 3, 5));
    assert_eq!(cm.state_params(), vec![40.0, -25.0, 0.2, 15.0]);
    assert_eq!(cm.state_of_param(), vec![0, 0, 1, 2]);
    let nn = cm.system_dofs();
    let nt = cm.n_terms();
    let x = [0.3, -0.4, 0.0, 0.0, 0.0];
    let v = [0.8, -0.5, 0.02, -0.3, 0.4];
    let u = [0.25];
    // Rates of the states by their laws.
    let mut a = vec![0.0; nn];
    cm.accel(&x, &v, &u, &mut a);
    let q = v[1] - v[0];
    let bw = StateLaw::BoucWen {
        a: 40.0,
        b: -25.0,
        nu: 1.0,
    };
    assert!((a[2] - bw.rate(q, v[2])).abs() < 1e-15);
    assert!((a[3] - (v[0] - v[3]) / 0.2).abs() < 1e-12);
    assert!((a[4] - 15.0 * (v[0] - v[0].abs() * v[4])).abs() < 1e-12);
    // Many states side by side (basin maps): each lane bit for bit what `accel` gives it,
    // the states' rates included, for blocks that are and are not multiples of eight lanes.
    for lanes in [1usize, 9, 16] {
        let (mut xl, mut vl) = (vec![0.0; nn * lanes], vec![0.0; nn * lanes]);
        for l in 0..lanes {
            for i in 0..nn {
                xl[i * lanes + l] = x[i] + 0.05 * l as f64;
                vl[i * lanes + l] = v[i] - 0.07 * (l * (i + 1)) as f64;
            }
        }
        let mut out = vec![f64::NAN; nn * lanes];
        cm.accel_lanes(&xl, &vl, &u, &mut out);
        for l in 0..lanes {
            let xs: Vec<f64> = (0..nn).map(|i| xl[i * lanes + l]).collect();
            let vs: Vec<f64> = (0..nn).map(|i| vl[i * lanes + l]).collect();
            let mut one = vec![0.0; nn];
            cm.accel(&xs, &vs, &u, &mut one);
            for i in 0..nn {
                assert_eq!(
                    out[i * lanes + l].to_bits(),
                    one[i].to_bits(),
                    "lane {l}, coordinate {i}"
                );
            }
        }
    }
    assert!((a[1] - (-2.0 * x[1] - 3.0 * v[2])).abs() < 1e-12);
    let coefs = cm.coefficients();
    let (mut aj, mut th, mut ax, mut av) = (
        vec![0.0; nn],
        vec![0.0; nt],
        vec![0.0; nn * nn],
        vec![0.0; nn * nn],
    );
    cm.eval_jacobian(&coefs, &x, &v, &u, &mut aj, &mut th, &mut ax, &mut av);
    same_as_accel_jacobian(&cm, (&x, &v, &u), &aj, &ax, &av);
    for i in 0..nn {
        assert!((aj[i] - a[i]).abs() < 1e-12, "a[{i}]");
    }
    let h = 1e-7;
    for k in 0..nn {
        for (is_v, jac) in [(false, &ax), (true, &av)] {
            let (mut xp, mut xm, mut vp, mut vm) = (x, x, v, v);
            if is_v {
                vp[k] += h;
                vm[k] -= h;
            } else {
                xp[k] += h;
                xm[k] -= h;
            }
            let (mut ap, mut am) = (vec![0.0; nn], vec![0.0; nn]);
            cm.accel(&xp, &vp, &u, &mut ap);
            cm.accel(&xm, &vm, &u, &mut am);
            for i in 0..nn {
                let fd = (ap[i] - am[i]) / (2.0 * h);
                let an = jac[i * nn + k];
                assert!(
                    (fd - an).abs() < 1e-5 * (1.0 + fd.abs()),
                    "∂a_{i}/∂{}_{k}: analytic {an}, central difference {fd}",
                    if is_v { "v" } else { "x" }
                );
            }
        }
    }
    let p = cm.state_params();
    let mut g = vec![0.0; p.len()];
    cm.state_param_gradient(&x, &v, &u, &mut g);
    let owner = cm.state_of_param();
    for r in 0..p.len() {
        let hr = 1e-6 * p[r].abs();
        let (mut pp, mut pm) = (p.clone(), p.clone());
        pp[r] += hr;
        pm[r] -= hr;
        let (mut ap, mut am) = (vec![0.0; nn], vec![0.0; nn]);
        cm.with_state_params(&pp)
            .unwrap()
            .accel(&x, &v, &u, &mut ap);
        cm.with_state_params(&pm)
            .unwrap()
            .accel(&x, &v, &u, &mut am);
        let i = 2 + owner[r];
        let fd = (ap[i] - am[i]) / (2.0 * hr);
        assert!(
            (fd - g[r]).abs() < 1e-6 * (1.0 + fd.abs()),
            "param {r}: {} vs {fd}",
            g[r]
        );
    }
    // New laws by state index rewrite every term that uses the state.
    let laws = [
        StateLaw::BoucWen {
            a: 50.0,
            b: -20.0,
            nu: 1.0,
        },
        StateLaw::Maxwell { tau: 0.3 },
        StateLaw::Dahl { kappa: 10.0 },
    ];
    let m2 = m.with_state_laws(&laws).unwrap();
    assert_eq!(
        m2.internal_states().iter().map(|s| s.1).collect::<Vec<_>>(),
        laws.to_vec()
    );
    assert!(m2.equation_string().contains("bouc_wen((x2-x1)', 50, -20)"));
    assert_eq!(
        m2.compile().unwrap().state_params(),
        vec![50.0, -20.0, 0.3, 10.0]
    );
    assert!(m.with_state_laws(&laws[..2]).is_err());
    // A model file with a bad state parameter names the term.
    let bad = m
        .to_json_string()
        .unwrap()
        .replace("maxwell(x1', 0.2)", "maxwell(x1', 0)");
    let e = Model::from_json_str(&bad).unwrap_err().to_string();
    assert!(e.contains("equations[0].terms") && e.contains("tau"), "{e}");
}
