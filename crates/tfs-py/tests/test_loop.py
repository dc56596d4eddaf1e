"""The diagnosis loop from Python: the same answers as the CLI, computed by the same code."""

import json
import subprocess

import tfs
from conftest import PAPER_MODEL, TEST, TRAIN

# The paper's model of the cell without its x^7 term: the restoring force no longer turns the
# cell back at large heights, so the free run of the test record blows up.
WITHOUT_X7 = PAPER_MODEL.replace('{"term":"x^7","coef":-6.56},', "")
# The same failure with the term kept at a zero coefficient: refitting the model's own terms
# mends it, so no effect is missing.
ZERO_X7 = PAPER_MODEL.replace('{"term":"x^7","coef":-6.56}', '{"term":"x^7","coef":0.0}')


def run_json(cmd):
    return json.loads(subprocess.run(cmd, check=True, capture_output=True, text=True).stdout)


def test_diagnose_simulates_the_candidates_as_the_cli_does(cli, tmp_path):
    m = tfs.Model.from_json(WITHOUT_X7)
    m.save(tmp_path / "m.json")
    c = run_json([cli, "diagnose", "--model", str(tmp_path / "m.json"), str(TEST), "--json"])
    d = tfs.diagnose(m, TEST)
    sim = d["simulation"]
    # The case tests the simulations' say: the model fails on the record, a candidate mends it.
    assert sim is not None and sim["before"]["failed"] == 1, sim
    assert sim["chosen"] is not None and d["verdict"].startswith("missing effect: ")
    assert d["verdict"] == c["verdict"]
    assert d["equation_error_verdict"] == c["equation_error_verdict"]
    assert sim == c["simulation"]


def test_a_failure_its_own_terms_mend_names_no_effect():
    d = tfs.diagnose(tfs.Model.from_json(ZERO_X7), TEST)
    sim = d["simulation"]
    assert sim["before"]["failed"] == 1 and sim["refitted"]["failed"] == 0, sim
    assert sim["chosen"] is None and "the start fit's" in sim["why"], sim
    assert not d["verdict"].startswith("missing effect"), d["verdict"]


def test_a_model_that_simulates_keeps_the_rankings_verdict():
    d = tfs.diagnose(tfs.Model.from_json(PAPER_MODEL), TEST)
    sim = d["simulation"]
    # Simulated, but nothing to cure: no refit-alone control, and the ranking's verdict stands.
    assert sim["before"]["failed"] == 0 and "refitted" not in sim, sim
    assert sim["ranking_stands"] and sim["reason"] in ("supported", "nothing-significant"), sim
    assert d["verdict"] == d["equation_error_verdict"]
    assert all(t["reason"] for t in sim["tried"]), sim


def test_the_loop_runs_from_python_as_the_cli_runs_it(cli, tmp_path):
    # Identified without any damping term: the loop must find the dashpot first.
    m = tfs.identify(TRAIN, library="x^1..7, xb_acc")
    looped = m.refit(TRAIN, until_clean=2)
    rounds = looped.report["rounds"]
    assert rounds[0]["added"] == "linear-damping", rounds
    # One decision: what `diagnose` names is what the loop adds first.
    assert tfs.diagnose(m, TRAIN)["named"] == rounds[0]["added"]
    ladder = looped.report["ladder"]
    assert ladder[-1]["geo_mean_r_mse"] < ladder[0]["geo_mean_r_mse"] / 5, ladder
    m.save(tmp_path / "m.json")
    out = tmp_path / "looped.json"
    c = run_json(
        [cli, "refit", "--model", str(tmp_path / "m.json"), "--until-clean", "2", "--json"]
        + ["--out", str(out), *map(str, TRAIN)]
    )
    assert rounds == c["rounds"]
    assert json.loads(looped.to_json())["equations"] == c["model"]["equations"]


def test_add_or_until_clean_is_required():
    m = tfs.Model.from_json(PAPER_MODEL)
    try:
        m.refit(TRAIN)
    except tfs.InputError as e:
        assert "until_clean" in str(e) and "--" not in str(e), str(e)
    else:
        raise AssertionError("refit with nothing to add and no loop did not raise")
