//! `Compressed::from_chunks` (rows written a chunk at a time) against `from_rows` of the same
//! rows stacked: the same factor to the bit, through the structured update, the dense QR for
//! huge entries and the dense QR for fewer rows than columns; errors name the row.

use faer::{ColRef, Mat, MatMut};
use tfs_regress::{Compressed, RegressError};

/// A tall `[A | b]` with monomial-like columns (scales from 1 to ~1e3), `m` rows.
fn rows(m: usize, n: usize, big: f64) -> (Mat<f64>, Vec<f64>) {
    let a = Mat::from_fn(m, n, |i, j| {
        let x = ((i * 7 + 3) as f64 * 0.013).sin() * 1.7;
        let v = x.powi(j as i32 % 8) * (1.0 + 0.1 * ((i * j) as f64).cos());
        if j == n - 1 { v * big } else { v }
    });
    let b = (0..m).map(|i| (i as f64 * 0.021).cos()).collect();
    (a, b)
}

/// `from_chunks` copying from `(a, b)`, counting how often each chunk was asked for.
fn chunked(a: &Mat<f64>, b: &[f64]) -> (Result<Compressed, RegressError>, Vec<usize>) {
    let n = a.ncols();
    let mut asked = Vec::new();
    let c = Compressed::from_chunks(n, a.nrows(), |start, mut chunk: MatMut<'_, f64>| {
        let k = chunk.nrows();
        asked.push(start);
        chunk
            .as_mut()
            .get_mut(.., ..n)
            .copy_from(a.as_ref().subrows(start, k));
        chunk
            .col_mut(n)
            .copy_from(ColRef::from_slice(&b[start..start + k]));
        Ok::<(), RegressError>(())
    });
    (c, asked)
}

#[test]
fn chunks_give_the_factor_of_the_stacked_rows_to_the_bit() {
    // Several chunks and a short last one; a chunk taller than a panel; one short chunk.
    for (m, n) in [(5000, 36), (2100, 9), (300, 20), (40, 5)] {
        let (a, b) = rows(m, n, 1.0);
        let whole = Compressed::from_rows(a.as_ref(), &b).unwrap();
        let (c, asked) = chunked(&a, &b);
        assert_eq!(c.unwrap(), whole, "m = {m}, n = {n}");
        assert_eq!(asked.len(), m.div_ceil(2048), "each chunk once");
    }
}

#[test]
fn huge_entries_and_few_rows_take_the_dense_qr_with_the_same_result() {
    // Entries of 1e150 are declined by the structured update: the chunk is asked for again
    // and stacked under the factor.
    let (a, b) = rows(3000, 6, 1e150);
    let whole = Compressed::from_rows(a.as_ref(), &b).unwrap();
    let (c, asked) = chunked(&a, &b);
    assert_eq!(c.unwrap(), whole);
    assert_eq!(asked, vec![0, 0, 2048, 2048]);
    // Fewer rows than columns.
    let (a, b) = rows(4, 9, 1.0);
    assert_eq!(
        chunked(&a, &b).0.unwrap(),
        Compressed::from_rows(a.as_ref(), &b).unwrap()
    );
}

#[test]
fn a_non_finite_entry_is_named_by_its_row_and_column() {
    let (mut a, mut b) = rows(5000, 4, 1.0);
    a[(4100, 2)] = f64::NAN;
    match chunked(&a, &b).0 {
        Err(RegressError::NonFinite { what, row, col, .. }) => {
            assert_eq!((what, row, col), ("A", 4100, 2))
        }
        other => panic!("{other:?}"),
    }
    a[(4100, 2)] = 1.0;
    b[17] = f64::INFINITY;
    match chunked(&a, &b).0 {
        Err(RegressError::NonFinite { what, row, .. }) => assert_eq!((what, row), ("b", 17)),
        other => panic!("{other:?}"),
    }
    assert!(matches!(
        Compressed::from_chunks(0, 10, |_, _| Ok::<(), RegressError>(())),
        Err(RegressError::Empty { .. })
    ));
}
