//! CSV reading, validation messages and round trips.

use proptest::prelude::*;
use tfs_data::{
    CsvOptions, DataError, Record, Saturation, check_consistent, check_record, from_reader,
    read_csv, read_csv_checked, read_csv_with, write_csv,
};

/// `n` uniformly sampled rows of `t,x,xb_acc` with smooth, non-constant, unclipped signals.
fn good_csv(n: usize) -> String {
    let mut s = String::from("t,x,xb_acc\n");
    for i in 0..n {
        let t = i as f64 * 0.01;
        s.push_str(&format!(
            "{t},{},{}\n",
            (3.0 * t).sin() + 0.1 * t,
            (5.0 * t).cos() * (1.0 + t)
        ));
    }
    s
}

fn read(text: &str, opts: &CsvOptions) -> Result<Record, DataError> {
    from_reader("bad.csv", text.as_bytes(), opts)
}

fn err(text: &str, opts: &CsvOptions) -> (DataError, String) {
    let e = read(text, opts).expect_err("input should be rejected");
    let m = e.to_string();
    assert!(!m.contains('\n'), "message must be one line: {m}");
    assert!(m.starts_with("bad.csv"), "message must name the file: {m}");
    (e, m)
}

/// Replaces line `line` (1-based) of `text`.
fn with_line(text: &str, line: usize, new: &str) -> String {
    let mut v: Vec<String> = text.lines().map(str::to_string).collect();
    v[line - 1] = new.to_string();
    v.join("\n") + "\n"
}

#[test]
fn good_file_reads() {
    let r = read(
        &good_csv(40),
        &CsvOptions::default().require(["x", "xb_acc"]),
    )
    .unwrap();
    assert_eq!(r.len(), 40);
    assert_eq!(r.names(), ["x", "xb_acc"]);
    assert!((r.dt() - 0.01).abs() < 1e-12);
    assert_eq!(r.source(), "bad.csv");
}

#[test]
fn empty_file() {
    let (e, m) = err("", &CsvOptions::default());
    assert!(matches!(e, DataError::NoHeader { .. }));
    assert!(
        m.contains("row 1") && m.contains("empty") && m.contains("header"),
        "{m}"
    );
}

#[test]
fn header_missing() {
    let text = good_csv(20).lines().skip(1).collect::<Vec<_>>().join("\n");
    let (e, m) = err(&text, &CsvOptions::default());
    assert!(matches!(e, DataError::NoHeader { .. }));
    assert!(m.contains("row 1") && m.contains("add a header"), "{m}");
}

#[test]
fn missing_time_column_suggests_case_match() {
    let text = good_csv(20).replacen("t,", "T,", 1);
    let (e, m) = err(&text, &CsvOptions::default());
    assert_eq!(e.column(), Some("t"));
    assert_eq!(e.row(), Some(1));
    assert!(
        m.contains("missing time column") && m.contains("did you mean 'T'?"),
        "{m}"
    );
    assert!(m.contains("[T, x, xb_acc]"), "{m}");
}

#[test]
fn custom_time_column() {
    let text = good_csv(20).replacen("t,", "time,", 1);
    assert!(read(&text, &CsvOptions::default().time_column("time")).is_ok());
    let (_, m) = err(&text, &CsvOptions::default().time_column("tau"));
    assert!(
        m.contains("column 'tau'") && m.contains("time column"),
        "{m}"
    );
}

#[test]
fn missing_required_column_suggests_close_name() {
    let text = good_csv(20).replacen("xb_acc", "xbacc", 1);
    let (e, m) = err(&text, &CsvOptions::default().require(["x", "xb_acc"]));
    assert!(matches!(e, DataError::MissingColumn { .. }));
    assert!(m.contains("row 1, column 'xb_acc'"), "{m}");
    assert!(m.contains("did you mean 'xbacc'?"), "{m}");
    assert!(m.contains("[t, x, xbacc]"), "{m}");
}

#[test]
fn missing_required_column_without_close_name() {
    let (_, m) = err(&good_csv(20), &CsvOptions::default().require(["force"]));
    assert!(
        m.contains("column 'force'") && !m.contains("did you mean"),
        "{m}"
    );
    assert!(m.contains("add the column"), "{m}");
}

#[test]
fn duplicate_column() {
    let text = good_csv(20).replacen("t,x,xb_acc", "t,x,x", 1);
    let (e, m) = err(&text, &CsvOptions::default());
    assert!(matches!(
        e,
        DataError::DuplicateColumn {
            first: 2,
            second: 3,
            ..
        }
    ));
    assert!(
        m.contains("row 1, column 'x'") && m.contains("twice"),
        "{m}"
    );
}

#[test]
fn ragged_row() {
    let text = with_line(&good_csv(20), 6, "0.04,1.0");
    let (e, m) = err(&text, &CsvOptions::default());
    assert!(matches!(
        e,
        DataError::Ragged {
            row: 6,
            expected: 3,
            found: 2,
            ..
        }
    ));
    assert!(
        m.contains("row 6") && m.contains("2 cells") && m.contains("3"),
        "{m}"
    );
}

#[test]
fn non_numeric_cell_is_quoted() {
    let text = with_line(&good_csv(20), 9, "0.07,abc,1.0");
    let (e, m) = err(&text, &CsvOptions::default());
    assert_eq!(e.row(), Some(9));
    assert!(
        m.contains("row 9, column 'x'") && m.contains("\"abc\""),
        "{m}"
    );
}

#[test]
fn empty_cell_is_non_numeric() {
    let text = with_line(&good_csv(20), 4, "0.02,,1.0");
    let (_, m) = err(&text, &CsvOptions::default());
    assert!(m.contains("row 4, column 'x'") && m.contains("\"\""), "{m}");
}

#[test]
fn nan_and_inf_rejected() {
    for bad in ["NaN", "inf", "-Infinity"] {
        let text = with_line(&good_csv(20), 5, &format!("0.03,0.5,{bad}"));
        let (e, m) = err(&text, &CsvOptions::default());
        assert!(matches!(e, DataError::NonFinite { .. }), "{m}");
        assert!(
            m.contains("row 5, column 'xb_acc'") && m.contains(bad),
            "{m}"
        );
    }
}

#[test]
fn non_increasing_time() {
    // line 8 holds sample 6 (t = 0.06); set it equal to the previous time
    let text = with_line(&good_csv(20), 8, "0.05,0.1,0.2");
    let (e, m) = err(&text, &CsvOptions::default());
    assert!(
        matches!(e, DataError::NonIncreasingTime { row: 8, .. }),
        "{m}"
    );
    assert!(
        m.contains("row 8, column 't'") && m.contains("does not increase"),
        "{m}"
    );
}

#[test]
fn time_gap_names_row_and_time() {
    // drop sample 10 (line 12): the step into line 12 (t = 0.11) is 2 dt
    let full = good_csv(30);
    let mut v: Vec<&str> = full.lines().collect();
    v.remove(11);
    let text = v.join("\n");
    let (e, m) = err(&text, &CsvOptions::default());
    assert!(matches!(e, DataError::TimeGap { row: 12, .. }), "{m}");
    assert!(
        m.contains("row 12, column 't'") && m.contains("t = 0.11"),
        "{m}"
    );
    assert!(m.contains("2.00 x"), "{m}");
}

#[test]
fn non_uniform_time_reports_worst_row() {
    let mut text = String::from("t,x\n");
    for i in 0..30 {
        let mut t = i as f64 * 0.01;
        if i == 7 {
            t += 0.0003; // 3 % jitter: steps into/out of line 9 deviate 3 %
        }
        if i >= 20 {
            t += 0.0012; // one step of 1.12 dt: worst, step into line 22
        }
        text.push_str(&format!("{t},{}\n", (i as f64).sin()));
    }
    let (e, m) = err(&text, &CsvOptions::default());
    assert!(
        matches!(e, DataError::NonUniformTime { row: 22, .. }),
        "{m}"
    );
    assert!(
        m.contains("row 22, column 't'") && m.contains("not uniformly sampled"),
        "{m}"
    );
    // a looser tolerance accepts it
    let opts = CsvOptions {
        time_tolerance: 0.2,
        ..CsvOptions::default()
    };
    assert!(read(&text, &opts).is_ok());
}

#[test]
fn too_few_rows() {
    let (e, m) = err(&good_csv(10), &CsvOptions::default());
    assert!(matches!(
        e,
        DataError::TooFewRows {
            rows: 10,
            min: 16,
            last_row: 11,
            ..
        }
    ));
    assert!(m.contains("only 10 data rows") && m.contains("16"), "{m}");
    assert!(read(&good_csv(10), &CsvOptions::default().min_rows(5)).is_ok());
}

#[test]
fn constant_required_column() {
    let mut text = String::from("t,x,xb_acc\n");
    for i in 0..20 {
        text.push_str(&format!("{},{},0.0\n", i as f64 * 0.01, (i as f64).sin()));
    }
    let (e, m) = err(&text, &CsvOptions::default().require(["xb_acc"]));
    assert!(matches!(e, DataError::Constant { .. }));
    assert!(
        m.contains("row 2, column 'xb_acc'") && m.contains("constant"),
        "{m}"
    );
    // not required: accepted
    assert!(read(&text, &CsvOptions::default().require(["x"])).is_ok());
}

fn clipped_csv() -> String {
    let mut text = String::from("t,x\n");
    for i in 0..200 {
        let v = (2.0 * std::f64::consts::PI * i as f64 / 50.0).sin() * 1.5;
        text.push_str(&format!("{},{}\n", i as f64 * 0.01, v.min(1.0)));
    }
    text
}

#[test]
fn saturated_channel_is_error_then_warning() {
    let text = clipped_csv();
    let (e, m) = err(&text, &CsvOptions::default());
    let DataError::Saturated {
        count,
        run,
        value,
        row,
        ..
    } = &e
    else {
        panic!("expected Saturated, got {m}")
    };
    assert_eq!(*value, 1.0);
    assert!(*count >= 3 && *run >= 3);
    // the first clipped sample: sin(2πi/50)·1.5 ≥ 1 first at i = 6 → line 8
    assert_eq!(*row, 8);
    assert!(
        m.contains("column 'x'") && m.contains("clipped") && m.contains("maximum"),
        "{m}"
    );
    // downgrade to a warning
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("clip.csv");
    std::fs::write(&p, &text).unwrap();
    let (r, w) = read_csv_checked(&p, &CsvOptions::default().saturation(Saturation::Warn)).unwrap();
    assert_eq!(r.len(), 200);
    assert_eq!(w.len(), 1);
    assert!(matches!(w[0], DataError::Saturated { .. }));
    assert!(read_csv_with(&p, &CsvOptions::default().saturation(Saturation::Allow)).is_ok());
}

#[test]
fn isolated_extremes_are_not_saturation() {
    // a pure sine sampled so its maximum occurs several times but never 3 in a row
    let mut text = String::from("t,x\n");
    for i in 0..200 {
        text.push_str(&format!(
            "{},{}\n",
            i as f64 * 0.01,
            [0.0, 1.0, 0.0, -1.0][i % 4]
        ));
    }
    assert!(read(&text, &CsvOptions::default()).is_ok());
}

#[test]
fn comments_and_line_numbers() {
    // a comment line shifts the data; reported rows are still file line numbers
    let text = format!("# rig 3\n{}", with_line(&good_csv(20), 5, "0.03,zz,1"));
    let (e, _) = err(&text, &CsvOptions::default());
    assert_eq!(e.row(), Some(6));
}

#[test]
fn missing_file_names_path() {
    let e = read_csv("/nonexistent/dir/data.csv").unwrap_err();
    let m = e.to_string();
    assert!(
        m.contains("/nonexistent/dir/data.csv") && m.contains("cannot read"),
        "{m}"
    );
}

#[test]
fn inconsistent_records() {
    let t: Vec<f64> = (0..20).map(|i| i as f64 * 0.01).collect();
    let x: Vec<f64> = t.iter().map(|t| t.sin()).collect();
    let a = Record::new("a.csv", t.clone(), vec![("x".into(), x.clone())]).unwrap();
    let b = Record::new("b.csv", t.clone(), vec![("y".into(), x.clone())]).unwrap();
    let m = check_consistent(&[a.clone(), b]).unwrap_err().to_string();
    assert!(
        m.contains("a.csv") && m.contains("b.csv") && m.contains("columns differ"),
        "{m}"
    );
    assert!(m.contains("[x]") && m.contains("[y]"), "{m}");
    let t2: Vec<f64> = (0..20).map(|i| i as f64 * 0.01 * (1.0 + 1e-5)).collect();
    let c = Record::new("c.csv", t2, vec![("x".into(), x.clone())]).unwrap();
    let m = check_consistent(&[a.clone(), c]).unwrap_err().to_string();
    assert!(
        m.contains("a.csv and c.csv") && m.contains("sampling intervals differ"),
        "{m}"
    );
    let t3: Vec<f64> = (0..20).map(|i| 5.0 + i as f64 * 0.01).collect();
    let d = Record::new("d.csv", t3, vec![("x".into(), x)]).unwrap();
    assert!(check_consistent(&[a, d]).is_ok());
}

#[test]
fn write_rejects_nan_with_row_and_column() {
    let t: Vec<f64> = (0..5).map(|i| i as f64).collect();
    let r = Record::new(
        "r",
        t,
        vec![("x".into(), vec![0.0, 1.0, f64::NAN, 2.0, 3.0])],
    )
    .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let m = write_csv(dir.path().join("o.csv"), &r)
        .unwrap_err()
        .to_string();
    assert!(m.contains("row 4, column 'x'"), "{m}");
}

#[test]
fn round_trip_file() {
    let r = read(&good_csv(50), &CsvOptions::default()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("rt.csv");
    write_csv(&p, &r).unwrap();
    let back = read_csv(&p).unwrap();
    assert_eq!(back.t(), r.t());
    assert_eq!(back.names(), r.names());
    for n in r.names() {
        assert_eq!(back.column(n), r.column(n));
    }
}

#[test]
fn ndarray_slice_offsets() {
    let t: Vec<f64> = (0..6).map(|i| i as f64 * 0.5).collect();
    let x = vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0];
    let y = vec![10.0, 10.0, 13.0, 13.0, 16.0, 16.0];
    let mut r = Record::new(
        "r",
        t.clone(),
        vec![("x".into(), x.clone()), ("y".into(), y.clone())],
    )
    .unwrap();
    let a = r.to_ndarray(&["y", "t"]).unwrap();
    assert_eq!(a.shape(), &[6, 2]);
    assert_eq!(a[[2, 0]], 13.0);
    assert_eq!(a[[5, 1]], 2.5);
    let m = r.to_ndarray(&["z"]).unwrap_err().to_string();
    assert!(m.contains("column 'z'") && m.contains("[x, y]"), "{m}");
    let back = Record::from_ndarray("r", t.clone(), &["y", "tt"], &a).unwrap();
    assert_eq!(back.column("tt").unwrap(), &t[..]);
    assert!(Record::from_ndarray("r", t.clone(), &["y"], &a).is_err());

    let s = r.slice(2..5).unwrap();
    assert_eq!(s.t(), &[1.0, 1.5, 2.0]);
    assert_eq!(s.column("y").unwrap(), &[13.0, 13.0, 16.0]);
    assert!(r.slice(3..9).is_err());

    let off = r.remove_offsets(&["x", "y"]).unwrap();
    assert_eq!(off, vec![("x".to_string(), 3.5), ("y".to_string(), 13.0)]);
    let sum: f64 = r.column("x").unwrap().iter().sum();
    assert!(sum.abs() < 1e-12);
    assert_eq!(r.column("y").unwrap()[0], -3.0);
    assert!(r.remove_offsets(&["q"]).is_err());
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]
    #[test]
    fn round_trip_random_finite(
        n in 16usize..60,
        dt_exp in -6i32..2,
        t0 in -1e3f64..1e3,
        seed in proptest::collection::vec(proptest::num::f64::NORMAL | proptest::num::f64::SUBNORMAL | proptest::num::f64::ZERO, 120),
    ) {
        let dt = 10f64.powi(dt_exp) * 1.37;
        let t: Vec<f64> = (0..n).map(|i| t0 + i as f64 * dt).collect();
        let x: Vec<f64> = (0..n).map(|i| seed[i]).collect();
        let y: Vec<f64> = (0..n).map(|i| seed[60 + i]).collect();
        let r = Record::new("p", t, vec![("x".into(), x), ("y".into(), y)]).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("p.csv");
        write_csv(&p, &r).unwrap();
        let opts = CsvOptions { saturation: Saturation::Allow, ..CsvOptions::default() };
        let back = read_csv_with(&p, &opts).unwrap();
        prop_assert_eq!(back.t(), r.t());
        prop_assert_eq!(back.column("x"), r.column("x"));
        prop_assert_eq!(back.column("y"), r.column("y"));
    }
}

/// `t,x` at 3 kHz with the time printed with `decimals` decimals; `jitter(k)` is added to the
/// true sampling time before printing.
fn rounded_time_csv(n: usize, decimals: usize, jitter: impl Fn(usize) -> f64) -> String {
    let mut s = String::from("t,x\n");
    for k in 0..n {
        let t = k as f64 / 3000.0 + jitter(k);
        s.push_str(&format!("{t:.decimals$},{}\n", (0.37 * k as f64).sin()));
    }
    s
}

#[test]
fn rounded_timestamps_are_accepted_and_regridded() {
    // 3 kHz written with 4 decimals: steps are 0.0003 or 0.0004 (±15 % of dt), yet the samples
    // are uniform; the reader puts them back on the grid and warns.
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("rounded.csv");
    let n = 3001;
    std::fs::write(&p, rounded_time_csv(n, 4, |_| 0.0)).unwrap();
    let (r, w) = read_csv_checked(&p, &CsvOptions::default()).unwrap();
    assert_eq!(w.len(), 1, "{w:?}");
    let m = w[0].to_string();
    assert!(
        matches!(w[0], DataError::TimeRounded { .. })
            && m.contains("rounded.csv")
            && m.contains("column 't'"),
        "{m}"
    );
    // The grid fitted to 3001 rounded stamps is k/3000 to far better than the rounding (1e-4,
    // 30 % of a step): within 0.1 % of a step everywhere, dt within 1e-6 relative.
    let dt = 1.0 / 3000.0;
    for (k, t) in r.t().iter().enumerate() {
        assert!((t - k as f64 * dt).abs() < 1e-3 * dt, "row {k}: {t}");
    }
    assert!((r.dt() - dt).abs() < 1e-6 * dt, "{}", r.dt());
}

#[test]
fn rounded_timestamps_with_real_jitter_are_still_refused() {
    // Same printing, but one sample was taken 30 % of a step late: beyond the rounding.
    let text = rounded_time_csv(3001, 4, |k| if k == 1500 { 0.3 / 3000.0 } else { 0.0 });
    let (e, m) = err(&text, &CsvOptions::default());
    assert!(
        matches!(e, DataError::NonUniformTime { row: 1502, .. }),
        "{m}"
    );
}

#[test]
fn exactly_printed_coarse_timestamps_are_not_regridded() {
    // 1 kHz written with 3 decimals is exact (dt is a whole multiple of the resolution).
    let mut s = String::from("t,x\n");
    for k in 0..200 {
        s.push_str(&format!(
            "{:.3},{}\n",
            k as f64 * 1e-3,
            (0.3 * k as f64).sin()
        ));
    }
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("exact.csv");
    std::fs::write(&p, &s).unwrap();
    let (_, w) = read_csv_checked(&p, &CsvOptions::default()).unwrap();
    assert!(w.is_empty(), "{w:?}");
    // and a missing sample is still a gap
    let text = s.replace("0.100,", "#0.100,");
    let (e, _) = err(&text, &CsvOptions::default());
    assert!(matches!(e, DataError::TimeGap { .. }));
}

/// A record built in memory passes the checks a file passes and fails those a file fails, with
/// the row counted from the first sample.
#[test]
fn records_from_arrays_are_checked_like_files() {
    let t: Vec<f64> = (0..100).map(|k| k as f64 * 0.01).collect();
    let x: Vec<f64> = t.iter().map(|t| (5.0 * t).sin()).collect();
    let make = |t: Vec<f64>, x: Vec<f64>| {
        Record::new(
            "arrays",
            t,
            vec![("x".into(), x), ("u".into(), vec![0.5; 100])],
        )
        .unwrap()
    };
    let opts = CsvOptions::default().require(["x"]);
    let (r, w) = check_record(make(t.clone(), x.clone()), &opts).unwrap();
    assert!(w.is_empty() && r.len() == 100);
    // A NaN names the column and the sample's row.
    let mut bad = x.clone();
    bad[41] = f64::NAN;
    let e = check_record(make(t.clone(), bad), &opts).unwrap_err();
    assert!(
        matches!(&e, DataError::NonFinite { row: 42, column, .. } if column == "x"),
        "{e}"
    );
    // A late sample is non-uniform time at its row.
    let mut late = t.clone();
    late[60] += 0.004;
    let e = check_record(make(late, x.clone()), &opts).unwrap_err();
    assert!(matches!(e, DataError::NonUniformTime { .. }), "{e}");
    // A required column must exist and must not be constant.
    let e = check_record(make(t.clone(), x.clone()), &opts.clone().require(["force"])).unwrap_err();
    assert!(e.to_string().contains("'force'"), "{e}");
    let e = check_record(make(t, x), &CsvOptions::default().require(["u"])).unwrap_err();
    assert!(matches!(e, DataError::Constant { .. }), "{e}");
}

#[test]
fn missing_column_of_one_dof_names_a_chain_s_numbered_columns() {
    let text = good_csv(20).replacen("t,x,xb_acc", "t,x1,xb_acc", 1);
    let (_, m) = err(&text, &CsvOptions::default().require(["x", "xb_acc"]));
    assert!(
        m.contains("column 'x'") && !m.contains("did you mean"),
        "{m}"
    );
    assert!(m.contains("the file has 'x1' instead"), "{m}");
    assert!(m.contains("chain"), "{m}");
}

/// Clones share their columns and a write copies only what it changes: a clone whose column is
/// replaced or whose offsets are removed leaves the original's samples as they were, and the
/// original's untouched columns are the very same allocation in the clone (no copy of the
/// record's samples per clone).
#[test]
fn a_clone_shares_columns_and_writes_do_not_reach_the_original() {
    let t = vec![0.0, 0.1, 0.2, 0.3];
    let cols = vec![
        ("x".to_string(), vec![1.0, 2.0, 3.0, 6.0]),
        ("u".to_string(), vec![0.5, 0.5, 1.5, 1.5]),
    ];
    let r = Record::new("r", t, cols).unwrap();
    let mut c = r.clone();
    assert!(std::ptr::eq(r.column("x").unwrap(), c.column("x").unwrap()));
    assert!(std::ptr::eq(r.t(), c.t()));
    c.set_column("u", vec![9.0; 4]).unwrap();
    c.remove_offsets(&["x"]).unwrap();
    assert_eq!(r.column("u").unwrap(), &[0.5, 0.5, 1.5, 1.5]);
    assert_eq!(r.column("x").unwrap(), &[1.0, 2.0, 3.0, 6.0]);
    assert_eq!(c.column("x").unwrap(), &[-2.0, -1.0, 0.0, 3.0]);
    assert_eq!(c.column("u").unwrap(), &[9.0; 4]);
    assert!(std::ptr::eq(r.t(), c.t()));
    assert_ne!(r, c);
}
