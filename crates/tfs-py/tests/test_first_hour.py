"""What a Python user meets first: warnings at their own line, results with a headline number,
a refit that says whether it helped, simulate by input name, models from coefficients, errors
in Python's words, and the README's Python block run as written."""

import ast
import re
import subprocess
import sys
import warnings

import numpy as np
import pytest

import tfs
from conftest import LIBRARY, ROOT, TEST, TRAIN

# Identified without a damping term: the diagnosis names the dashpot, and adding it helps.
NO_DAMPING = "x^1..7, xb_acc"


@pytest.fixture(scope="module")
def model():
    return tfs.identify(TRAIN, library=LIBRARY)


@pytest.fixture(scope="module")
def undamped():
    return tfs.identify(TRAIN, library=NO_DAMPING)


def columns(path):
    d = np.loadtxt(path, delimiter=",", skiprows=1)
    return d[:, 0], d[:, 1], d[:, 2]


def test_warnings_name_the_callers_file_and_line():
    # Without the damping term the full library is not supported: identify warns.
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        line = sys._getframe().f_lineno + 1
        tfs.identify(TRAIN, library=NO_DAMPING)
    assert caught, "no warning"
    for w in caught:
        assert w.filename == __file__, (w.filename, str(w.message))
        assert w.lineno == line, (w.lineno, str(w.message))


def test_a_record_without_intervals_says_why():
    t, x, u = columns(TRAIN[0])
    one = tfs.Record(x, t=t, inputs={"xb_acc": u})
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        m = tfs.identify(one, library=LIBRARY)
    assert m.intervals["x"] == {}, m.intervals
    notes = [str(w.message) for w in caught if "no coefficient intervals" in str(w.message)]
    assert notes and "give two or more records" in notes[0], [str(w.message) for w in caught]


def test_compare_returns_a_scalar_r_mse_that_diagnose_reports_too(model):
    c = model.compare(TEST)
    assert isinstance(c, tfs.Comparison)
    assert isinstance(c.r_mse, float) and 0 < c.r_mse < 0.2
    (rec,) = c  # iterating gives the per-record dicts, as `tfs compare --json`'s files
    assert c.r_mse == rec["r_mse"] == c.per_dof["x"]
    assert list(c.per_record.values()) == [{"x": rec["r_mse"]}]
    text = str(c)
    assert "R-MSE" in text and len(text.splitlines()) <= 4, text
    d = tfs.diagnose(model, TEST)
    assert d["r_mse"] == pytest.approx(c.r_mse, rel=1e-12)


def test_compare_scores_short_horizon_pieces_when_asked(model):
    (rec,) = model.compare(TEST, horizon=40)
    assert rec["short_horizon"]["samples"] == 40
    assert 0 <= rec["short_horizon"]["r_mse"] < 0.2, rec["short_horizon"]
    with pytest.raises(ValueError, match="--horizon|horizon"):
        model.compare(TEST, horizon=1)


def test_refit_carries_its_verdict(undamped):
    better = undamped.refit(TRAIN, add=["linear-damping"])
    assert better.improved is True, better.verdict
    assert "lowered the geometric-mean R-MSE" in better.verdict
    assert better.report["verdict"] == better.verdict
    assert undamped.verdict is None and undamped.improved is None


def test_a_refit_that_raises_the_error_warns_at_the_callers_line(model):
    # The model fits these records well: a constant offset adds nothing they support.
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        line = sys._getframe().f_lineno + 1
        worse = model.refit(TRAIN, add=["offset"])
    if worse.improved is not False:
        pytest.skip(f"the offset did not raise the error here: {worse.verdict}")
    assert "raised the geometric-mean R-MSE" in worse.verdict
    raised = [w for w in caught if "worse" in str(w.message)]
    assert raised, [str(w.message) for w in caught]
    assert raised[0].filename == __file__ and raised[0].lineno == line


def test_simulate_takes_inputs_by_name_and_ignores_dropped_ones():
    t, x, u = columns(TRAIN[0])
    t2, x2, u2 = columns(TRAIN[1])
    rng = np.random.default_rng(1)
    recs = [
        tfs.Record(x, t=t, inputs={"xb_acc": u, "probe": 1e-3 * rng.standard_normal(len(t))}),
        tfs.Record(x2, t=t2, inputs={"xb_acc": u2, "probe": 1e-3 * rng.standard_normal(len(t2))}),
    ]
    m = tfs.identify(recs, library=LIBRARY + ", probe")
    assert m.used_inputs == ["xb_acc"], m.coefficients
    assert m.inputs == ["xb_acc", "probe"]
    probe = np.zeros_like(u)
    by_name = m.simulate(t, {"xb_acc": u, "probe": probe}, x0=[x[0]])
    positional = m.simulate(t, np.c_[u, probe], x0=[x[0]])
    used_only = m.simulate(t, u, x0=[x[0]])
    for a, b in zip(by_name, positional):
        np.testing.assert_array_equal(a, b)
    for a, b in zip(by_name, used_only):
        np.testing.assert_array_equal(a, b)
    with pytest.raises(tfs.InputError, match="no input 'force'"):
        m.simulate(t, {"xb_acc": u, "force": u})


def test_from_terms_round_trips_the_coefficients(model):
    again = tfs.Model.from_terms(model.coefficients)
    assert again.coefficients == model.coefficients
    assert again.inputs == ["xb_acc"] and again.dofs == ["x"]
    t, x, u = columns(TEST)
    a = model.simulate(t, u, x0=[x[0]])
    b = again.simulate(t, u, x0=[x[0]])
    np.testing.assert_array_equal(a[0], b[0])
    # A model fitted elsewhere, written in the term grammar.
    duffing = tfs.Model.from_terms({"x": {"x": -1.0, "x^3": -0.5, "x'": -0.1, "u": 1.0}})
    assert duffing.inputs == ["u"]
    with pytest.raises(tfs.InputError, match="x\\^1..3"):
        tfs.Model.from_terms({"x": {"x^1..3": 1.0}})


def test_errors_name_python_keywords_not_cli_flags():
    with pytest.raises(tfs.InputError) as e:
        tfs.identify(TRAIN, threshold=-1.0)
    msg = str(e.value)
    assert "threshold=-1" in msg and "--threshold" not in msg, msg
    with pytest.raises(tfs.InputError) as e:
        tfs.identify(TRAIN, library="x^1..3, x'", tie=True)
    assert "--tie" not in str(e.value) and "tie=True" in str(e.value), str(e.value)


def test_stubs_list_the_closed_sets():
    stub = (ROOT / "crates/tfs-py/python/tfs/_tfs.pyi").read_text()
    tree = ast.parse(stub)
    aliases = {
        n.targets[0].id: ast.unparse(n.value)
        for n in tree.body
        if isinstance(n, ast.Assign) and isinstance(n.targets[0], ast.Name)
    }
    assert aliases["Method"] == "Literal['tfs', 'sindy']"
    assert aliases["Clipped"] == "Literal['error', 'warn', 'allow']"
    ident = next(n for n in tree.body if isinstance(n, ast.FunctionDef) and n.name == "identify")
    kw = {a.arg: ast.unparse(a.annotation) for a in ident.args.kwonlyargs}
    assert kw["method"] == "Method" and kw["offsets"] == "IdentifyOffsets"
    # help() lists the values too.
    assert "'sindy'" in tfs.identify.__doc__ and "'constant-term'" in tfs.identify.__doc__


def readme_python_block():
    """The README's first Python block (the one under "From Python")."""
    text = (ROOT / "README.md").read_text()
    section = text[text.index("## From Python") :]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


def test_the_readme_python_block_runs_and_the_error_falls(tmp_path):
    code = readme_python_block()
    assert "tempfile" in code or "tmp" in code, "the README example must not write into the checkout"
    proc = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=900
    )
    assert proc.returncode == 0, proc.stderr
    out = proc.stdout
    nums = re.findall(r"held-out R-MSE: ([0-9.eE+-]+) -> ([0-9.eE+-]+)", out)
    assert nums, out
    before, after = map(float, nums[0])
    assert after < before, out
    assert not (ROOT / "model.json").exists()
