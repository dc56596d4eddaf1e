//! The folded stop of the Kresling truss cell from the CLI: records of the truss truth at 60 dB
//! (two sweeps per draw, several draws), identified with `x^1..7, x', xb_acc`, then
//! `refit --add stop`. The loop's equation-error fit puts a soft stop inside the data's range
//! (the smoothed acceleration cannot resolve the contact); re-scanning the position by T-F-S
//! must find the contact where the truth has it (h = 0), with the truth's contact stiffness,
//! and lower the mean R-MSE below the equation-error fit's rung of the ladder; and
//! `refit --until-clean` must end with that contact by itself (the stop's equation-error
//! evidence is weak at 60 dB; T-F-S's is not).

#[path = "common/run.rs"]
mod run;
use run::ok;

fn json(s: &str) -> serde_json::Value {
    serde_json::from_str(s).unwrap_or_else(|e| panic!("{e}: {s}"))
}

#[test]
fn refit_add_stop_finds_the_truss_contact() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let k_stop = json(&ok(d, &["kresling", "--json"]))["k_stop"]
        .as_f64()
        .unwrap();
    for seed in ["22", "24"] {
        let out = format!("k{seed}.csv");
        ok(
            d,
            &[
                "simulate",
                "kresling",
                "--truth",
                "truss",
                "--excitation",
                "sweep:0.05:1.5:4",
                "--excitation",
                "sweep:0.1:1.5:3.5",
                "--duration",
                "80",
                "--snr-db",
                "60",
                "--seed",
                seed,
                "--out",
                &out,
            ],
        );
        let (r1, r2) = (format!("k{seed}-1.csv"), format!("k{seed}-2.csv"));
        let m = format!("m{seed}.json");
        ok(
            d,
            &[
                "identify",
                &r1,
                &r2,
                "--library",
                "x^1..7, x', xb_acc",
                "--out",
                &m,
            ],
        );
        let r = format!("r{seed}.json");
        let v = json(&ok(
            d,
            &[
                "refit", "--model", &m, &r1, &r2, "--add", "stop", "--json", "--out", &r,
            ],
        ));
        let stop = &v["stops"][0];
        assert_eq!(stop["kept"], true, "seed {seed}: {stop}");
        let to = stop["to"].as_str().unwrap();
        let c: f64 = to
            .trim_start_matches("below(x, ")
            .trim_end_matches(')')
            .parse()
            .unwrap_or_else(|e| panic!("seed {seed}: {to}: {e}"));
        assert!(
            c.abs() <= 1e-3,
            "seed {seed}: contact at {c}, truth 0 ({stop})"
        );
        let k = stop["coef"].as_f64().unwrap();
        assert!(
            (k / k_stop - 1.0).abs() < 0.1,
            "seed {seed}: contact stiffness {k}, truth {k_stop}"
        );
        let ladder = v["ladder"].as_array().unwrap();
        let rung = |name: &str| {
            ladder
                .iter()
                .find(|s| s["step"] == name)
                .and_then(|s| s["geo_mean_r_mse"].as_f64())
                .unwrap_or_else(|| panic!("seed {seed}: no rung '{name}' in {ladder:?}"))
        };
        assert!(
            rung("stop by T-F-S") < rung("add stop"),
            "seed {seed}: {ladder:?}"
        );
        // The loop by itself: whether the equation error makes the stop significant or not
        // (at 60 dB it mostly does not), it must end with the contact T-F-S finds.
        if seed == "22" {
            let u = json(&ok(
                d,
                &[
                    "refit",
                    "--model",
                    &m,
                    &r1,
                    &r2,
                    "--until-clean",
                    "3",
                    "--json",
                    "--out",
                    "u22.json",
                ],
            ));
            let rounds = u["rounds"].as_array().unwrap();
            assert!(
                rounds.iter().any(|r| r["added"] == "stop"),
                "seed {seed}: the loop added no stop: {rounds:?}"
            );
            let found = u["stops"].as_array().unwrap().iter().any(|s| {
                s["kept"] == true
                    && s["to"]
                        .as_str()
                        .and_then(|t| {
                            t.trim_start_matches("below(x, ")
                                .trim_end_matches(')')
                                .parse::<f64>()
                                .ok()
                        })
                        .is_some_and(|c| c.abs() <= 1e-3)
            });
            assert!(found, "seed {seed}: {}", u["stops"]);
        }
    }
}
