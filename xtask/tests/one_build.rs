//! One build for everything a newcomer runs: `cargo xtask …`, `cargo install --path crates/tfs
//! --debug` and `cargo test --workspace` must compile every dependency with the same features,
//! or the second command rebuilds what the first one built (cargo resolves features for the
//! packages it is asked to build, and the tests' dev-dependencies switch on more of them).

use std::collections::BTreeSet;
use std::process::Command;

/// Every `name version [features]` line of `cargo tree` for these arguments (registry packages
/// only: the workspace's own crates are compiled per target anyway).
fn tree(args: &[&str]) -> BTreeSet<String> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/..");
    let out = Command::new(cargo)
        .current_dir(root)
        .args(["tree", "--offline", "--prefix", "none", "--no-dedupe"])
        .args(["-f", "{p} [{f}]"])
        .args(args)
        .output()
        .expect("running cargo tree");
    assert!(
        out.status.success(),
        "cargo tree {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter(|l| !l.trim().is_empty() && !l.contains("(/") && !l.contains("(*)"))
        .map(|l| l.trim().to_string())
        .collect()
}

#[test]
fn xtask_and_cli_share_the_test_build_of_every_dependency() {
    let all = tree(&["--workspace", "-e", "normal,build,dev"]);
    assert!(all.iter().any(|l| l.starts_with("faer ")), "{all:?}");
    for pkg in ["xtask", "tfs"] {
        let own = tree(&["-p", pkg, "-e", "normal,build"]);
        let differ: Vec<&String> = own.difference(&all).collect();
        assert!(
            differ.is_empty(),
            "building `{pkg}` alone compiles these dependencies with other features than \
             `cargo test --workspace` does, so one of the two rebuilds them: {differ:?}; switch \
             the missing features on in crates/tfs/Cargo.toml (feature alignment)"
        );
    }
}
