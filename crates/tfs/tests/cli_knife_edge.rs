//! Identification does not sit on a knife edge: the same measurement reprinted at 15 significant
//! digits, moved by one ulp in every sample, or with its time column shifted by 10⁶ s, gives the
//! same model and the same warnings (the three fixtures and simulated records at 20–60 dB). (A decision that
//! rounding in the last digits could flip — whether a nearly singular jackknife replicate could be
//! factored — once turned a six-term model into a two-term one with a warning.)

use std::path::{Path, PathBuf};
use std::process::Command;

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../fixtures")
        .join(name)
}

/// Rewrites the `t,x,xb_acc` columns of `src` with `f(column, value)` into `dst`.
fn rewrite(src: &Path, dst: &Path, f: impl Fn(usize, f64) -> String) {
    let text = std::fs::read_to_string(src).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let keep: Vec<usize> = ["t", "x", "xb_acc"]
        .iter()
        .map(|n| header.iter().position(|h| h == n).unwrap())
        .collect();
    let mut out = String::from("t,x,xb_acc\n");
    for line in lines.filter(|l| !l.trim().is_empty()) {
        let cells: Vec<&str> = line.split(',').collect();
        let row: Vec<String> = keep
            .iter()
            .enumerate()
            .map(|(c, &i)| f(c, cells[i].trim().parse::<f64>().unwrap()))
            .collect();
        out.push_str(&row.join(","));
        out.push('\n');
    }
    std::fs::write(dst, out).unwrap();
}

/// The identified equation of `tfs identify FILE --library LIB` and the warnings printed before
/// it (stdout up to the equation; record names are printed only after it).
fn equation(file: &Path) -> String {
    let o = Command::new(env!("CARGO_BIN_EXE_tfs"))
        .args([
            "identify",
            file.to_str().unwrap(),
            "--library",
            "x^1..7, x', xb_acc",
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let out = String::from_utf8_lossy(&o.stdout);
    let mut head = Vec::new();
    for line in out.lines() {
        head.push(line.to_string());
        if line.starts_with("x'' = ") {
            break;
        }
    }
    head.join("\n")
}

/// A record of the project's Kresling simulator at `snr` dB (all its columns).
fn simulated(dir: &Path, snr: u32, seed: u64) -> PathBuf {
    let p = dir.join(format!("sim-{snr}db-{seed}.csv"));
    let o = Command::new(env!("CARGO_BIN_EXE_tfs"))
        .args(["simulate", "kresling", "--duration", "60", "--dt", "0.01"])
        .args(["--snr-db", &snr.to_string(), "--seed", &seed.to_string()])
        .args(["--out", p.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    p
}

#[test]
fn last_digits_and_a_time_shift_do_not_change_the_model() {
    let dir = tempfile::tempdir().unwrap();
    let mut sources: Vec<(String, PathBuf)> = [
        "kresling-30db-train-1.csv",
        "kresling-30db-train-2.csv",
        "kresling-30db-test.csv",
    ]
    .iter()
    .map(|n| (n.to_string(), fixture(n)))
    .collect();
    for (snr, seed) in [(20, 11), (30, 12), (40, 13), (60, 14)] {
        sources.push((
            format!("simulated {snr} dB"),
            simulated(dir.path(), snr, seed),
        ));
    }
    for (k, (name, src)) in sources.iter().enumerate() {
        let name = name.as_str();
        let src = src.clone();
        // one ulp up or down on every sample, alternating with the row and the column
        let ulp = dir.path().join(format!("ulp-{k}.csv"));
        let flip = std::cell::Cell::new(false);
        rewrite(&src, &ulp, |c, v| {
            flip.set(!flip.get());
            let w = if c == 0 {
                v
            } else if flip.get() {
                v.next_up()
            } else {
                v.next_down()
            };
            format!("{w:?}")
        });
        let exact = dir.path().join(format!("exact-{k}.csv"));
        rewrite(&src, &exact, |_, v| format!("{v:?}"));
        let p15 = dir.path().join(format!("p15-{k}.csv"));
        rewrite(&src, &p15, |_, v| format!("{v:.14e}"));
        let shifted = dir.path().join(format!("shift-{k}.csv"));
        rewrite(&src, &shifted, |c, v| {
            format!("{:?}", if c == 0 { v + 1e6 } else { v })
        });
        let base = equation(&exact);
        assert!(base.contains("x'' = "), "{name}: no equation: {base}");
        same(
            &equation(&p15),
            &base,
            &format!("{name} reprinted at 15 digits"),
        );
        same(
            &equation(&shifted),
            &base,
            &format!("{name} with t shifted by 1e6 s"),
        );
        same(
            &equation(&ulp),
            &base,
            &format!("{name} with every sample moved by one ulp"),
        );
    }
}

/// The printed output with every interval half-width (`± w`) taken out, and the half-widths.
fn split_half_widths(out: &str) -> (String, Vec<f64>) {
    let mut text = String::new();
    let mut widths = Vec::new();
    let mut rest = out;
    while let Some(i) = rest.find("± ") {
        text.push_str(&rest[..i + "± ".len()]);
        rest = &rest[i + "± ".len()..];
        let end = rest
            .find(|c: char| !(c.is_ascii_digit() || ".e-+".contains(c)))
            .unwrap_or(rest.len());
        widths.push(rest[..end].parse().unwrap());
        rest = &rest[end..];
    }
    text.push_str(rest);
    (text, widths)
}

/// The same terms, coefficients and warnings as printed, and every interval half-width equal to
/// 2e-3 relative. The half-widths are compared to a tolerance because a jackknife replicate that
/// leaves out a dominant cluster is solved at a condition number up to 1e12 (the replicates'
/// margin): it carries about five significant digits, and the printed fourth digit of a
/// half-width can round either way (the simulated 60 dB record's `x^7` half-width moved by 4e-5
/// relative when reprinted at 15 digits). Intervals switching on or off still fail here.
fn same(got: &str, want: &str, what: &str) {
    let (gt, gw) = split_half_widths(got);
    let (wt, ww) = split_half_widths(want);
    assert_eq!(gt, wt, "{what}");
    for (g, w) in gw.iter().zip(&ww) {
        assert!(
            (g - w).abs() <= 2e-3 * w.abs(),
            "{what}: half-width {g} vs {w}\n{got}\n{want}"
        );
    }
}
