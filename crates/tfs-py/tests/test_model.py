"""Simulation, prediction, blow-ups, diagnosis, refit, basins and the simulators."""

import math
import pickle
import threading
import time

import numpy as np
import pytest

import tfs
from conftest import PAPER_MODEL, TEST, TRAIN

# A damped linear oscillator x'' = -4 x - 0.2 x' + u.
LINEAR = """{"format":"tfs-model/1","dofs":["x"],"inputs":["u"],"equations":[{"dof":"x",
"terms":[{"term":"x","coef":-4.0},{"term":"x'","coef":-0.2},{"term":"u","coef":1.0}]}]}"""


def test_simulate_matches_the_free_decay():
    m = tfs.Model.from_json(LINEAR)
    t = np.linspace(0, 10, 1001)
    x, v = m.simulate(t, np.zeros_like(t), x0=[1.0])
    zeta_w, wd = 0.1, math.sqrt(4 - 0.01)
    exact = np.exp(-zeta_w * t) * (np.cos(wd * t) + zeta_w / wd * np.sin(wd * t))
    assert x.shape == (1001, 1) and v.shape == (1001, 1)
    np.testing.assert_allclose(x[:, 0], exact, atol=1e-6)


def test_simulate_takes_inputs_by_name():
    m = tfs.Model.from_json(LINEAR)
    t = np.linspace(0, 5, 501)
    u = np.sin(2 * t)
    a, _ = m.simulate(t, u)
    b, _ = m.simulate(t, {"u": u})
    np.testing.assert_array_equal(a, b)
    assert np.abs(a).max() > 0.1


def test_blow_up_raises_with_time_and_state():
    m = tfs.Model.from_json(
        """{"format":"tfs-model/1","dofs":["x"],"inputs":[],"equations":[{"dof":"x",
        "terms":[{"term":"x^3","coef":1.0}]}]}"""
    )
    t = np.linspace(0, 10, 101)
    with pytest.raises(tfs.SimulationError) as e:
        m.simulate(t, x0=[1.0])
    err = e.value
    assert 0 < err.t < 10 and "blew up at t =" in str(err)
    assert len(err.x) == 1 and abs(err.x[0]) > 1e3 or not math.isfinite(err.x[0])
    # It survives pickling (a Dask worker sends it back to the client).
    back = pickle.loads(pickle.dumps(err))
    assert isinstance(back, tfs.SimulationError) and back.t == err.t


def test_predict_is_the_equation():
    m = tfs.Model.from_json(LINEAR)
    x = np.array([0.0, 1.0, -0.5])
    v = np.array([1.0, 0.0, 2.0])
    u = np.array([0.0, 3.0, 1.0])
    np.testing.assert_allclose(m.predict(x, v, u)[:, 0], -4 * x - 0.2 * v + u, rtol=1e-14)


def test_missing_input_is_an_input_error():
    m = tfs.Model.from_json(LINEAR)
    with pytest.raises(tfs.InputError, match=r"takes the input\(s\) \[u\]"):
        m.simulate(np.linspace(0, 1, 11))


def test_diagnose_and_refit():
    m = tfs.identify(TRAIN, library="x^1..7, x', xb_acc")
    d = tfs.diagnose(m, TEST)
    assert isinstance(d["verdict"], str) and d["ranked"]
    names = [r["name"] for r in d["ranked"]]
    assert len(set(names)) == len(names)
    refitted = m.refit(TRAIN, add=["cubic-damping"])
    ladder = refitted.report["ladder"]
    assert [s["step"] for s in ladder][0] != [s["step"] for s in ladder][-1]
    assert len(refitted.terms) > len(m.terms)


def test_basin_of_the_paper_model():
    m = tfs.Model.from_json(PAPER_MODEL)
    b = tfs.basin(m, grid=(24, 20), x=(0.0, 2.0), v=(-3.0, 3.0))
    labels = b["labels"]
    assert labels.shape == (20, 24)
    assert len(b["stable"]) == 2
    for k, share in enumerate(b["shares"]):
        assert share == pytest.approx(np.mean(labels == k))
    # Starting at rest in a well ends in that well.
    i = int(round(b["stable"][1] / 2.0 * 23))
    j = int(np.argmin(np.abs(np.array(b["v"]))))
    assert labels[j, i] == 1


def test_basin_against_truth_and_med():
    m = tfs.Model.from_json(PAPER_MODEL)
    b = tfs.basin(m, grid=(16, 16), truth="kresling")
    assert 0 <= b["boa_error"] < 0.2 and b["truth_labels"].shape == (16, 16)
    r = tfs.med(truth="kresling", grid=(30, 30))
    assert r["energy"] > 0 and r["quasi_static_barrier"] > 0


def test_kresling_cell_and_simulators():
    s = tfs.kresling(gamma0=30)
    assert len(s["stable"]) == 2 and s["barrier"] > 0
    recs = tfs.simulate_kresling(gamma0=30, duration=20, snr_db=30, seed=3)
    assert len(recs) == 1 and "x" in recs[0] and "xb_acc" in recs[0]
    chain = tfs.simulate_chain(duration=10, excitations=["sine:0.5:2"])
    assert {"x1", "x2", "xb_acc"} <= set(chain[0].names)


def test_gil_is_released_during_computation():
    """A Python thread keeps running while a basin map is computed."""
    m = tfs.Model.from_json(PAPER_MODEL)
    ticks = []
    done = threading.Event()

    def counter():
        while not done.is_set():
            ticks.append(time.perf_counter())
            time.sleep(0.001)

    th = threading.Thread(target=counter)
    th.start()
    time.sleep(0.02)
    # Maps grow until one call lasts long enough to count ticks in (basin maps are fast, and
    # how fast depends on the machine), up to a map far larger than any machine needs.
    for n in (120, 300, 700, 1500):
        start = time.perf_counter()
        tfs.basin(m, grid=(n, n))
        end = time.perf_counter()
        if end - start > 0.1:
            break
    done.set()
    th.join()
    during = [t for t in ticks if start < t < end]
    assert end - start > 0.1
    # With the GIL held the counter could not tick at all during the call.
    assert len(during) >= 10
