"""The design-sweep example on a two-worker local Dask cluster: every geometry computed on the
workers equals the same computation in this process."""

import pathlib
import sys

import numpy as np
import pytest

distributed = pytest.importorskip("distributed")

EXAMPLES = pathlib.Path(__file__).resolve().parents[1] / "examples"
sys.path.insert(0, str(EXAMPLES))
import kresling_sweep  # noqa: E402


def test_sweep_on_two_workers_equals_serial(tmp_path):
    import cloudpickle
    from dask.distributed import Client, LocalCluster

    # The workers cannot import the example module: ship its functions by value.
    cloudpickle.register_pickle_by_value(kresling_sweep)
    gammas, a0s = [28.0, 30.0], [1.5, 1.6]
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        with Client(cluster) as client:
            rows = kresling_sweep.sweep(client, gammas, a0s, grid=16)
            workers = client.run(lambda: __import__("os").getpid())
    assert len(workers) == 2
    assert [(r["gamma0"], r["a0"]) for r in rows] == [(g, a) for g in gammas for a in a0s]
    for r in rows:
        serial = kresling_sweep.cell_design(r["gamma0"], r["a0"], grid=16)
        assert r["stable"] == serial["stable"] and r["barrier"] == serial["barrier"]
        if serial["labels"] is None:
            assert r["labels"] is None
        else:
            np.testing.assert_array_equal(r["labels"], serial["labels"])
            assert sum(r["basin_shares"]) <= 1.0 + 1e-12
    assert any(r["labels"] is not None for r in rows), "no bistable geometry in the test grid"
    kresling_sweep.write_table(rows, tmp_path / "sweep.csv")
    lines = (tmp_path / "sweep.csv").read_text().splitlines()
    assert len(lines) == 1 + len(rows)
