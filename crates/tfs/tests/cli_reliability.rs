//! The CLI's reliability contract: no lost files (atomic writes, outputs never replace inputs,
//! a failed or killed write leaves the previous file), inputs read once (pipes, `-`), limits on
//! sizes users set, and the small bad-input cases of issue 32 — each answered with a clear
//! one-line error instead of a silent result.

mod common;
use common::assert_fails;

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_tfs"))
}

fn tfs(args: &[&str]) -> Output {
    bin().args(args).output().expect("the tfs binary runs")
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A simulated Kresling record (the project's own simulator, 40 dB), `t,x,xb_acc` only.
fn record(dir: &Path, name: &str, seed: u64) -> PathBuf {
    let full = dir.join(format!("{name}-full.csv"));
    let o = tfs(&[
        "simulate",
        "kresling",
        "--duration",
        "40",
        "--dt",
        "0.01",
        "--snr-db",
        "40",
        "--seed",
        &seed.to_string(),
        "--out",
        s(&full),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&full).unwrap();
    let cut: String = text
        .lines()
        .map(|l| l.split(',').take(3).collect::<Vec<_>>().join(",") + "\n")
        .collect();
    let p = dir.join(format!("{name}.csv"));
    std::fs::write(&p, cut).unwrap();
    p
}

/// A fitted model file.
fn model(dir: &Path, data: &Path) -> PathBuf {
    let m = dir.join("model.json");
    let o = tfs(&["identify", s(data), "--out", s(&m)]);
    assert!(o.status.success(), "{}", stderr(&o));
    m
}

#[test]
fn output_equal_to_an_input_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let data = record(dir.path(), "a", 1);
    let before = std::fs::read(&data).unwrap();
    assert_fails(
        &tfs(&["identify", s(&data), "--out", s(&data)]),
        &["--out", "a.csv", "also an input"],
    );
    // Another spelling of the same file is the same file.
    let other = dir.path().join(".").join("a.csv");
    assert_fails(
        &tfs(&["identify", s(&data), "--out", s(&other)]),
        &["also an input"],
    );
    assert_eq!(
        std::fs::read(&data).unwrap(),
        before,
        "the measurement survived"
    );
    let m = model(dir.path(), &data);
    assert_fails(
        &tfs(&[
            "refit",
            "--model",
            s(&m),
            "--add",
            "offset",
            s(&data),
            "--out",
            s(&m),
        ]),
        &["--out", "model.json", "also an input"],
    );
}

#[test]
fn missing_parent_folders_of_out_are_created() {
    let dir = tempfile::tempdir().unwrap();
    let data = record(dir.path(), "a", 1);
    let out = dir.path().join("new/sub/model.json");
    let o = tfs(&["identify", s(&data), "--out", s(&out)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(tfs::library::Model::from_path(&out).is_ok());
    let sim = dir.path().join("other/dir/sim.csv");
    let o = tfs(&["simulate", "kresling", "--duration", "20", "--out", s(&sim)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(sim.exists() && dir.path().join("other/dir/sim.meta.json").exists());
}

/// Runs `tfs args` with a file-size limit of `limit` bytes (RLIMIT_FSIZE): a write past it
/// fails (EFBIG) when `ignore_signal`, else the kernel kills the process in the middle of the
/// write (SIGXFSZ) — a full disk and a kill mid-write, on demand.
#[cfg(target_os = "linux")]
fn run_with_size_limit(args: &[&str], limit: u64, ignore_signal: bool) -> Output {
    use std::os::unix::process::CommandExt;
    let mut cmd = bin();
    cmd.args(args);
    // SAFETY: only async-signal-safe calls (setrlimit, signal) between fork and exec.
    unsafe {
        cmd.pre_exec(move || {
            let lim = libc::rlimit {
                rlim_cur: limit,
                rlim_max: limit,
            };
            if libc::setrlimit(libc::RLIMIT_FSIZE, &lim) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            let action = if ignore_signal {
                libc::SIG_IGN
            } else {
                libc::SIG_DFL
            };
            libc::signal(libc::SIGXFSZ, action);
            Ok(())
        });
    }
    cmd.output().unwrap()
}

/// A write that fails (the file system refuses more bytes) or a process killed in the middle
/// of writing leaves the previous model, CSV and metadata intact.
#[cfg(target_os = "linux")]
#[test]
fn failed_or_killed_writes_keep_the_previous_file() {
    use std::os::unix::process::ExitStatusExt;
    let dir = tempfile::tempdir().unwrap();
    let data = record(dir.path(), "a", 1);
    let m = model(dir.path(), &data);
    let good = std::fs::read(&m).unwrap();
    assert!(good.len() > 4096, "the model with its trace is several kB");
    for ignore in [true, false] {
        let o = run_with_size_limit(&["identify", s(&data), "--out", s(&m)], 2048, ignore);
        if ignore {
            assert_fails(&o, &["model.json", "File too large"]);
        } else {
            assert_eq!(o.status.signal(), Some(libc::SIGXFSZ), "{}", stderr(&o));
        }
        assert_eq!(std::fs::read(&m).unwrap(), good, "ignore SIGXFSZ: {ignore}");
        assert!(tfs::library::Model::from_path(&m).is_ok());
    }
    // The same for a simulated CSV (the CSV writer) and its metadata.
    let sim = dir.path().join("sim.csv");
    let o = tfs(&["simulate", "kresling", "--duration", "20", "--out", s(&sim)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (csv_before, meta_before) = (
        std::fs::read(&sim).unwrap(),
        std::fs::read(dir.path().join("sim.meta.json")).unwrap(),
    );
    for ignore in [true, false] {
        let args = [
            "simulate",
            "kresling",
            "--duration",
            "30",
            "--seed",
            "7",
            "--out",
            s(&sim),
        ];
        let o = run_with_size_limit(&args, 65536, ignore);
        assert!(!o.status.success());
        assert_eq!(std::fs::read(&sim).unwrap(), csv_before);
        assert_eq!(
            std::fs::read(dir.path().join("sim.meta.json")).unwrap(),
            meta_before
        );
    }
    // Figures too: a basin map whose PNG cannot be written leaves the previous one.
    let png = dir.path().join("basin.png");
    let basin = |limit: Option<u64>| {
        let args = [
            "basin",
            "--model",
            s(&m),
            "--grid",
            "40x40",
            "--t-max",
            "20",
            "--out",
            s(&png),
        ];
        match limit {
            Some(l) => run_with_size_limit(&args, l, true),
            None => tfs(&args),
        }
    };
    let o = basin(None);
    assert!(o.status.success(), "{}", stderr(&o));
    let png_before = std::fs::read(&png).unwrap();
    let o = basin(Some(4096));
    assert!(!o.status.success());
    assert_eq!(std::fs::read(&png).unwrap(), png_before);
}

/// Standard input as `-` or `/dev/stdin`, and a pipe opened by path (what `<(…)` gives), are
/// read once: the header is not read in a separate pass.
#[test]
fn pipes_and_stdin_are_read_once() {
    let dir = tempfile::tempdir().unwrap();
    let data = record(dir.path(), "a", 1);
    let text = std::fs::read(&data).unwrap();
    let reference = tfs(&["identify", s(&data), "--json"]);
    assert!(reference.status.success(), "{}", stderr(&reference));
    let model_of = |o: &Output| -> serde_json::Value {
        let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        v["model"]["equations"].clone()
    };
    for path in ["-", "/dev/stdin"] {
        let mut child = bin()
            .args(["identify", path, "--json"])
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let mut stdin = child.stdin.take().unwrap();
        let t = text.clone();
        let writer = std::thread::spawn(move || stdin.write_all(&t));
        let o = child.wait_with_output().unwrap();
        writer.join().unwrap().ok();
        assert!(o.status.success(), "{path}: {}", stderr(&o));
        assert_eq!(model_of(&o), model_of(&reference), "{path}");
    }
    // A named pipe that can be read once, like `<(cat a.csv)`.
    #[cfg(unix)]
    {
        let fifo = dir.path().join("pipe.csv");
        let c = std::ffi::CString::new(s(&fifo)).unwrap();
        // SAFETY: a valid NUL-terminated path.
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
        let f2 = fifo.clone();
        let writer = std::thread::spawn(move || {
            let mut w = std::fs::OpenOptions::new().write(true).open(&f2).unwrap();
            w.write_all(&text).ok();
        });
        let mut child = bin()
            .args(["identify", s(&fifo), "--json"])
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let start = Instant::now();
        while child.try_wait().unwrap().is_none() {
            if start.elapsed() > Duration::from_secs(60) {
                child.kill().ok();
                panic!("identify on a pipe did not finish: it waited to read it a second time");
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        let o = child.wait_with_output().unwrap();
        writer.join().unwrap();
        assert!(o.status.success(), "{}", stderr(&o));
        assert_eq!(model_of(&o), model_of(&reference));
    }
}

#[test]
fn same_record_twice_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let data = record(dir.path(), "a", 1);
    assert_fails(
        &tfs(&["identify", s(&data), s(&data)]),
        &["a.csv", "given twice"],
    );
    let copy = dir.path().join("copy.csv");
    std::fs::copy(&data, &copy).unwrap();
    assert_fails(
        &tfs(&["identify", s(&data), s(&copy)]),
        &["a.csv", "copy.csv", "same samples"],
    );
}

#[test]
fn dofs_that_are_not_displacements_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let data = record(dir.path(), "a", 1);
    assert_fails(
        &tfs(&["identify", s(&data), "--dofs", "t"]),
        &["--dofs t", "time column"],
    );
    assert_fails(
        &tfs(&["identify", s(&data), "--dofs", "xb_acc"]),
        &["--dofs xb_acc", "input"],
    );
}

/// Semicolon- and tab-separated files read like the comma-separated file; a header `time` is
/// named as the time axis (not "did you mean 'x'?") and `--time-column` chooses it.
#[test]
fn separators_and_time_column_names() {
    let dir = tempfile::tempdir().unwrap();
    let data = record(dir.path(), "a", 1);
    let text = std::fs::read_to_string(&data).unwrap();
    let reference = tfs(&["identify", s(&data), "--json"]);
    let eqs = |o: &Output| -> serde_json::Value {
        assert!(o.status.success(), "{}", stderr(o));
        serde_json::from_slice::<serde_json::Value>(&o.stdout).unwrap()["model"]["equations"]
            .clone()
    };
    for (name, sep) in [("semi.csv", ";"), ("tab.tsv", "\t")] {
        let p = dir.path().join(name);
        std::fs::write(&p, text.replace(',', sep)).unwrap();
        assert_eq!(eqs(&tfs(&["identify", s(&p), "--json"])), eqs(&reference));
    }
    let p = dir.path().join("time.csv");
    std::fs::write(&p, text.replacen("t,", "time,", 1)).unwrap();
    let o = tfs(&["identify", s(&p)]);
    assert_fails(
        &o,
        &[
            "time.csv",
            "'time' looks like the time axis",
            "--time-column",
        ],
    );
    assert!(!stderr(&o).contains("did you mean 'x'"));
    let o = tfs(&["identify", s(&p), "--time-column", "time", "--json"]);
    assert_eq!(eqs(&o), eqs(&reference));
}

/// A cell that makes a library term overflow is named by file, time and value.
#[test]
fn overflowing_cell_names_file_and_time() {
    let dir = tempfile::tempdir().unwrap();
    let data = record(dir.path(), "a", 1);
    let mut lines: Vec<String> = std::fs::read_to_string(&data)
        .unwrap()
        .lines()
        .map(String::from)
        .collect();
    let t = lines[100].split(',').next().unwrap().to_string();
    lines[100] = format!("{t},1e300,0.5");
    let p = dir.path().join("big.csv");
    std::fs::write(&p, lines.join("\n") + "\n").unwrap();
    for method in ["tfs", "sindy"] {
        assert_fails(
            &tfs(&["identify", s(&p), "--method", method]),
            &["big.csv", &format!("t = {t} s"), "x = 1e300", "not finite"],
        );
    }
}

/// Classical SINDy that keeps no term does not report `x'' = 0` as a result.
#[test]
fn empty_sindy_model_is_not_a_result() {
    let dir = tempfile::tempdir().unwrap();
    let data = record(dir.path(), "a", 1);
    let out = dir.path().join("m.json");
    let o = tfs(&[
        "identify",
        s(&data),
        "--method",
        "sindy",
        "--threshold",
        "1e12",
        "--out",
        s(&out),
    ]);
    assert_fails(
        &o,
        &["nothing identified", "classical SINDy", "--threshold"],
    );
    assert!(!out.exists(), "no empty model written");
}

/// Model files that are not what they say: a term listed twice, no term at all.
#[test]
fn model_files_with_repeated_or_no_terms_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let data = record(dir.path(), "a", 1);
    let twice = dir.path().join("twice.json");
    std::fs::write(
        &twice,
        r#"{"format":"tfs-model/1","dofs":["x"],"inputs":["xb_acc"],"equations":[{"dof":"x","terms":[
        {"term":"x'","coef":-2.0},{"term":"x^5","coef":-6.0},{"term":"x^6","coef":18.0},
        {"term":"x^5","coef":-6.1},{"term":"x^7","coef":-6.6},{"term":"xb_acc","coef":-1.0}]}]}"#,
    )
    .unwrap();
    for cmd in [
        vec!["compare", "--model", s(&twice), s(&data)],
        vec!["basin", "--model", s(&twice), "--grid", "10x10"],
    ] {
        assert_fails(&tfs(&cmd), &["twice.json", "'x^5'", "twice"]);
    }
    let empty = dir.path().join("empty.json");
    std::fs::write(
        &empty,
        r#"{"format":"tfs-model/1","dofs":["x"],"equations":[{"dof":"x","terms":[]}]}"#,
    )
    .unwrap();
    assert_fails(
        &tfs(&["basin", "--model", s(&empty), "--grid", "10x10"]),
        &["empty.json", "no terms"],
    );
}

/// Sizes users set are bounded: a simulation's sample count and a library's term count are
/// refused at once with what to do, not run out of memory or time.
#[test]
fn sizes_users_set_are_bounded() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("s.csv");
    let start = Instant::now();
    let o = tfs(&[
        "simulate",
        "kresling",
        "--duration",
        "1e12",
        "--out",
        s(&out),
    ]);
    assert_fails(&o, &["--duration", "samples", "at most"]);
    let data = record(dir.path(), "a", 1);
    let run = |lib: &str| {
        let mut child = bin()
            .args(["identify", s(&data), "--library", lib])
            .stderr(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .unwrap();
        let t = Instant::now();
        while child.try_wait().unwrap().is_none() {
            if t.elapsed() > Duration::from_secs(30) {
                child.kill().ok();
                panic!("--library {lib} ran without limit");
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        child.wait_with_output().unwrap()
    };
    assert_fails(&run("x^1..65536"), &["at most"]);
    assert_fails(&run("x^1..600"), &["600 terms", "at most 512"]);
    assert!(start.elapsed() < Duration::from_secs(60));
}

/// `compare` scores on the variance (mean removed) and also gives Appendix B's ratio, each
/// named; the numbers are those definitions of the simulated error.
#[test]
fn compare_reports_both_r_mse_definitions() {
    let dir = tempfile::tempdir().unwrap();
    let data = record(dir.path(), "a", 1);
    let m = model(dir.path(), &data);
    let o = tfs(&["compare", "--model", s(&m), s(&data), "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let d = &v["files"][0]["dofs"][0];
    let rms = d["rms_error"].as_f64().unwrap();
    let rec = tfs::data::read_csv(&data).unwrap();
    let x = rec.column("x").unwrap();
    let n = x.len() as f64;
    let mean = x.iter().sum::<f64>() / n;
    let var = x.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / n;
    let ms = x.iter().map(|v| v * v).sum::<f64>() / n;
    let r = d["r_mse"].as_f64().unwrap();
    let rb = d["r_mse_mean_square"].as_f64().unwrap();
    assert!(
        (r - rms * rms / var).abs() <= 1e-9 * r,
        "{r} vs {}",
        rms * rms / var
    );
    assert!(
        (rb - rms * rms / ms).abs() <= 1e-9 * rb,
        "{rb} vs {}",
        rms * rms / ms
    );
    assert!(r > rb, "the DC level ({mean}) flatters Appendix B's ratio");
    assert!(v["r_mse_definition"].as_str().unwrap().contains("variance"));
    assert!(
        v["r_mse_mean_square_definition"]
            .as_str()
            .unwrap()
            .contains("Appendix B")
    );
}

/// Errors of `simulate` that are not a divergence carry no advice about divergence.
#[test]
fn simulate_errors_say_only_what_went_wrong() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("s.csv");
    let o = tfs(&["simulate", "kresling", "--gamma0", "90", "--out", s(&out)]);
    assert_fails(&o, &["gamma0"]);
    assert!(!stderr(&o).contains("diverged"), "{}", stderr(&o));
}

/// A hand-written 1-DOF model (`x'' = -4 x + c x' + extra - xb_acc`), as a model file.
fn hand_model(dir: &Path, name: &str, damping: f64, extra: &str) -> PathBuf {
    let p = dir.join(name);
    let extra = if extra.is_empty() {
        String::new()
    } else {
        format!(r#"{{"term":"{extra}","coef":-0.5}},"#)
    };
    std::fs::write(
        &p,
        format!(
            r#"{{"format":"tfs-model/1","dofs":["x"],"inputs":["xb_acc"],"equations":[{{"dof":"x","terms":[
            {{"term":"x","coef":-4.0}},{{"term":"x'","coef":{damping:e}}},{extra}{{"term":"xb_acc","coef":-1.0}}]}}]}}"#
        ),
    )
    .unwrap();
    p
}

/// `--out` never replaces what is not a regular, writable file: a device node, a FIFO or a
/// read-only file is refused before any work and left as it was (the atomic rename used to put
/// a regular file in its place, and `identify --out /dev/full` said "model written").
#[cfg(unix)]
#[test]
fn out_replaces_only_regular_writable_files() {
    use std::os::unix::fs::{FileTypeExt, PermissionsExt};
    let dir = tempfile::tempdir().unwrap();
    let sim = |out: &str| tfs(&["simulate", "kresling", "--duration", "5", "--out", out]);
    assert_fails(&sim("/dev/null"), &["--out /dev/null", "character device"]);
    assert!(
        std::fs::metadata("/dev/null")
            .unwrap()
            .file_type()
            .is_char_device()
    );
    let data = record(dir.path(), "a", 1);
    assert_fails(
        &tfs(&["identify", s(&data), "--out", "/dev/full"]),
        &["--out /dev/full", "not a regular file"],
    );
    let fifo = dir.path().join("pipe.csv");
    assert!(
        Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap()
            .success()
    );
    assert_fails(&sim(s(&fifo)), &["pipe.csv", "FIFO"]);
    assert!(std::fs::metadata(&fifo).unwrap().file_type().is_fifo());
    let ro = dir.path().join("ro.csv");
    std::fs::write(&ro, "keep").unwrap();
    std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o444)).unwrap();
    assert_fails(&sim(s(&ro)), &["ro.csv", "read-only", "chmod"]);
    assert_eq!(std::fs::read_to_string(&ro).unwrap(), "keep");
    // A read-only metadata file beside a writable CSV: nothing is written at all.
    let out = dir.path().join("b.csv");
    let meta = dir.path().join("b.meta.json");
    std::fs::write(&meta, "old").unwrap();
    std::fs::set_permissions(&meta, std::fs::Permissions::from_mode(0o444)).unwrap();
    assert_fails(&sim(s(&out)), &["b.meta.json", "read-only"]);
    assert!(!out.exists());
}

/// Every file a command writes is checked against its inputs, the derived ones too: basin's
/// SVG beside `--out X.png`, compare's figures (two records with the same file name in two
/// folders get two sets of figures), and simulate's records are written as a set.
#[test]
fn derived_outputs_are_checked_and_distinct() {
    let dir = tempfile::tempdir().unwrap();
    let m = hand_model(dir.path(), "map.svg", -0.2, "");
    let before = std::fs::read(&m).unwrap();
    let png = dir.path().join("map.png");
    assert_fails(
        &tfs(&[
            "basin",
            "--model",
            s(&m),
            "--grid",
            "10x10",
            "--out",
            s(&png),
        ]),
        &["--out", "map.svg", "also an input"],
    );
    assert_eq!(std::fs::read(&m).unwrap(), before);
    // compare: a/rec.csv and b/rec.csv each get their figures.
    let m = hand_model(dir.path(), "lin.json", -0.2, "");
    std::fs::create_dir_all(dir.path().join("a")).unwrap();
    std::fs::create_dir_all(dir.path().join("b")).unwrap();
    let ra = dir.path().join("a/rec.csv");
    let rb = dir.path().join("b/rec.csv");
    std::fs::copy(record(dir.path(), "r1", 1), &ra).unwrap();
    std::fs::copy(record(dir.path(), "r2", 2), &rb).unwrap();
    let plots = dir.path().join("figs");
    let o = tfs(&[
        "compare",
        "--model",
        s(&m),
        s(&ra),
        s(&rb),
        "--plots",
        s(&plots),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let mut names: Vec<String> = std::fs::read_dir(&plots)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".svg"))
        .collect();
    names.sort();
    assert_eq!(names, ["a-rec-x.svg", "b-rec-x.svg"]);
    // A figure among the inputs, in the --plots folder, is refused before any work.
    let fig = plots.join("a-rec-x.svg");
    std::fs::copy(&ra, &fig).unwrap();
    assert_fails(
        &tfs(&["compare", "--model", s(&m), s(&fig), "--plots", s(&plots)]),
        &["--plots", "a-rec-x.svg"],
    );
}

/// A 2,000-sample record `t,x,xb_acc` written directly (a forced, damped oscillation).
fn plain_record(dir: &Path, name: &str, amplitude: f64) -> PathBuf {
    let mut text = String::from("t,x,xb_acc\n");
    for k in 0..2000 {
        let t = k as f64 * 0.01;
        let x = amplitude * ((1.3 * t).sin() + 0.3 * (2.9 * t).cos());
        text.push_str(&format!("{t},{x:e},{:e}\n", (1.1 * t).cos()));
    }
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// Runs `tfs args`; a run still going after `limit` is killed and the test fails (a hang).
fn run_or_hang(args: &[&str], limit: Duration) -> Output {
    let mut child = bin()
        .args(args)
        .stderr(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let t = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if t.elapsed() > limit {
            child.kill().ok();
            panic!("tfs {args:?} ran past {limit:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    child.wait_with_output().unwrap()
}

/// A discontinuous model (`sign(x')`) and a stiff one (damping 1e12) on a 2,000-sample record:
/// the simulation's step budget, sized from the record, stops them with what is wrong (they
/// used to run for minutes, or ~1e8 s, printing nothing).
#[test]
fn stiff_or_discontinuous_models_stop_with_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let data = plain_record(dir.path(), "r.csv", 1.0);
    let limit = Duration::from_secs(300);
    for (name, damping, extra) in [("sign.json", -0.05, "sign(x')"), ("stiff.json", -1e12, "")] {
        let m = hand_model(dir.path(), name, damping, extra);
        let o = run_or_hang(&["compare", "--model", s(&m), s(&data)], limit);
        assert_fails(&o, &["r.csv", "too stiff or discontinuous"]);
    }
}

/// A model whose DOF is the time column, and a record too small for the simulation to
/// resolve, are errors that say so (they were scored: R-MSE against time, or NaN).
#[test]
fn time_as_a_dof_and_unresolved_records_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    let data = plain_record(dir.path(), "r.csv", 1.0);
    let m = dir.path().join("t.json");
    std::fs::write(
        &m,
        r#"{"format":"tfs-model/1","dofs":["t"],"inputs":["xb_acc"],"equations":[{"dof":"t","terms":[
        {"term":"t","coef":-4.0},{"term":"xb_acc","coef":-1.0}]}]}"#,
    )
    .unwrap();
    assert_fails(
        &tfs(&["compare", "--model", s(&m), s(&data)]),
        &["'t' is the time column"],
    );
    let tiny = plain_record(dir.path(), "tiny.csv", 1e-160);
    let m = hand_model(dir.path(), "lin.json", -0.2, "");
    let o = tfs(&["compare", "--model", s(&m), s(&tiny), "--json"]);
    assert_fails(&o, &["tiny.csv", "'x'", "smaller units"]);
}
