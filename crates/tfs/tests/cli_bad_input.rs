//! The CLI's answer to bad input: exit code 2 and one line on stderr naming the file, the row or
//! column, and what to do — never a panic.

mod common;
use common::assert_fails;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn tfs(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_tfs"))
        .args(args)
        .output()
        .expect("the tfs binary runs")
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// A valid record of `n` rows: a small oscillation under a sine base acceleration.
fn good_csv(n: usize) -> String {
    let mut s = String::from("t,x,xb_acc\n");
    for k in 0..n {
        let t = 0.01 * k as f64;
        s.push_str(&format!(
            "{t},{},{}\n",
            0.1 * (2.0 * t).sin(),
            (3.0 * t).cos()
        ));
    }
    s
}

fn identify(file: &Path) -> Output {
    tfs(&[
        "identify",
        file.to_str().unwrap(),
        "--method",
        "sindy",
        "--library",
        "x, x', xb_acc",
    ])
}

#[test]
fn missing_column_is_named_with_a_suggestion() {
    let dir = tempfile::tempdir().unwrap();
    let f = write(
        dir.path(),
        "a.csv",
        &good_csv(64).replace("xb_acc", "xb_ac"),
    );
    assert_fails(&identify(&f), &["a.csv", "xb_acc", "xb_ac"]);
}

#[test]
fn non_numeric_cell_names_row_and_column() {
    let dir = tempfile::tempdir().unwrap();
    let mut text = good_csv(64);
    text = text.replacen("\n0.05,", "\n0.05,abc", 1);
    let f = write(dir.path(), "b.csv", &text);
    let out = identify(&f);
    assert_fails(&out, &["b.csv", "row 7"]);
}

#[test]
fn nan_cell_is_rejected() {
    let dir = tempfile::tempdir().unwrap();
    let mut lines: Vec<String> = good_csv(64).lines().map(String::from).collect();
    lines[10] = "0.09,NaN,1.0".into();
    let f = write(dir.path(), "c.csv", &(lines.join("\n") + "\n"));
    assert_fails(&identify(&f), &["c.csv", "row 11", "x"]);
}

#[test]
fn non_increasing_time_is_rejected() {
    let dir = tempfile::tempdir().unwrap();
    let mut lines: Vec<String> = good_csv(64).lines().map(String::from).collect();
    lines[20] = lines[19].clone();
    let f = write(dir.path(), "d.csv", &(lines.join("\n") + "\n"));
    assert_fails(&identify(&f), &["d.csv", "row 21", "t"]);
}

#[test]
fn non_uniform_time_is_rejected() {
    let dir = tempfile::tempdir().unwrap();
    let mut s = String::from("t,x,xb_acc\n");
    let mut t = 0.0;
    for k in 0..64 {
        s.push_str(&format!(
            "{t},{},{}\n",
            (0.3 * k as f64).sin(),
            (0.2 * k as f64).cos()
        ));
        t += if k == 30 { 0.0125 } else { 0.01 };
    }
    let f = write(dir.path(), "e.csv", &s);
    assert_fails(&identify(&f), &["e.csv", "t"]);
}

#[test]
fn too_few_rows_is_rejected() {
    let dir = tempfile::tempdir().unwrap();
    let f = write(dir.path(), "f.csv", &good_csv(5));
    assert_fails(&identify(&f), &["f.csv", "rows"]);
}

#[test]
fn constant_signal_is_rejected() {
    let dir = tempfile::tempdir().unwrap();
    let mut s = String::from("t,x,xb_acc\n");
    for k in 0..64 {
        s.push_str(&format!(
            "{},{},0.5\n",
            0.01 * k as f64,
            (0.3 * k as f64).sin()
        ));
    }
    let f = write(dir.path(), "g.csv", &s);
    assert_fails(&identify(&f), &["g.csv", "xb_acc", "constant"]);
}

#[test]
fn mismatched_records_are_rejected() {
    let dir = tempfile::tempdir().unwrap();
    let a = write(dir.path(), "h1.csv", &good_csv(64));
    let mut s = String::from("t,x,xb_acc\n");
    for k in 0..64 {
        let t = 0.02 * k as f64;
        s.push_str(&format!("{t},{},{}\n", (0.3 * t).sin(), (0.7 * t).cos()));
    }
    let b = write(dir.path(), "h2.csv", &s);
    let out = tfs(&[
        "identify",
        a.to_str().unwrap(),
        b.to_str().unwrap(),
        "--method",
        "sindy",
        "--library",
        "x, x', xb_acc",
    ]);
    assert_fails(&out, &["h1.csv", "h2.csv"]);
}

#[test]
fn missing_file_is_named() {
    let out = identify(Path::new("/nonexistent/data.csv"));
    assert_fails(&out, &["/nonexistent/data.csv"]);
}

#[test]
fn bad_library_spec_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let f = write(dir.path(), "i.csv", &good_csv(64));
    let out = tfs(&["identify", f.to_str().unwrap(), "--library", "x^^2, x'"]);
    assert_fails(&out, &["x^^2"]);
}

#[test]
fn model_file_with_wrong_format_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let m = write(
        dir.path(),
        "m.json",
        r#"{"format": "other/9", "dofs": ["x"], "equations": []}"#,
    );
    let f = write(dir.path(), "j.csv", &good_csv(64));
    let out = tfs(&[
        "compare",
        "--model",
        m.to_str().unwrap(),
        f.to_str().unwrap(),
    ]);
    assert_fails(&out, &["m.json", "format"]);
}

#[test]
fn bad_grid_flag_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let m = write(
        dir.path(),
        "m.json",
        r#"{"format":"tfs-model/1","dofs":["x"],"inputs":[],"equations":[{"dof":"x","terms":[{"term":"x'","coef":-1.0},{"term":"x","coef":-1.0}]}],"method":"test"}"#,
    );
    let out = tfs(&["basin", "--model", m.to_str().unwrap(), "--grid", "20by20"]);
    assert_fails(&out, &["--grid", "20by20"]);
}

/// A rig record whose input header carries units: `x'' = -3 x - 0.2 x' - acc` exactly.
fn rig_csv(input: &str) -> String {
    let mut s = format!("t,x,{input}\n");
    for k in 0..2000 {
        let t = 0.01 * k as f64;
        let x = 0.1 * (2.0 * t).sin() + 0.05 * (5.0 * t).sin();
        let v = 0.2 * (2.0 * t).cos() + 0.25 * (5.0 * t).cos();
        let a = -0.4 * (2.0 * t).sin() - 1.25 * (5.0 * t).sin();
        s.push_str(&format!("{t},{x},{}\n", -(a + 3.0 * x + 0.2 * v)));
    }
    s
}

/// Headers with units or dashes are column names: a library spec names them in double quotes
/// (the model prints and reads them back so), and a column left out is named with the reason
/// (it was dropped silently, and identify then said "nothing identified").
#[test]
fn rig_headers_with_units_are_named_and_usable() {
    let dir = tempfile::tempdir().unwrap();
    for header in ["acc [m/s2]", "base-acc"] {
        let f = write(dir.path(), "rig.csv", &rig_csv(header));
        let o = tfs(&["identify", f.to_str().unwrap()]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            err.contains(&format!("column '{header}' not used")) && err.contains("--library"),
            "{err}"
        );
        let out = dir.path().join("m.json");
        let lib = format!("x, x', \"{header}\"");
        let o = tfs(&[
            "identify",
            f.to_str().unwrap(),
            "--method",
            "sindy",
            "--library",
            &lib,
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let m = tfs::library::Model::from_path(&out).unwrap();
        assert_eq!(m.inputs, [header]);
        let c = tfs(&[
            "compare",
            "--model",
            out.to_str().unwrap(),
            f.to_str().unwrap(),
        ]);
        assert!(c.status.success(), "{}", String::from_utf8_lossy(&c.stderr));
    }
}

/// Messages that misled: each names the file or flag the user gave and what to do.
#[test]
fn messages_name_what_the_user_gave() {
    let dir = tempfile::tempdir().unwrap();
    let p = |f: &Path| f.to_str().unwrap().to_string();
    // Too short for identify: the file, not an internal half 'f.csv#1'; no option to lower.
    let short = write(dir.path(), "short.csv", &good_csv(100));
    let o = tfs(&["identify", &p(&short)]);
    assert_fails(&o, &["short.csv", "100 data rows", "128"]);
    assert!(!String::from_utf8_lossy(&o.stderr).contains("#1"));
    let tiny = write(dir.path(), "tiny.csv", &good_csv(8));
    let o = tfs(&["identify", &p(&tiny)]);
    assert_fails(&o, &["tiny.csv", "record a longer stretch"]);
    assert!(!String::from_utf8_lossy(&o.stderr).contains("lower the minimum"));
    // An unknown term of a model is the model's, not a missing CSV column.
    let rec = write(dir.path(), "r.csv", &good_csv(400));
    let foo = write(
        dir.path(),
        "foo.json",
        r#"{"format":"tfs-model/1","dofs":["x"],"inputs":["xb_acc","foo"],"equations":[{"dof":"x","terms":[
        {"term":"x","coef":-4.0},{"term":"foo","coef":-1.0},{"term":"xb_acc","coef":-1.0}]}]}"#,
    );
    assert_fails(
        &tfs(&["compare", "--model", &p(&foo), &p(&rec)]),
        &["foo.json", "input column 'foo'", "correct the model's term"],
    );
    // A repeated --add is named as such (it said the effect "does not apply").
    let lin = write(
        dir.path(),
        "lin.json",
        r#"{"format":"tfs-model/1","dofs":["x"],"inputs":["xb_acc"],"equations":[{"dof":"x","terms":[
        {"term":"x","coef":-4.0},{"term":"x'","coef":-0.2},{"term":"xb_acc","coef":-1.0}]}]}"#,
    );
    let out = dir.path().join("o.json");
    assert_fails(
        &tfs(&[
            "refit",
            "--model",
            &p(&lin),
            &p(&rec),
            "--add",
            "offset",
            "--add",
            "offset",
            "--out",
            &p(&out),
        ]),
        &["--add offset", "twice"],
    );
    // --dofs naming the time column suggests the file's other columns, not itself.
    let o = tfs(&["identify", &p(&rec), "--time-column", "x", "--dofs", "x"]);
    assert_fails(&o, &["--dofs x", "time column", "t, xb_acc"]);
    // med has the --dt its message names.
    let bi = write(
        dir.path(),
        "bi.json",
        r#"{"format":"tfs-model/1","dofs":["x"],"equations":[{"dof":"x","terms":[
        {"term":"x","coef":1.0},{"term":"x^3","coef":-1.0},{"term":"x'","coef":-1e6}]}]}"#,
    );
    let o = tfs(&["med", "--model", &p(&bi), "--grid", "10x10", "--x", "-2:2"]);
    assert_fails(&o, &["--dt (model basin map)", "too long"]);
    assert!(!String::from_utf8_lossy(&o.stderr).contains("basin basin"));
}
