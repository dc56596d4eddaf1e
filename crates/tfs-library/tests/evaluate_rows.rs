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
