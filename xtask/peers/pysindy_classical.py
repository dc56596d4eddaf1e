#!/usr/bin/env python3
"""PySINDy's classical SINDy for Table B1 of `cargo xtask reproduce-paper`.

Reads train1..N.csv (columns t, x, xb_acc) from --data. Classical SINDy as PySINDy does it: the
state (x, v) with v from PySINDy's SmoothedFiniteDifference (a Savitzky-Golay smoother of the
given window, polynomial order 3, then finite differences), x'' from the same differentiation of
v inside SINDy.fit, the 36-column library of run_pysindy.py (every monomial of (x, v) of degree
1..7 plus the input), PySINDy's STLSQ with its defaults but the threshold.

  --grid           one candidate per (window, threshold) fitted on every record but the last,
                   with its x'' equation error on the last record; the Rust side chooses (per
                   window the lowest held-out BIC among candidates with terms that simulate the
                   last record, then the window whose choice simulates it best).
  --final W T      the chosen window W and threshold T fitted on every record (timed: median
                   of TIMING_REPS calls).

Each model is written as tfs-model/1 JSON and listed in index.json with its parameters.
"""

import argparse
import json
import os
import warnings

import numpy as np
import pysindy as ps
from pysindy.utils import AxesArray

from run_pysindy import library, read, timed, write_model

WINDOWS = [11, 21, 41, 81]  # Savitzky-Golay window lengths (samples), the Rust side's half-widths 5..40
THRESHOLDS = [float(f"{1e-3 * 10 ** (k / 3):.4g}") for k in range(16)]  # 0.001 .. 100, raw units
POLYORDER = 3


def differentiation(window):
    return ps.SmoothedFiniteDifference(smoother_kws={"window_length": window, "polyorder": POLYORDER})


def states(recs, window):
    """The state (x, v) of every record, v = x' by PySINDy's smoothed differences."""
    diff = differentiation(window)
    return [np.column_stack([x, np.asarray(diff(x.reshape(-1, 1), t)).ravel()]) for t, x, _ in recs]


def fit(recs, window, threshold):
    """PySINDy classical SINDy on recs with the smoothed differences of `window` samples."""
    m = ps.SINDy(
        optimizer=ps.STLSQ(threshold=threshold),
        feature_library=library(),
        differentiation_method=differentiation(window),
    )
    xs = states(recs, window)
    m.fit(xs, t=[r[0] for r in recs], u=[r[2].reshape(-1, 1) for r in recs], feature_names=["x", "v", "u"])
    return m


def rows(m, recs, window):
    """SINDy.fit's regression rows for recs: each record's state differentiated and smoothed by
    the differentiation of `window` samples, the library of the smoothed state and the input."""
    thetas, dxs = [], []
    for s, (t, _, u) in zip(states(recs, window), recs):
        diff = differentiation(window)
        dxs.append(np.asarray(diff(s, t)))
        z = np.column_stack([np.asarray(diff.smoothed_x_), u])
        thetas.append(np.asarray(m.feature_library.transform([AxesArray(z, {"ax_time": 0, "ax_coord": 1})])[0]))
    return np.vstack(thetas), np.vstack(dxs)


def grid(recs, held, window, thresholds):
    """One fit on recs per threshold at `window`, the same as fit() gives (SINDy.fit's rows built
    once, then PySINDy's STLSQ per threshold), with its x'' equation error on the held-out
    record `held` (its rows built the same way). Yields (threshold, feature names, x'' row
    coefficients, held-out residual sum of squares, held-out rows)."""
    m = fit(recs, window, thresholds[0])
    theta, dx = rows(m, recs, window)
    theta_h, dx_h = rows(m, [held], window)
    names = m.get_feature_names()
    for thr in thresholds:
        o = ps.STLSQ(threshold=thr)
        o.fit(theta, dx)
        c = np.asarray(o.coef_)[1]
        rss = float(np.sum((dx_h[:, 1] - theta_h @ c) ** 2))
        yield thr, names, c, rss, int(dx_h.shape[0])


def save(out, file, names, coefs, params, index, secs=None, held=None):
    write_model(os.path.join(out, file), names, coefs, "pysindy-classical", params)
    entry = {"file": file, "params": params, "terms": int(np.count_nonzero(coefs))}
    if held is not None:
        entry["held_out_rss"], entry["held_out_rows"] = held
    if secs is not None:
        entry["fit_seconds"] = secs
    index.append(entry)


def main():
    warnings.filterwarnings("ignore", message=".*axes labeled.*")
    warnings.filterwarnings("ignore", message="Sparsity parameter is too big")
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", required=True, help="folder with train1..N.csv")
    ap.add_argument("--out", required=True, help="folder for models and index.json")
    ap.add_argument("--grid", action="store_true", help="candidates fitted without the last record")
    ap.add_argument("--final", nargs=2, type=float, metavar=("WINDOW", "THRESHOLD"))
    a = ap.parse_args()
    if a.grid == (a.final is not None):
        raise SystemExit("give exactly one of --grid and --final WINDOW THRESHOLD")
    os.makedirs(a.out, exist_ok=True)
    recs = []
    while os.path.exists(os.path.join(a.data, f"train{len(recs) + 1}.csv")):
        recs.append(read(os.path.join(a.data, f"train{len(recs) + 1}.csv")))
    if len(recs) < 2:
        raise SystemExit(f"{a.data}: need train1.csv and train2.csv at least (the last one is held out)")
    index = []
    if a.grid:
        for w in WINDOWS:
            for thr, names, coefs, rss, m in grid(recs[:-1], recs[-1], w, THRESHOLDS):
                params = {"window": w, "threshold": thr}
                save(a.out, f"grid_w{w}_thr{thr}.json", names, coefs, params, index, held=(rss, m))
    else:
        w, thr = int(a.final[0]), a.final[1]
        model, secs = timed(lambda: fit(recs, w, thr))
        coefs = np.asarray(model.coefficients())[1]  # the v row: x'' = ...
        save(a.out, "final.json", model.get_feature_names(), coefs, {"window": w, "threshold": thr}, index, secs)
    with open(os.path.join(a.out, "index.json"), "w") as f:
        json.dump({"pysindy": getattr(ps, "__version__", ""), "held_out": f"train{len(recs)}", "models": index}, f, indent=1)


if __name__ == "__main__":
    main()
