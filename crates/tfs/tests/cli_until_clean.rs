//! The diagnosis loop from the CLI (`tfs refit --until-clean`): a Kresling cell identified with a
//! library that lacks any damping term leaves most of its motion unexplained; the loop adds the
//! top significant effect round by round, each round lowers the error ladder, it stops by itself
//! once nothing is significant, and the model it writes holds the added terms. `--until-clean 0`
//! is refused naming the flag.

#[path = "common/run.rs"]
mod run;
use run::{ok, tfs};

#[test]
fn until_clean_adds_effects_until_none_is_significant() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    ok(
        d,
        &[
            "simulate",
            "kresling",
            "--excitation",
            "sweep:0.05:1.5:4",
            "--excitation",
            "sweep:0.05:1.5:3",
            "--duration",
            "60",
            "--snr-db",
            "50",
            "--seed",
            "2",
            "--out",
            "k.csv",
        ],
    );
    ok(
        d,
        &[
            "identify",
            "k-1.csv",
            "k-2.csv",
            "--library",
            "x^5..7, xb_acc",
            "--out",
            "m.json",
        ],
    );
    // The same loop with each output: `refit m.json k-1.csv k-2.csv --until-clean 4 --out OUT`.
    let until_clean = |out: &str, extra: &[&str]| -> String {
        let mut args = vec![
            "refit",
            "--model",
            "m.json",
            "k-1.csv",
            "k-2.csv",
            "--until-clean",
            "4",
            "--out",
            out,
        ];
        args.extend_from_slice(extra);
        ok(d, &args)
    };
    let json = until_clean("r.json", &["--json"]);
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    let rounds = v["rounds"].as_array().unwrap();
    let added: Vec<&str> = rounds.iter().filter_map(|r| r["added"].as_str()).collect();
    assert!(!added.is_empty(), "no effect added: {rounds:?}");
    // Each added effect lowers the geometric-mean R-MSE, and the loop ends because nothing is significant
    // (a round that adds nothing), not because it ran out of rounds.
    let ladder: Vec<f64> = v["ladder"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["geo_mean_r_mse"].as_f64().unwrap())
        .collect();
    assert_eq!(ladder.len(), added.len() + 1, "{ladder:?}");
    assert!(
        ladder.windows(2).all(|w| w[1] < w[0]),
        "the ladder does not fall: {ladder:?}"
    );
    assert!(ladder[ladder.len() - 1] < 0.1 * ladder[0], "{ladder:?}");
    assert!(
        rounds.last().unwrap()["added"].is_null() && rounds.len() <= 4,
        "{rounds:?}"
    );
    // The model written holds more terms than the start, and the human output tells the story.
    let model = |p: &str| -> usize {
        let m: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(d.join(p)).unwrap()).unwrap();
        m["equations"][0]["terms"].as_array().unwrap().len()
    };
    assert!(model("r.json") > model("m.json"));
    let human = until_clean("r2.json", &[]);
    assert!(human.contains("round 1: added"), "{human}");
    assert!(human.contains("the loop stops"), "{human}");

    let zero = tfs(
        d,
        &[
            "refit",
            "--model",
            "m.json",
            "k-1.csv",
            "--until-clean",
            "0",
            "--out",
            "r0.json",
        ],
    );
    assert_eq!(zero.status.code(), Some(2));
    let err = String::from_utf8_lossy(&zero.stderr);
    assert!(err.contains("--until-clean 0"), "{err}");
    assert!(!d.join("r0.json").exists());
}
