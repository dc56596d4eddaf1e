#!/usr/bin/env python3
"""Python overhead of `tfs.identify` on records like `cargo xtask peers`'s: four training sweeps
of the Kresling cell (0.05-2 Hz, 60-120 s at 200 Hz, amplitudes 3-6, white noise at --snr dB).

The Rust time is the library call's own wall time, measured in Rust around the workflow the CLI
runs (`tfs::identify::plan`, validation, offsets, the fit; the model's `report["library_seconds"]`);
the Python time is the wall time of the whole `tfs.identify` call on the same records (arguments
and records handed over from numpy, the model and its warnings back to Python). Both are medians
of --reps calls; the overhead is their difference as a share of the library's time.

    python crates/tfs-py/bench/overhead.py [--snr 30] [--reps 5]
"""

import argparse
import statistics
import time

import numpy as np

import tfs

# (f0 Hz, f1 Hz, duration s, amplitude): the training sweeps of the peers benchmark.
SWEEPS = [(0.05, 1.5, 100.0, 3.0), (0.05, 1.5, 60.0, 4.0), (0.1, 1.2, 80.0, 5.0), (0.05, 2.0, 120.0, 6.0)]
# The cell and its force law: the paper's S-DOF case (gamma0 = 30 deg, the polynomial surrogate).


def records(snr):
    out = []
    for i, (f0, f1, d, a) in enumerate(SWEEPS):
        (r,) = tfs.simulate_kresling(gamma0=30, excitations=[f"sweep:{f0}:{f1}:{a}"], duration=d,
                                     dt=0.005, snr_db=snr, seed=100 + 17 * i)
        # Hand the measured columns over as numpy arrays, as a user would.
        out.append(tfs.Record(np.asarray(r["x"]), t=np.asarray(r.t), inputs={"xb_acc": np.asarray(r["xb_acc"])},
                              name=f"train{i + 1}"))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--snr", type=float, default=30.0)
    ap.add_argument("--reps", type=int, default=5)
    a = ap.parse_args()
    recs = records(a.snr)
    wall, fit = [], []
    for _ in range(a.reps):
        t0 = time.perf_counter()
        m = tfs.identify(recs, library="x^1..7, x', xb_acc")
        wall.append(time.perf_counter() - t0)
        fit.append(m.report["library_seconds"])
    w, f = statistics.median(wall), statistics.median(fit)
    print(f"{len(recs)} records, {sum(len(r) for r in recs)} samples, {a.snr:g} dB: "
          f"tfs.identify {w * 1e3:.1f} ms, the Rust call inside it {f * 1e3:.1f} ms (medians of {a.reps}); "
          f"Python overhead {(w - f) * 1e3:.2f} ms = {100 * (w - f) / f:.2f} % of the fit")
    m.print()
    return 0


if __name__ == "__main__":
    main()
