"""identify and the Model: the CLI's results to the bit, and the model's API."""

import json
import pickle
import subprocess

import numpy as np
import pytest

import tfs
from conftest import LIBRARY, TEST, TRAIN


@pytest.fixture(scope="module")
def cli_model(cli, tmp_path_factory):
    out = tmp_path_factory.mktemp("cli") / "model.json"
    subprocess.run(
        [cli, "identify", *map(str, TRAIN), "--library", LIBRARY, "--out", str(out)],
        check=True,
        capture_output=True,
    )
    return json.loads(out.read_text())


@pytest.fixture(scope="module")
def model():
    return tfs.identify(TRAIN, library=LIBRARY)


def test_paths_give_the_cli_model_to_the_bit(cli_model, model):
    py = json.loads(model.to_json())
    # Floats are written so that reading them gives back the same bits: equal JSON numbers
    # are equal coefficients and intervals.
    assert py["equations"] == cli_model["equations"]
    assert py["trace"]["offsets"] == cli_model["trace"]["offsets"]
    assert py["dofs"] == cli_model["dofs"] and py["inputs"] == cli_model["inputs"]


def test_arrays_give_the_cli_model_to_the_bit(cli_model):
    recs = []
    for p in TRAIN:
        d = np.loadtxt(p, delimiter=",", skiprows=1)
        recs.append(tfs.Record(d[:, 1], t=d[:, 0], inputs={"xb_acc": d[:, 2]}, name=str(p)))
    m = tfs.identify(recs, library=LIBRARY)
    assert json.loads(m.to_json())["equations"] == cli_model["equations"]


def test_coefficients_dict_and_array_agree(model):
    coefs = model.coefficients
    arr = model.coefficient_array
    assert arr.shape == (1, len(model.terms))
    for j, term in enumerate(model.terms):
        assert arr[0, j] == coefs["x"][term]
    # The identified cell: a negative linear damping and the base input with coefficient ~ -1.
    assert coefs["x"]["xb_acc"] == pytest.approx(-1.0, rel=0.1)
    assert coefs["x"]["x'"] < 0


def test_equations_and_intervals(model):
    (eq,) = model.equations()
    assert eq.startswith("x'' =") and "±" in eq
    assert str(model) == eq
    lo, hi = model.intervals["x"]["xb_acc"]
    assert lo <= model.coefficients["x"]["xb_acc"] <= hi


def test_trace_is_a_dict(model):
    tr = model.trace
    assert tr["method"] == model.method == "tfs-sindy"
    assert tr["dofs"][0]["dof"] == "x"
    assert tr["offsets"]["mode"] == "keep"  # base excitation: origin kept


def test_json_pickle_and_files(model, tmp_path):
    assert tfs.Model.from_json(model.to_json()) == model
    assert pickle.loads(pickle.dumps(model)) == model
    model.save(tmp_path / "m.json")
    assert tfs.load(tmp_path / "m.json") == model
    assert tfs.Model.load(tmp_path / "m.json").to_json() == model.to_json()


def test_compare_equals_the_cli(cli, model, tmp_path):
    model.save(tmp_path / "m.json")
    out = subprocess.run(
        [cli, "compare", "--model", str(tmp_path / "m.json"), str(TEST), "--json"],
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    (cli_file,) = json.loads(out)["files"]
    (py_file,) = model.compare(TEST)
    assert py_file["r_mse"] == cli_file["r_mse"]
    assert py_file["dofs"] == cli_file["dofs"]
    assert py_file["r_mse"] < 0.2


def test_sindy_method_and_threshold(model):
    m = tfs.identify(TRAIN, library=LIBRARY, method="sindy", threshold=0.05)
    assert m.method == "sindy"
    assert all(abs(c) >= 0.05 for c in m.coefficients["x"].values())


def test_bad_options_are_input_errors():
    with pytest.raises(tfs.InputError, match="method 'lasso': expected tfs or sindy"):
        tfs.identify(TRAIN, method="lasso")
    with pytest.raises(ValueError, match="threshold=-1"):
        tfs.identify(TRAIN, threshold=-1.0)
    with pytest.raises(tfs.InputError, match="offsets 'sometimes'"):
        tfs.identify(TRAIN, offsets="sometimes")


def test_error_messages_are_the_cli_s(cli):
    """The same bad input gives the same one-line message from Python as from the CLI, with
    the Python keyword where the CLI names its flag."""
    cases = [
        ["--library", "x^1..3, x', force"],
        ["--library", "x^1..3, x'", "--tie"],
    ]
    for args in cases:
        proc = subprocess.run(
            [cli, "identify", *map(str, TRAIN), *args], capture_output=True, text=True
        )
        assert proc.returncode == 2
        cli_msg = proc.stderr.strip().splitlines()[-1].removeprefix("error: ")
        kwargs = {"library": args[1], "tie": "--tie" in args}
        with pytest.raises(tfs.InputError) as e:
            tfs.identify(TRAIN, **kwargs)
        keywords = cli_msg.replace("--library", "library").replace("--tie", "tie=True")
        assert str(e.value) == keywords
