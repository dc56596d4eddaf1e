#!/usr/bin/env python3
"""The same numpy arrays through PySINDy's weak form and through tfs: both models printed, and
both scored the same way on a held-out record (free-run simulation under its measured input).

    pip install pysindy      # plus the tfs package (see README)
    python crates/tfs-py/examples/pysindy_side_by_side.py [--threshold 0.1]

The records are the repository's 30 dB Kresling fixtures (base excitation `xb_acc`, displacement
`x`). PySINDy gets the first-order state (x, v), v from its smoothed finite differences, and the
input u; tfs gets x and the input and identifies the second-order equation directly.
"""

import argparse
import json
import pathlib
import time
import warnings

import numpy as np
import pysindy as ps

import tfs

ROOT = pathlib.Path(__file__).resolve().parents[3]
TRAIN = ROOT / "fixtures" / "kresling-30db-train-1.csv"
TEST = ROOT / "fixtures" / "kresling-30db-test.csv"


def load(path):
    t, x, u = np.loadtxt(path, delimiter=",", skiprows=1, usecols=(0, 1, 2)).T
    return t, x, u


def pysindy_weak(t, x, u, threshold):
    v = ps.SmoothedFiniteDifference()(x, t)
    weak = ps.WeakPDELibrary(
        function_library=ps.PolynomialLibrary(degree=7), spatiotemporal_grid=t, K=200, p=4, H_xt=1.0
    )
    model = ps.SINDy(feature_library=weak, optimizer=ps.STLSQ(threshold=threshold))
    return model.fit(np.c_[x, v], t=t, u=u, feature_names=["x", "v", "u"])


def as_tfs_model(sindy):
    """PySINDy's v row (x'' = ...) as a tfs model, so both are scored by the same simulation."""
    terms = []
    for name, coef in zip(sindy.get_feature_names(), np.asarray(sindy.coefficients())[1]):
        if coef == 0.0:
            continue
        factors = []
        for tok in name.split():
            var, _, power = tok.partition("^")
            base = {"x": "x", "v": "x'", "u": "xb_acc", "1": "1"}[var]
            factors.append(base if not power else f"{base}^{power}")
        terms.append({"term": "*".join(factors), "coef": float(coef)})
    text = {"format": "tfs-model/1", "dofs": ["x"], "equations": [{"dof": "x", "terms": terms}],
            "method": "pysindy-weak"}
    return tfs.Model.from_json(json.dumps(text))


def main():
    warnings.filterwarnings("ignore")
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--threshold", type=float, default=0.1, help="PySINDy's STLSQ threshold")
    a = ap.parse_args()
    t, x, u = load(TRAIN)

    t0 = time.perf_counter()
    sindy = pysindy_weak(t, x, u, a.threshold)
    t_sindy = time.perf_counter() - t0
    t0 = time.perf_counter()
    model = tfs.identify(tfs.Record(x, t=t, inputs={"xb_acc": u}), library="x^1..7, x', xb_acc")
    t_tfs = time.perf_counter() - t0

    print(f"PySINDy weak form ({t_sindy:.2f} s):")
    sindy.print()
    print(f"\ntfs ({t_tfs:.2f} s):")
    model.print()

    tt, xt, ut = load(TEST)
    test = tfs.Record(xt, t=tt, inputs={"xb_acc": ut}, name="held-out sweep")
    print(f"\nheld-out R-MSE (free-run simulation under the measured input, {TEST.name}):")
    for label, m in [("PySINDy weak", as_tfs_model(sindy)), ("tfs", model)]:
        try:
            (score,) = m.compare(test)
            print(f"  {label:<14} {score['r_mse']:.4g}")
        except tfs.SimulationError as e:
            print(f"  {label:<14} blew up at t = {e.t:.4g} s")
        except tfs.TfsError as e:
            print(f"  {label:<14} cannot be simulated: {e}")


if __name__ == "__main__":
    main()
