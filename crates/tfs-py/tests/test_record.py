import pickle

import numpy as np
import pytest

import tfs
from conftest import TEST


def sine_record(n=200, dt=0.01):
    t = np.arange(n) * dt
    return t, np.sin(3 * t), np.cos(5 * t)


def test_from_arrays_with_dt_or_t():
    t, x, u = sine_record()
    a = tfs.Record(x, dt=0.01, inputs={"u": u})
    b = tfs.Record(x, t=t, inputs={"u": u})
    assert a.names == ["x", "u"] == b.names
    assert len(a) == 200 and a.dt == pytest.approx(0.01)
    np.testing.assert_array_equal(a["x"], x)
    np.testing.assert_allclose(a.t, t, rtol=0, atol=1e-12)
    assert "u" in a and "y" not in a


def test_several_dofs_are_named_x1_x2():
    t, x, u = sine_record()
    r = tfs.Record(np.column_stack([x, 2 * x]), dt=0.01, inputs={"xb_acc": u})
    assert r.names == ["x1", "x2", "xb_acc"]
    np.testing.assert_array_equal(r["x2"], 2 * x)


def test_csv_matches_the_file():
    r = tfs.Record.from_csv(TEST)
    data = np.loadtxt(TEST, delimiter=",", skiprows=1)
    np.testing.assert_array_equal(r["x"], data[:, 1])
    np.testing.assert_array_equal(r["xb_acc"], data[:, 2])
    assert r.source == str(TEST)


def test_csv_round_trip(tmp_path):
    t, x, u = sine_record()
    r = tfs.Record(x, t=t, inputs={"u": u})
    r.to_csv(tmp_path / "r.csv")
    back = tfs.Record.from_csv(tmp_path / "r.csv")
    np.testing.assert_array_equal(back["x"], r["x"])
    np.testing.assert_array_equal(back.t, r.t)


def test_pickle_round_trip():
    t, x, u = sine_record()
    r = tfs.Record(x, t=t, inputs={"u": u}, name="rig-3")
    back = pickle.loads(pickle.dumps(r))
    assert back.source == "rig-3" and back.names == r.names
    np.testing.assert_array_equal(back["u"], u)


def test_nan_names_column_and_row():
    t, x, u = sine_record()
    x[41] = np.nan
    with pytest.raises(tfs.InputError) as e:
        tfs.Record(x, t=t, inputs={"u": u}, name="bench")
    msg = str(e.value)
    assert "bench" in msg and "row 42" in msg and "'x'" in msg
    # A bad-input error is a ValueError too, and a TfsError.
    assert isinstance(e.value, ValueError) and isinstance(e.value, tfs.TfsError)


def test_non_uniform_time_is_refused_with_the_row():
    t, x, u = sine_record()
    t[100:] += 0.004
    with pytest.raises(ValueError, match="row 101"):
        tfs.Record(x, t=t, inputs={"u": u})


def test_lengths_must_agree():
    t, x, u = sine_record()
    with pytest.raises(tfs.InputError, match="'u' has 199 rows"):
        tfs.Record(x, t=t, inputs={"u": u[:-1]})


def test_time_axis_or_step_required():
    _, x, _ = sine_record()
    with pytest.raises(tfs.InputError, match="time axis t or the sampling interval dt"):
        tfs.Record(x)
