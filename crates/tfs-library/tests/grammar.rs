//! Grammar tests: print/parse round trips, range expansion, error messages.

use proptest::prelude::*;
use tfs_library::{Coord, Factor, Library, LibraryError, StateLaw, Term, Var};

const DOFS: [&str; 3] = ["x", "x1", "x2"];

fn var_strategy() -> impl Strategy<Value = Var> {
    let dof = prop::sample::select(vec!["x", "x1", "x2"]).prop_map(String::from);
    // Rig headers carry units and dashes: such names print quoted and parse back.
    let input = prop::sample::select(vec![
        "xb_acc",
        "u",
        "force",
        "xb",
        "acc [m/s2]",
        "base-acc",
        "say \"hi\"",
    ])
    .prop_map(String::from);
    prop_oneof![
        dof.clone().prop_map(Var::Disp),
        dof.clone().prop_map(Var::Vel),
        input.prop_map(Var::Input),
        (0usize..3, 0usize..4)
            .prop_filter_map("distinct", |(a, b)| {
                let names = ["x", "x1", "x2", "xb"];
                (a != b).then(|| {
                    let base = if b < 3 {
                        Coord::Dof(names[b].into())
                    } else {
                        Coord::Input("xb".into())
                    };
                    (names[a].to_string(), base)
                })
            })
            .prop_flat_map(|(a, b)| prop_oneof![
                Just(Var::RelDisp(a.clone(), b.clone())),
                Just(Var::RelVel(a, b))
            ]),
    ]
}

/// Velocity coordinates (what drives an internal state).
fn velocity_strategy() -> impl Strategy<Value = Var> {
    var_strategy().prop_filter("a velocity", Var::is_velocity)
}

fn law_strategy() -> impl Strategy<Value = StateLaw> {
    prop_oneof![
        (1e-4f64..10.0).prop_map(|tau| StateLaw::Maxwell { tau }),
        (
            -1e4f64..1e4,
            -1e4f64..1e4,
            prop::sample::select(vec![1.0, 1.5, 2.0])
        )
            .prop_map(|(a, b, nu)| StateLaw::BoucWen { a, b, nu }),
        (1e-3f64..1e5).prop_map(|kappa| StateLaw::Dahl { kappa }),
    ]
}

fn factor_strategy() -> impl Strategy<Value = Factor> {
    prop_oneof![
        (velocity_strategy(), law_strategy()).prop_map(|(v, l)| Factor::State(v, l)),
        (var_strategy(), 1u32..9).prop_map(|(v, k)| Factor::Pow(v, k)),
        var_strategy().prop_map(Factor::Abs),
        var_strategy().prop_map(Factor::Sign),
        (var_strategy(), 1e-6f64..10.0).prop_map(|(v, e)| Factor::Tanh(v, e)),
        (var_strategy(), -5.0f64..5.0).prop_map(|(v, c)| Factor::Below(v, c)),
        (var_strategy(), -5.0f64..5.0).prop_map(|(v, c)| Factor::Above(v, c)),
    ]
}

fn term_strategy() -> impl Strategy<Value = Term> {
    prop::collection::vec(factor_strategy(), 0..4).prop_map(Term::new)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn term_print_parse_round_trip(t in term_strategy()) {
        let s = t.to_string();
        let back = Term::parse(&s, &DOFS).unwrap();
        prop_assert_eq!(&back, &t);
        prop_assert_eq!(back.to_string(), s);
    }

    #[test]
    fn spec_round_trip_with_whitespace(terms in prop::collection::vec(term_strategy(), 1..6)) {
        // Insert spaces around every token boundary we can: after commas and around '*'.
        let spec = terms.iter().map(|t| t.to_string().replace('*', " * ")).collect::<Vec<_>>().join(" ,  ");
        let lib = Library::parse(&spec, &DOFS).unwrap();
        let mut distinct: Vec<Term> = Vec::new();
        for t in terms {
            if !distinct.contains(&t) { distinct.push(t); }
        }
        prop_assert_eq!(lib.terms(), &distinct[..]);
        let again = Library::parse(&lib.spec(), &DOFS).unwrap();
        prop_assert_eq!(again, lib);
    }

    #[test]
    fn factor_order_does_not_matter(fs in prop::collection::vec(factor_strategy(), 0..4)) {
        let mut rev = fs.clone();
        rev.reverse();
        prop_assert_eq!(Term::new(fs), Term::new(rev));
    }
}

#[test]
fn canonical_names() {
    let p = |s: &str| Term::parse(s, &["x"]).unwrap().to_string();
    assert_eq!(p("x'*x^2"), "x^2*x'");
    assert_eq!(p("x*x*x'"), "x^2*x'");
    assert_eq!(p("abs(x')*x'"), "x'*abs(x')");
    assert_eq!(p(" tanh( x' / 0.01 ) "), "tanh(x'/0.01)");
    assert_eq!(p("tanh(x'/1e-3)"), "tanh(x'/0.001)");
    assert_eq!(p("1"), "1");
    assert_eq!(p("1*x"), "x");
    assert_eq!(p("xb_acc"), "xb_acc");
    let q = |s: &str| Term::parse(s, &["x1", "x2"]).unwrap().to_string();
    assert_eq!(q("( x2 - x1 )^3"), "(x2-x1)^3");
    assert_eq!(q("(x1-xb)'"), "(x1-xb)'");
}

#[test]
fn variable_kinds() {
    let t = Term::parse("(x2-x1)^2*(x1-xb)'*u", &["x1", "x2"]).unwrap();
    assert_eq!(
        t.factors(),
        &[
            Factor::Pow(Var::RelDisp("x2".into(), Coord::Dof("x1".into())), 2),
            Factor::Pow(Var::RelVel("x1".into(), Coord::Input("xb".into())), 1),
            Factor::Pow(Var::Input("u".into()), 1),
        ]
    );
    assert_eq!(t.required_columns(), ["x2", "x1", "x1'", "xb_vel", "u"]);
    assert_eq!(t.required_inputs(), ["xb_vel", "u"]);
}

#[test]
fn range_expansion_counts() {
    let lib = Library::parse("poly(x, x'; 0..7)", &["x"]).unwrap();
    assert_eq!(lib.len(), 36);
    // Every monomial x^i x'^j with i + j <= 7 exactly once.
    for i in 0..=7u32 {
        for j in 0..=(7 - i) {
            let mut f = vec![];
            if i > 0 {
                f.push(Factor::Pow(Var::Disp("x".into()), i));
            }
            if j > 0 {
                f.push(Factor::Pow(Var::Vel("x".into()), j));
            }
            assert!(
                lib.index_of(&Term::new(f)).is_some(),
                "missing x^{i} x'^{j}"
            );
        }
    }
    assert_eq!(lib.names()[0], "1");
    let lib = Library::parse("x^1..7, x', xb_acc", &["x"]).unwrap();
    assert_eq!(
        lib.names(),
        [
            "x", "x^2", "x^3", "x^4", "x^5", "x^6", "x^7", "x'", "xb_acc"
        ]
    );
    let lib = Library::parse("(x2-x1)^1..7", &["x1", "x2"]).unwrap();
    assert_eq!(lib.len(), 7);
    assert_eq!(lib.names()[6], "(x2-x1)^7");
    // Ranges in products expand to the Cartesian product; duplicates vanish.
    let lib = Library::parse("x^1..2*x'^1..3, x*x', x'*x", &["x"]).unwrap();
    assert_eq!(lib.len(), 6);
    // Degree-3 monomials in three variables: C(5,2) = 10.
    let lib = Library::parse("poly(x1, x2, x1'; 3..3)", &["x1", "x2"]).unwrap();
    assert_eq!(lib.len(), 10);
    assert!(lib.terms().iter().all(|t| t.degree() == Some(3)));
}

fn parse_err(spec: &str, dofs: &[&str]) -> (usize, String, String) {
    match Library::parse(spec, dofs) {
        Err(LibraryError::Parse {
            position,
            found,
            expected,
            ..
        }) => (position, found, expected),
        other => panic!("expected a parse error for {spec:?}, got {other:?}"),
    }
}

#[test]
fn bad_specs_name_the_token() {
    let (pos, found, _) = parse_err("x^1..7, x', $", &["x"]);
    assert_eq!((pos, found.as_str()), (12, "'$'"));
    let (pos, found, exp) = parse_err("x^", &["x"]);
    assert_eq!((pos, found.as_str()), (2, "end of input"));
    assert!(exp.contains("power"));
    let (_, found, exp) = parse_err("xb'", &["x"]);
    assert!(found.contains("xb"));
    assert!(exp.contains("xb_vel"), "{exp}");
    let (_, found, _) = parse_err("x^7..3", &["x"]);
    assert_eq!(found, "'3'");
    let (_, _, exp) = parse_err("tanh(x')", &["x"]);
    assert!(exp.contains("eps"));
    let (_, found, _) = parse_err("tanh(x'/0)", &["x"]);
    assert_eq!(found, "'0'");
    let (_, found, _) = parse_err("(xb-x)", &["x"]);
    assert_eq!(found, "'xb'");
    let (pos, found, _) = parse_err("x x'", &["x"]);
    assert_eq!((pos, found.as_str()), (2, "'x'"));
    parse_err("", &["x"]);
    parse_err("x,", &["x"]);
    parse_err("x^0", &["x"]);
    parse_err("poly(x; 0..)", &["x"]);
    let msg = Library::parse("x, y$", &["x"]).unwrap_err().to_string();
    assert!(msg.contains("position 4") && msg.contains("'$'"), "{msg}");
    // Single terms reject ranges.
    assert!(Term::parse("x^1..3", &["x"]).is_err());
    assert!(Term::parse("poly(x; 1..2)", &["x"]).is_err());
    // Bad DOF declarations.
    assert!(Library::parse("x", &["x", "x"]).is_err());
    assert!(Library::parse("x", &["x'"]).is_err());
}

#[test]
fn term_properties() {
    let d = ["x", "x1", "x2"];
    let t = |s: &str| Term::parse(s, &d).unwrap();
    assert!(t("x^5").is_position_only("x"));
    assert!(t("1").is_position_only("x"));
    assert!(!t("x^2*x'").is_position_only("x"));
    assert!(!t("x1").is_position_only("x"));
    assert!(t("x^2*x'").is_linear_in_velocity());
    assert!(t("x1*x2'").is_linear_in_velocity());
    assert!(!t("x'^3").is_linear_in_velocity());
    assert!(!t("x'*abs(x')").is_linear_in_velocity());
    assert!(!t("tanh(x'/0.01)").is_linear_in_velocity());
    assert!(!t("xb_acc*x'").is_linear_in_velocity());
    assert!(!t("x^2").is_linear_in_velocity());

    let e = t("x^3*x'").exact_derivative().unwrap();
    assert_eq!(e.antiderivative(), t("x^4"));
    assert_eq!(e.scale, 0.25);
    let e = t("x'").exact_derivative().unwrap();
    assert_eq!((e.antiderivative(), e.scale), (t("x"), 1.0));
    let e = t("(x2-x1)^2*(x2-x1)'").exact_derivative().unwrap();
    assert_eq!(e.antiderivative(), t("(x2-x1)^3"));
    assert!(t("x1*x2'").exact_derivative().is_none());
    assert!(t("x^2").exact_derivative().is_none());
    assert!(t("x'^2").exact_derivative().is_none());
}

/// One-sided stops: `below(v, c) = max(0, c − v)`, `above(v, c) = max(0, v − c)`, with a signed
/// position; malformed calls are errors that say what was expected.
#[test]
fn stops_parse_evaluate_and_refuse_bad_input() {
    let t = Term::parse("below(x, -0.25) * x'", &DOFS).unwrap();
    assert_eq!(t.to_string(), "below(x, -0.25)*x'");
    let f = &t.factors()[0];
    assert_eq!(
        (f.apply(-1.0), f.apply(-0.25), f.apply(0.5)),
        (0.75, 0.0, 0.0)
    );
    assert_eq!((f.derivative(-1.0), f.derivative(0.5)), (-1.0, 0.0));
    let a = Term::parse("above((x2-x1), 1.5)", &DOFS).unwrap();
    assert_eq!(a.to_string(), "above((x2-x1), 1.5)");
    let g = &a.factors()[0];
    assert_eq!((g.apply(2.0), g.apply(1.0)), (0.5, 0.0));
    assert_eq!((g.derivative(2.0), g.derivative(1.0)), (1.0, 0.0));
    // Distinct positions are distinct terms, in a canonical order.
    let lib = Library::parse("below(x, 0.1), below(x, -0.1), below(x, 0.1)", &DOFS).unwrap();
    assert_eq!(lib.len(), 2);
    for bad in ["below(x)", "below(x, )", "above(x 1)", "below(x, 1"] {
        let e = Library::parse(bad, &DOFS).unwrap_err().to_string();
        assert!(e.contains("expected"), "{bad}: {e}");
    }
}

/// Internal states: `maxwell(v', tau)`, `bouc_wen(v', a, b[, nu])`, `dahl(v', kappa)` parse with
/// signed parameters, print back (ν = 1 omitted), evaluate along a record from rest, and bad
/// calls are errors naming what was expected.
#[test]
fn internal_states_parse_evaluate_and_refuse_bad_input() {
    let t = Term::parse("bouc_wen(x', 800, -1100)", &DOFS).unwrap();
    assert_eq!(t.to_string(), "bouc_wen(x', 800, -1100)");
    assert_eq!(
        t.states(),
        vec![(
            &Var::Vel("x".into()),
            &StateLaw::BoucWen {
                a: 800.0,
                b: -1100.0,
                nu: 1.0
            }
        )]
    );
    assert!(t.uses_velocity() && !t.is_linear_in_velocity() && t.exact_derivative().is_none());
    let t2 = Term::parse("bouc_wen((x2-x1)', 3, 1, 2) * x", &DOFS).unwrap();
    assert_eq!(t2.to_string(), "x*bouc_wen((x2-x1)', 3, 1, 2)");
    assert_eq!(
        Term::parse("maxwell(x1', 0.35)", &DOFS)
            .unwrap()
            .to_string(),
        "maxwell(x1', 0.35)"
    );
    assert_eq!(
        Term::parse("dahl( x' , 2.5e3 )", &DOFS)
            .unwrap()
            .to_string(),
        "dahl(x', 2500)"
    );
    // Along a record: the law integrated from rest on the velocity column.
    let n = 400;
    let dt = 0.01;
    let time: Vec<f64> = (0..n).map(|k| k as f64 * dt).collect();
    let v: Vec<f64> = time.iter().map(|s| (3.0 * s).cos()).collect();
    let x: Vec<f64> = time.iter().map(|s| (3.0 * s).sin() / 3.0).collect();
    let rec = tfs_data::Record::new(
        "r",
        time,
        vec![("x".into(), x.clone()), ("x'".into(), v.clone())],
    )
    .unwrap();
    let law = StateLaw::Dahl { kappa: 20.0 };
    let want = law.integrate(&v, dt);
    let got =
        tfs_library::evaluate_term(&Term::parse("x*dahl(x', 20)", &DOFS).unwrap(), &rec).unwrap();
    for k in 0..n {
        assert_eq!(got[k], x[k] * want[k]);
    }
    assert_eq!(want[0], 0.0);
    // Dahl saturates at 1 after a long slide in one direction.
    assert!(want.iter().all(|z| z.abs() <= 1.0 + 1e-9));
    for (bad, says) in [
        ("maxwell(x, 0.3)", "velocity"),
        ("maxwell(xb_acc, 0.3)", "velocity"),
        ("maxwell(x', 0)", "tau"),
        ("maxwell(x', -1)", "tau"),
        ("bouc_wen(x', 1)", "bouc_wen(v', a, b)"),
        ("bouc_wen(x', 1, 2, 0.5)", "nu"),
        ("dahl(x')", "dahl(v', kappa)"),
        ("dahl(x', 3", "')'"),
    ] {
        let e = Library::parse(bad, &DOFS).unwrap_err().to_string();
        assert!(e.contains(says), "{bad}: {e}");
    }
    // Distinct laws or parameters are distinct terms.
    let lib = Library::parse(
        "maxwell(x', 0.1), maxwell(x', 0.2), maxwell(x', 0.1), dahl(x', 0.1)",
        &DOFS,
    )
    .unwrap();
    assert_eq!(lib.len(), 3);
}

/// A column whose header has units or dashes is named in a spec by quoting it; the term prints
/// quoted and parses back to the same column; an unclosed or empty quote is an error.
#[test]
fn quoted_column_names() {
    let lib = Library::parse("x^1..3, x', \"acc [m/s2]\", abs(\"base-acc\")", &["x"]).unwrap();
    let cols = lib.required_columns();
    assert!(cols.contains(&"acc [m/s2]".to_string()), "{cols:?}");
    assert!(cols.contains(&"base-acc".to_string()), "{cols:?}");
    let t = Term::parse("\"acc [m/s2]\"", &["x"]).unwrap();
    assert_eq!(t.to_string(), "\"acc [m/s2]\"");
    assert_eq!(Term::parse(&t.to_string(), &["x"]).unwrap(), t);
    for bad in ["\"acc", "\"\"", "x, \"  \""] {
        let e = Library::parse(bad, &["x"]).unwrap_err().to_string();
        assert!(e.contains("quote"), "{bad}: {e}");
    }
}
