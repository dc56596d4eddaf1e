//! Running the `tfs` binary in a folder, for the CLI tests that chain several commands.

use std::path::Path;
use std::process::{Command, Output};

/// Runs `tfs args…` with `dir` as the working folder.
pub fn tfs(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_tfs"))
        .current_dir(dir)
        .args(args)
        .output()
        .unwrap()
}

/// Runs `tfs args…` in `dir`, asserts it succeeded (showing its stderr if not), returns stdout.
pub fn ok(dir: &Path, args: &[&str]) -> String {
    let out = tfs(dir, args);
    assert!(
        out.status.success(),
        "tfs {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}
