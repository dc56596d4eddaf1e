//! Unit tests of the term evaluator, the sensitivities and the block solver.

use faer::Mat;
use faer::linalg::solvers::Solve;
use tfs_dynamics::SampledInput;
use tfs_library::{Equation, Model, ModelTerm, Term};

use crate::lm::{Prepared, Problem, Segment};
use crate::sens::Structure;

fn two_dof_model() -> Model {
    let dofs = vec!["x1".to_string(), "x2".to_string()];
    let t = |s: &str| Term::parse(s, &dofs).unwrap();
    Model::new(
        dofs.clone(),
        vec![
            Equation {
                dof: "x1".into(),
                terms: vec![
                    ModelTerm::new(t("x1"), -3.0),
                    ModelTerm::new(t("x1^3"), -0.5),
                    ModelTerm::new(t("x1'"), -0.1),
                    ModelTerm::new(t("(x1-x2)"), -1.5),
                    ModelTerm::new(t("u"), 2.0),
                    ModelTerm::new(t("x1*x2'"), 0.3),
                ],
            },
            Equation {
                dof: "x2".into(),
                terms: vec![
                    ModelTerm::new(t("x2"), -2.0),
                    ModelTerm::new(t("(x2-x1)'"), -0.2),
                    ModelTerm::new(t("tanh(x2'/0.5)"), -0.05),
                    ModelTerm::new(t("abs(x2)*x2"), 0.4),
                    ModelTerm::new(t("1"), 0.01),
                ],
            },
        ],
        "test",
    )
    .unwrap()
}

#[test]
fn evaluator_matches_compiled_model_and_fd_jacobians() {
    let m = two_dof_model();
    let cm = m.compile().unwrap();
    let (st, coefs) = Structure::new(&m).unwrap();
    assert_eq!(st.params(), 11);
    assert_eq!(cm.input_names(), &["u".to_string()]);
    let (mut a, mut th, mut ax, mut av) = (vec![0.0; 2], vec![0.0; 11], vec![0.0; 4], vec![0.0; 4]);
    let mut a_ref = vec![0.0; 2];
    for (x, v, u) in [
        ([0.3, -0.7], [1.1, 0.4], [0.5]),
        ([-1.2, 0.2], [-0.3, -0.9], [-1.0]),
    ] {
        st.eval(&coefs, &x, &v, &u, &mut a, &mut th, &mut ax, &mut av);
        cm.accel(&x, &v, &u, &mut a_ref);
        for i in 0..2 {
            assert!((a[i] - a_ref[i]).abs() < 1e-12, "{a:?} vs {a_ref:?}");
        }
        // Linear in coefficients: a_i = Σ_{j in eq i} c_j θ_j.
        let mut a_lin = [0.0; 2];
        for j in 0..11 {
            a_lin[st.eq_of(j)] += coefs[j] * th[j];
        }
        assert!((a_lin[0] - a[0]).abs() < 1e-12 && (a_lin[1] - a[1]).abs() < 1e-12);
        // Central finite differences of the compiled model.
        let h = 1e-6;
        for k in 0..2 {
            for (is_v, jac) in [(false, &ax), (true, &av)] {
                let (mut xp, mut vp, mut xm, mut vm) = (x, v, x, v);
                if is_v {
                    vp[k] += h;
                    vm[k] -= h;
                } else {
                    xp[k] += h;
                    xm[k] -= h;
                }
                let (mut ap, mut am) = (vec![0.0; 2], vec![0.0; 2]);
                cm.accel(&xp, &vp, &u, &mut ap);
                cm.accel(&xm, &vm, &u, &mut am);
                for i in 0..2 {
                    let fd = (ap[i] - am[i]) / (2.0 * h);
                    assert!(
                        (fd - jac[i * 2 + k]).abs() < 1e-6 * (1.0 + fd.abs()),
                        "d a{i}/d {}{k}: fd {fd} analytic {}",
                        if is_v { "v" } else { "x" },
                        jac[i * 2 + k]
                    );
                }
            }
        }
    }
}

/// A small two-DOF problem with three segments in one record and one segment in another.
fn small_problem<'a>(st: &'a Structure, recs: &'a [Prepared]) -> Problem<'a> {
    Problem {
        st,
        recs,
        segs: vec![
            Segment {
                rec: 0,
                k0: 0,
                k1: 12,
                linked: true,
            },
            Segment {
                rec: 0,
                k0: 12,
                k1: 25,
                linked: true,
            },
            Segment {
                rec: 0,
                k0: 25,
                k1: 39,
                linked: false,
            },
            Segment {
                rec: 1,
                k0: 0,
                k1: 29,
                linked: false,
            },
        ],
        pscale: st_scales(st),
        xs: vec![0.5, 0.4],
        vs: vec![0.9, 0.7],
        zs: (0..st.m).map(|j| 0.3 + 0.2 * j as f64).collect(),
        defect_weight: 3.0,
        substeps: 3,
        limit: 1e3,
    }
}

fn st_scales(st: &Structure) -> Vec<f64> {
    (0..st.params()).map(|j| 1.0 + 0.1 * j as f64).collect()
}

fn records() -> Vec<Prepared> {
    let mk = |len: usize, ph: f64| {
        let dt = 0.1;
        let u: Vec<f64> = (0..len).map(|k| (0.7 * k as f64 * dt + ph).sin()).collect();
        let x1: Vec<f64> = (0..len)
            .map(|k| 0.5 * (1.1 * k as f64 * dt + ph).sin())
            .collect();
        let x2: Vec<f64> = (0..len)
            .map(|k| 0.4 * (0.8 * k as f64 * dt).cos())
            .collect();
        let v1: Vec<f64> = (0..len)
            .map(|k| 0.55 * (1.1 * k as f64 * dt + ph).cos())
            .collect();
        let v2: Vec<f64> = (0..len)
            .map(|k| -0.32 * (0.8 * k as f64 * dt).sin())
            .collect();
        // Two internal-state tracks (used by the model with states).
        let z1: Vec<f64> = (0..len)
            .map(|k| 0.2 * (0.9 * k as f64 * dt).sin())
            .collect();
        let z2: Vec<f64> = (0..len)
            .map(|k| 0.1 * (0.5 * k as f64 * dt).cos())
            .collect();
        Prepared {
            input: SampledInput::new(0.0, dt, vec![u]).unwrap(),
            t0: 0.0,
            dt,
            xm: vec![x1, x2],
            vm: vec![v1, v2],
            zm: vec![z1, z2],
            w: vec![2.0, 1.5],
        }
    };
    vec![mk(40, 0.0), mk(30, 1.0)]
}

/// The two-DOF model plus a hysteretic coupling (in both equations, one state) and a Maxwell
/// element on `x1`.
fn model_with_states() -> Model {
    let mut m = two_dof_model();
    let t = |s: &str| Term::parse(s, &m.dofs).unwrap();
    let bw = t("bouc_wen((x2-x1)', 2, -0.5)");
    m.equations[0].terms.push(ModelTerm::new(bw.clone(), 0.8));
    m.equations[0]
        .terms
        .push(ModelTerm::new(t("maxwell(x1', 0.7)"), -0.6));
    m.equations[1].terms.push(ModelTerm::new(bw, -0.8));
    Model::new(m.dofs.clone(), m.equations.clone(), "t").unwrap()
}

#[test]
fn gradient_matches_finite_differences_of_the_cost() {
    gradient_check(&two_dof_model());
}

/// With internal states, the state parameters and the states' starts are unknowns too: their
/// gradient from the forward sensitivities matches differences of the cost.
#[test]
fn gradient_with_internal_states_matches_finite_differences() {
    let m = model_with_states();
    let (st, _) = Structure::new(&m).unwrap();
    assert_eq!((st.n, st.m, st.n_coefs(), st.params()), (2, 2, 14, 17));
    gradient_check(&m);
}

fn gradient_check(m: &Model) {
    let (st, coefs) = Structure::new(m).unwrap();
    let recs = records();
    let pb = small_problem(&st, &recs);
    let mut p = pb.initial(&coefs);
    // Move segment states off the data so defects are non-zero.
    for (k, v) in p.iter_mut().enumerate().skip(st.params()) {
        *v += 0.05 * ((k as f64) * 0.37).sin();
    }
    let nm = pb.normal(&p).unwrap();
    let g = pb.gradient(&nm);
    assert_eq!(g.len(), pb.n_params());
    for j in 0..p.len() {
        let h = 1e-6;
        let mut pp = p.clone();
        let mut pm = p.clone();
        pp[j] += h;
        pm[j] -= h;
        let fd = (pb.normal(&pp).unwrap().cost - pb.normal(&pm).unwrap().cost) / (2.0 * h);
        assert!(
            (fd - g[j]).abs() < 1e-5 * (1.0 + fd.abs()),
            "param {j}: fd {fd} vs analytic {}",
            g[j]
        );
    }
}

#[test]
fn block_solver_matches_dense_solve() {
    for m in [two_dof_model(), model_with_states()] {
        block_check(&m);
    }
}

fn block_check(m: &Model) {
    let (st, coefs) = Structure::new(m).unwrap();
    let recs = records();
    let pb = small_problem(&st, &recs);
    let p = pb.initial(&coefs);
    let nm = pb.normal(&p).unwrap();
    let dim = pb.n_params();
    let damp: Vec<f64> = (0..dim).map(|i| 1e-3 * (1.0 + i as f64)).collect();
    let delta = pb.solve(&nm, &damp).unwrap();
    let mut h = pb.dense(&nm);
    for i in 0..dim {
        h[(i, i)] += damp[i];
    }
    let g = pb.gradient(&nm);
    let rhs = Mat::<f64>::from_fn(dim, 1, |i, _| -g[i]);
    let z = h.partial_piv_lu().solve(&rhs);
    let scale = (0..dim).map(|i| z[(i, 0)].abs()).fold(0.0, f64::max);
    for i in 0..dim {
        assert!(
            (delta[i] - z[(i, 0)]).abs() < 1e-7 * scale.max(1.0),
            "component {i}: block {} dense {}",
            delta[i],
            z[(i, 0)]
        );
    }
}
