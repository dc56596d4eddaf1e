//! `Library::evaluate_rows` (a block of rows into a caller's matrix) against the rows of
//! `Library::evaluate`: the same values to the bit, errors counted in the record's rows.

use faer::Mat;
use tfs_data::Record;
use tfs_library::{ColumnSet, Library, LibraryError};

fn record(n: usize) -> Record {
    let t: Vec<f64> = (0..n).map(|i| i as f64 * 0.005).collect();
    let col = |f: f64| t.iter().map(|&s| (f * s).sin() + 0.3).collect::<Vec<f64>>();
    Record::new(
        "r",
        t.clone(),
        vec![
            ("x1".into(), col(1.3)),
            ("x2".into(), col(0.7)),
            ("xb_acc".into(), col(2.1)),
        ],
    )
    .unwrap()
}

#[test]
fn blocks_of_rows_equal_the_whole_evaluation() {
    let rec = record(3000);
    let mut cols = ColumnSet::new(&rec);
    let v: Vec<f64> = rec.column("x1").unwrap().iter().map(|x| 0.5 * x).collect();
    cols.insert("x1'", v).unwrap();
    let dofs = ["x1".to_string(), "x2".to_string()];
    for spec in [
        "poly(x1, x1'; 0..7), xb_acc",
        "(x2-x1)^1..5, abs(x1)*x1', sign(x1'), xb_acc",
    ] {
        let lib = Library::parse(spec, &dofs).unwrap();
        assert!(lib.is_row_local());
        let whole = lib.evaluate(&cols).unwrap();
        for (a, b) in [(0, 3000), (1, 2049), (2049, 2999), (700, 700)] {
            let mut block = Mat::<f64>::zeros(b - a, lib.len());
            lib.evaluate_rows(&cols, a..b, block.as_mut()).unwrap();
            assert_eq!(
                block,
                whole.as_ref().subrows(a, b - a).to_owned(),
                "{spec} {a}..{b}"
            );
        }
        // A strided block (a view into a taller matrix) gets the same values.
        let mut tall = Mat::<f64>::zeros(500, lib.len() + 1);
        let mut view = tall.as_mut().get_mut(100..400, ..lib.len());
        lib.evaluate_rows(&cols, 10..310, view.as_mut()).unwrap();
        assert_eq!(
            tall.as_ref().get(100..400, ..lib.len()).to_owned(),
            whole.as_ref().subrows(10, 300).to_owned()
        );
    }
}

#[test]
fn errors_name_the_record_row_and_refuse_what_blocks_cannot_do() {
    let mut rec_cols: Vec<(String, Vec<f64>)> = vec![("x1".into(), vec![1.0; 100])];
    rec_cols[0].1[57] = 1e200;
    let t: Vec<f64> = (0..100).map(|i| i as f64 * 0.01).collect();
    let rec = Record::new("r", t, rec_cols).unwrap();
    let dofs = ["x1".to_string()];
    let lib = Library::parse("x1^1..3", &dofs).unwrap();
    let mut block = Mat::<f64>::zeros(50, 3);
    match lib.evaluate_rows(&rec, 50..100, block.as_mut()) {
        Err(LibraryError::NonFinite { term, row }) => {
            assert_eq!((term.as_str(), row), ("x1^2", 57))
        }
        other => panic!("{other:?}"),
    }
    assert!(lib.evaluate_rows(&rec, 60..110, block.as_mut()).is_err());
    let missing = Library::parse("x1, xb_acc", &dofs).unwrap();
    let mut block = Mat::<f64>::zeros(10, 2);
    assert!(matches!(
        missing.evaluate_rows(&rec, 0..10, block.as_mut()),
        Err(LibraryError::MissingColumn { .. })
    ));
    let state = Library::parse("x1, maxwell(x1', 0.1)", &dofs).unwrap();
    assert!(!state.is_row_local());
    assert!(state.evaluate_rows(&rec, 0..10, block.as_mut()).is_err());
}

/// `first_non_finite` (bounds first, evaluation only where a bound is large) finds what
/// evaluating every term finds: the first term in library order and its first row.
#[test]
fn first_non_finite_agrees_with_evaluating_every_term() {
    let t: Vec<f64> = (0..200).map(|i| i as f64 * 0.01).collect();
    let dofs = ["x1".to_string(), "x2".to_string()];
    let lib = Library::parse(
        "x1^1..7, x1', (x2-x1)^1..5, abs(x1)*x1', sign(x1'), below(x1, 0.2)*x1, xb_acc",
        &dofs,
    )
    .unwrap();
    // Largest magnitudes from ordinary to just past the overflow of x1^7 (≈ 2.6e44).
    for (big, row) in [
        (1.0, 50),
        (1e40, 120),
        (1e44, 7),
        (3e44, 199),
        (1e150, 0),
        (1e200, 33),
    ] {
        let x1: Vec<f64> = t
            .iter()
            .enumerate()
            .map(|(i, s)| if i == row { big } else { s.sin() })
            .collect();
        let x2: Vec<f64> = t.iter().map(|s| (0.5 * s).cos()).collect();
        let rec = Record::new(
            "r",
            t.clone(),
            vec![
                ("x1".into(), x1.clone()),
                ("x2".into(), x2),
                ("xb_acc".into(), vec![0.1; 200]),
            ],
        )
        .unwrap();
        let mut cols = ColumnSet::new(&rec);
        cols.insert("x1'", x1.iter().map(|v| 0.5 * v).collect())
            .unwrap();
        let want = lib.terms().iter().enumerate().find_map(|(j, term)| {
            match tfs_library::evaluate_term(term, &cols) {
                Err(LibraryError::NonFinite { row, .. }) => Some((j, row)),
                _ => None,
            }
        });
        assert_eq!(lib.first_non_finite(&cols), want, "largest |x1| = {big:e}");
        if big >= 3e44 {
            assert!(want.is_some(), "x1^7 of {big:e} overflows");
        }
    }
}
