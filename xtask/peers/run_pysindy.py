#!/usr/bin/env python3
"""PySINDy side of `cargo xtask peers`.

Reads train1..4.csv (columns t, x, xb_acc) from --data and fits, with PySINDy itself:

  weak       weak-form SINDy (WeakPDELibrary) on the state (x, v), v = x' from PySINDy's
             SmoothedFiniteDifference (Savitzky-Golay 21/3, then central differences), input
             u = xb_acc; library = every monomial of (x, v) of degree 1..7 (35 columns) plus u;
             STLSQ. One candidate per (test-function half-width H, threshold) of a small grid.
  classical  classical SINDy (SINDy with FiniteDifference derivatives) on the state (x, x'), x'
             by finite differences, same 36-column library, STLSQ. One candidate per threshold.

The records have different durations, so the weak library is built per record on its own time
grid (K subdomains proportional to the record length) and the weak rows of all records are
stacked before PySINDy's STLSQ is fitted on them.

Each candidate is written as a tfs-model/1 JSON (the second-order equation x'' = ... is the v row
of the first-order system; terms `x^i*x'^j`, `xb_acc`, `1`) and listed in index.json with its
parameters and fit time (each timed step the median of TIMING_REPS identical calls, as tfs's fit
time is the median of five). Selection among candidates (by test R-MSE, an oracle) and all scoring
are done by the Rust side with the same code for every method.
"""

import argparse
import json
import os
import time
import warnings

import numpy as np
import pysindy as ps
from pysindy.utils import AxesArray

DEGREE = 7
SG = {"window_length": 21, "polyorder": 3}
H_GRID = [0.25, 0.5, 1.0, 2.0]  # test-function half-width (s)
THRESHOLDS = [0.01, 0.03, 0.1, 0.3, 1.0]
SUBDOMAINS_PER_HALF_WIDTH = 2.0  # K = ceil(2 * duration / H) subdomains of length 2H: each sample lies in ~4 on average


TIMING_REPS = 5  # every timed step is the median of this many identical calls, as tfs's fit time


def timed(fn):
    """(result, median seconds) of TIMING_REPS identical calls of fn()."""
    secs = []
    out = None
    for _ in range(TIMING_REPS):
        t0 = time.perf_counter()
        out = fn()
        secs.append(time.perf_counter() - t0)
    return out, float(np.median(secs))


def read(path):
    with open(path) as f:
        header = f.readline().strip().split(",")
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    cols = {name: data[:, i] for i, name in enumerate(header)}
    for need in ("t", "x", "xb_acc"):
        if need not in cols:
            raise SystemExit(f"{path}: no column '{need}' (header: {','.join(header)})")
    return cols["t"], cols["x"], cols["xb_acc"]


def library():
    return ps.GeneralizedLibrary(
        [ps.PolynomialLibrary(degree=DEGREE, include_bias=False), ps.IdentityLibrary()],
        inputs_per_library=[[0, 1], [2]],
    )


def term_name(feature):
    """PySINDy feature name over (x, v, u) -> tfs term."""
    if feature.strip() == "1":
        return "1"
    i = j = 0
    k = 0
    for tok in feature.split():
        var, _, power = tok.partition("^")
        p = int(power) if power else 1
        if var == "x":
            i += p
        elif var == "v":
            j += p
        elif var == "u":
            k += p
        else:
            raise ValueError(f"unexpected factor '{tok}' in feature '{feature}'")
    if k:
        if k != 1 or i or j:
            raise ValueError(f"feature '{feature}': only a linear input term is expected")
        return "xb_acc"
    parts = []
    if i:
        parts.append("x" if i == 1 else f"x^{i}")
    if j:
        parts.append("x'" if j == 1 else f"x'^{j}")
    return "*".join(parts)


def write_model(path, names, coefs, method, params):
    terms = [{"term": term_name(n), "coef": float(c)} for n, c in zip(names, coefs) if c != 0.0]
    model = {
        "format": "tfs-model/1",
        "dofs": ["x"],
        "equations": [{"dof": "x", "terms": terms}],
        "method": method,
        "trace": {"pysindy": ps.__version__ if hasattr(ps, "__version__") else "", "params": params},
    }
    with open(path, "w") as f:
        json.dump(model, f, indent=1)


def velocity(t, x):
    d = ps.SmoothedFiniteDifference(smoother_kws=dict(SG))
    return np.asarray(d(x.reshape(-1, 1), t)).ravel()


def weak_rows(recs, h):
    thetas, lhss, names = [], [], None
    for t, x, u, v in recs:
        duration = t[-1] - t[0]
        if 2 * h >= duration / 2:
            raise ValueError(f"H = {h} s is too wide for a {duration:.1f} s record")
        k = int(np.ceil(SUBDOMAINS_PER_HALF_WIDTH * duration / h))
        np.random.seed(12345)  # subdomain centres are random in PySINDy
        # PySINDy's WeakPDELibrary cannot wrap a GeneralizedLibrary (inputs_per_library fails on
        # its single-sample fit), so the full degree-7 polynomial of (x, v, u) is built and the
        # 36 wanted columns (u-free monomials and u itself) are kept.
        poly = ps.PolynomialLibrary(degree=DEGREE, include_bias=False)
        lib = ps.WeakPDELibrary(function_library=poly, spatiotemporal_grid=t, K=k, H_xt=h, p=4)
        xs = AxesArray(np.column_stack([x, v, u]), {"ax_time": 0, "ax_coord": 1})
        state = AxesArray(np.column_stack([x, v]), {"ax_time": 0, "ax_coord": 1})
        lib.fit([xs])
        all_names = poly.get_feature_names(["x", "v", "u"])
        keep = [i for i, n in enumerate(all_names) if n == "u" or all(f.partition("^")[0] != "u" for f in n.split())]
        theta = np.asarray(lib.transform([xs])[0])[:, keep]
        lhs = np.asarray(lib.convert_u_dot_integral(state))
        thetas.append(theta)
        lhss.append(lhs)
        if names is None:
            names = [all_names[i] for i in keep]
    return np.vstack(thetas), np.vstack(lhss), names


def main():
    warnings.filterwarnings("ignore", message=".*axes labeled.*")
    warnings.filterwarnings("ignore", message="Sparsity parameter is too big")
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", required=True, help="folder with train1..4.csv")
    ap.add_argument("--out", required=True, help="folder for candidate models and index.json")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    recs = []
    i = 1
    while os.path.exists(os.path.join(a.data, f"train{i}.csv")):
        t, x, u = read(os.path.join(a.data, f"train{i}.csv"))
        recs.append((t, x, u))
        i += 1
    if not recs:
        raise SystemExit(f"{a.data}: no train1.csv")
    index = {"pysindy": getattr(ps, "__version__", ""), "weak": [], "classical": []}

    # (a) weak form
    recs_v, t_vel = timed(lambda: [(t, x, u, velocity(t, x)) for t, x, u in recs])
    for h in H_GRID:
        try:
            (theta, lhs, names), t_lib = timed(lambda: weak_rows(recs_v, h))
        except ValueError as e:
            print(f"weak H={h}: skipped ({e})")
            continue
        for thr in THRESHOLDS:
            def fit():
                o = ps.STLSQ(threshold=thr)
                o.fit(theta, lhs)
                return o
            opt, t_fit = timed(fit)
            secs = t_vel + t_lib + t_fit
            coefs = np.asarray(opt.coef_)[1]  # the v row: x'' = ...
            file = f"weak_H{h}_thr{thr}.json"
            params = {"H_xt": h, "threshold": thr, "K_per_record": [int(np.ceil(SUBDOMAINS_PER_HALF_WIDTH * (r[0][-1] - r[0][0]) / h)) for r in recs], "p": 4}
            write_model(os.path.join(a.out, file), names, coefs, "pysindy-weak", params)
            index["weak"].append({"file": file, "params": params, "fit_seconds": secs})

    # (b) classical SINDy with finite differences
    for thr in THRESHOLDS:
        def fit():
            fd = ps.FiniteDifference()
            xs = [np.column_stack([x, np.asarray(fd(x.reshape(-1, 1), t)).ravel()]) for t, x, _ in recs]
            m = ps.SINDy(optimizer=ps.STLSQ(threshold=thr), feature_library=library(), differentiation_method=ps.FiniteDifference())
            m.fit(xs, t=[r[0] for r in recs], u=[r[2].reshape(-1, 1) for r in recs], feature_names=["x", "v", "u"])
            return m
        model, secs = timed(fit)
        names = model.get_feature_names()
        coefs = np.asarray(model.coefficients())[1]
        file = f"classical_thr{thr}.json"
        params = {"threshold": thr}
        write_model(os.path.join(a.out, file), names, coefs, "pysindy-classical", params)
        index["classical"].append({"file": file, "params": params, "fit_seconds": secs})

    with open(os.path.join(a.out, "index.json"), "w") as f:
        json.dump(index, f, indent=1)
    print(f"pysindy {index['pysindy']}: {len(index['weak'])} weak and {len(index['classical'])} classical candidates in {a.out}")


if __name__ == "__main__":
    main()
