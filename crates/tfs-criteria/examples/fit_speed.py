#!/usr/bin/env python3
"""T-F-S's fit against PySINDy 2.1's weak-form fit on the same `cargo xtask peers` records, in one run.

    cargo build -p tfs-criteria --example profile_peers
    target/peers/venv/bin/python crates/tfs-criteria/examples/fit_speed.py \\
        --data target/peers/data --cases white60,white30,white20,pink30 \\
        --tfs target/debug/examples/profile_peers [--tfs other/profile_peers ...]

PySINDy's weak fit is timed as `xtask/peers/run_pysindy.py` times it (its own functions are
imported): velocity smoothing, weak library rows and STLSQ, each step the median of five calls, for
every test-function half-width H of its grid (the peers benchmark picks one H per case by test
error; this script shows them all). The tfs fit is `identify_tfs` with the 9-column and the
36-column library, timed by `profile_peers` (the median of five calls, as `cargo xtask peers`).
Cases are run one after the other and, within a case, PySINDy and every tfs build in turn, so that
a change in the machine's load touches them alike.

Two clocks: wall time (tfs on all cores, as the peers table), and CPU time (PySINDy's process time;
tfs on one thread, `RAYON_NUM_THREADS=1`, the CPU time of nine fits less that of one, over eight).
On a shared machine the CPU times are the steadier comparison.
"""

import argparse
import os
import re
import resource
import statistics
import subprocess
import sys
import time
import warnings

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "..", "..", "xtask", "peers"))


def pysindy_times(rp, ps, data, case):
    """{H: (wall ms, CPU ms)} of PySINDy's weak fit on the case's training records."""
    recs = [rp.read(os.path.join(data, case, f"train{i}.csv")) for i in range(1, 5)]

    def both(fn):
        walls, cpus, out = [], [], None
        for _ in range(rp.TIMING_REPS):
            t0, c0 = time.perf_counter(), time.process_time()
            out = fn()
            walls.append(time.perf_counter() - t0)
            cpus.append(time.process_time() - c0)
        return out, statistics.median(walls), statistics.median(cpus)

    recs_v, w_vel, c_vel = both(lambda: [(t, x, u, rp.velocity(t, x)) for t, x, u in recs])
    out = {}
    for h in rp.H_GRID:
        (theta, lhs, _), w_lib, c_lib = both(lambda: rp.weak_rows(recs_v, h))

        def fit():
            o = ps.STLSQ(threshold=0.1)
            o.fit(theta, lhs)
            return o

        _, w_fit, c_fit = both(fit)
        out[h] = (1e3 * (w_vel + w_lib + w_fit), 1e3 * (c_vel + c_lib + c_fit))
    return out


def tfs_wall(binary, data, case, classical):
    """Median of five `identify_tfs` calls (ms), all cores."""
    cmd = [binary, os.path.join(data, case), "5"] + (["classical"] if classical else [])
    out = subprocess.run(cmd, capture_output=True, text=True, check=True).stdout
    return statistics.median(float(m.group(1)) for m in re.finditer(r"^tfs ([0-9.]+) ms", out, re.M))


def tfs_cpu(binary, data, case, classical):
    """CPU ms of one `identify_tfs` call on one thread: nine calls less one, over eight."""
    env = dict(os.environ, RAYON_NUM_THREADS="1")

    def cpu(reps):
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        cmd = [binary, os.path.join(data, case), str(reps)] + (["classical"] if classical else [])
        subprocess.run(cmd, capture_output=True, check=True, env=env)
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)

    return 1e3 * (cpu(9) - cpu(1)) / 8


def main():
    warnings.filterwarnings("ignore")
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default="target/peers/data", help="the peers run's data folder")
    ap.add_argument("--cases", default="white60,white30,white20,pink30")
    ap.add_argument("--tfs", action="append", required=True, help="a profile_peers binary (repeatable)")
    a = ap.parse_args()
    import pysindy as ps
    import run_pysindy as rp

    for case in a.cases.split(","):
        py = pysindy_times(rp, ps, a.data, case)
        print(f"\n{case}  (load {os.getloadavg()[0]:.1f})")
        print("  PySINDy weak, per H: " + ", ".join(f"H={h}: {w:.0f} ms wall, {c:.0f} ms CPU" for h, (w, c) in py.items()))
        walls = [w for w, _ in py.values()]
        cpus = [c for _, c in py.values()]
        for b in a.tfs:
            for lib, classical in (("9 columns", False), ("36 columns", True)):
                w = tfs_wall(b, a.data, case, classical)
                c = tfs_cpu(b, a.data, case, classical)
                print(
                    f"  {b} {lib}: {w:.1f} ms wall, {c:.1f} ms CPU; PySINDy/tfs wall {min(walls) / w:.1f}-{max(walls) / w:.1f}x, "
                    f"CPU {min(cpus) / c:.1f}-{max(cpus) / c:.1f}x (over H)",
                    flush=True,
                )


if __name__ == "__main__":
    main()
