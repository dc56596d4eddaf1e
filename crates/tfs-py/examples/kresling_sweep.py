#!/usr/bin/env python3
"""Design sweep of the Kresling cell on Dask distributed: gamma0 x a0 -> stable states, energy
barrier and basin-of-attraction map of every geometry, gathered into one table and one figure.

One task per geometry; the same code runs on a laptop (a LocalCluster) and on a Slurm cluster
(dask-jobqueue's SLURMCluster, see docs/python.md). Each worker runs one task at a time on one core:
tfs's own thread pool is pinned to one thread per worker process (RAYON_NUM_THREADS=1), so
the workers, not the threads inside a task, share the cores.

    python kresling_sweep.py --gamma0 26:34:5 --a0 1.4:1.8:5 --grid 60 --workers 1,2 --out sweep

prints the table and, with several worker counts, the time of each and the speed-up.
"""

import argparse
import csv
import json
import os
import pathlib
import tempfile
import time

import numpy as np

# Set before any worker process starts: they inherit it (and tfs reads it at its first parallel
# call in each process).
os.environ.setdefault("RAYON_NUM_THREADS", "1")

import tfs  # noqa: E402


def cell_design(gamma0, a0, grid=60):
    """Stable states, barrier and (for a bistable cell) the truss truth's basin map of one
    geometry. A plain function of its arguments: Dask ships it to the workers."""
    s = tfs.kresling(gamma0=gamma0, a0=a0)
    row = {
        "gamma0": gamma0,
        "a0": a0,
        "classification": s["classification"],
        "stable": s["stable"],
        "unstable": s["unstable"],
        "barrier": s["barrier"],
        "basin_shares": None,
        "labels": None,
    }
    if len(s["stable"]) >= 2:
        top = 1.15 * max(s["stable"] + s["unstable"])
        b = tfs.basin(
            truth="kresling:truss",
            cell={"gamma0": gamma0, "a0": a0},
            grid=(grid, grid),
            x=(0.0, top),
            v=(-3.0, 3.0),
        )
        row["basin_shares"] = b["shares"]
        row["labels"] = b["labels"]
    return row


def grid_of(text):
    """`A:B:N` -> N values from A to B; `A,B,C` -> those values."""
    if ":" in text:
        a, b, n = text.split(":")
        return list(np.linspace(float(a), float(b), int(n)))
    return [float(v) for v in text.split(",")]


def sweep(client, gammas, a0s, grid):
    """Runs every (gamma0, a0) on the cluster behind `client`; rows in grid order."""
    pairs = [(g, a) for g in gammas for a in a0s]
    futures = client.map(cell_design, [g for g, _ in pairs], [a for _, a in pairs], grid=grid, pure=False)
    return client.gather(futures)


def write_table(rows, path):
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["gamma0_deg", "a0", "classification", "stable_heights", "unstable_heights", "barrier", "basin_shares"])
        for r in rows:
            w.writerow([
                f"{r['gamma0']:.4g}", f"{r['a0']:.4g}", r["classification"],
                " ".join(f"{h:.4g}" for h in r["stable"]), " ".join(f"{h:.4g}" for h in r["unstable"]),
                "" if r["barrier"] is None else f"{r['barrier']:.4g}",
                "" if r["basin_shares"] is None else " ".join(f"{s:.4g}" for s in r["basin_shares"]),
            ])


def write_figure(rows, gammas, a0s, path):
    """Barrier over the design grid, and the share of the upper state's basin (needs matplotlib)."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib not installed: no figure (pip install matplotlib)")
        return None
    barrier = np.full((len(gammas), len(a0s)), np.nan)
    share = np.full_like(barrier, np.nan)
    for k, r in enumerate(rows):
        i, j = divmod(k, len(a0s))
        if r["barrier"] is not None:
            barrier[i, j] = r["barrier"]
        if r["basin_shares"]:
            share[i, j] = r["basin_shares"][-1]
    fig, axes = plt.subplots(1, 2, figsize=(10, 4), constrained_layout=True)
    def edges(v):  # cell edges half a step beyond the first and last values
        h = (v[-1] - v[0]) / (2 * max(len(v) - 1, 1)) or 0.5
        return v[0] - h, v[-1] + h

    extent = [*edges(a0s), *edges(gammas)]
    for ax, data, title, unit in [
        (axes[0], barrier, "Energy barrier from the folded state\n(white: monostable)", "barrier (energy, cell units)"),
        (axes[1], share, "Share of the upper stable state's basin\n(white: monostable)", "share of the (x0, v0) grid (-)"),
    ]:
        im = ax.imshow(data, origin="lower", aspect="auto", extent=extent)
        ax.set_xlabel("crease length a0 (cell units)")
        ax.set_ylabel("crease-pattern angle gamma0 (deg)")
        ax.set_title(title)
        fig.colorbar(im, ax=ax, label=unit)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--gamma0", default="26:34:5", help="A:B:N or a comma list (degrees)")
    ap.add_argument("--a0", default="1.4:1.8:5", help="A:B:N or a comma list")
    ap.add_argument("--grid", type=int, default=60, help="basin grid N (N x N starts)")
    ap.add_argument("--workers", default="2", help="worker counts to time, e.g. 1,2")
    ap.add_argument("--out", help="folder for sweep.csv, sweep.png, sweep.json (default: a new temporary folder)")
    ap.add_argument("--scheduler", help="address of a running scheduler (e.g. a SLURMCluster's); default: a LocalCluster")
    a = ap.parse_args()
    from dask.distributed import Client, LocalCluster

    gammas, a0s = grid_of(a.gamma0), grid_of(a.a0)
    out = pathlib.Path(a.out or tempfile.mkdtemp(prefix="tfs-sweep-"))
    out.mkdir(parents=True, exist_ok=True)
    timings = {}
    rows = None
    counts = [int(n) for n in a.workers.split(",")] if not a.scheduler else [0]
    for n in counts:
        if a.scheduler:
            cluster, client = None, Client(a.scheduler)
        else:
            cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None)
            client = Client(cluster)
        client.run(lambda: __import__("tfs").kresling())  # import tfs on every worker first
        t0 = time.perf_counter()
        rows = sweep(client, gammas, a0s, a.grid)
        timings[n] = time.perf_counter() - t0
        client.close()
        if cluster is not None:
            cluster.close()
        print(f"{n} worker(s): {len(rows)} geometries in {timings[n]:.2f} s")
    write_table(rows, out / "sweep.csv")
    fig = write_figure(rows, gammas, a0s, out / "sweep.png")
    report = {"gamma0": gammas, "a0": a0s, "grid": a.grid, "seconds_by_workers": timings}
    if 1 in timings and 2 in timings:
        report["speedup_1_to_2"] = timings[1] / timings[2]
        print(f"speed-up from 1 to 2 workers: {report['speedup_1_to_2']:.2f}x "
              f"({timings[1]:.2f} s / {timings[2]:.2f} s, {len(rows)} geometries, {a.grid}x{a.grid} basin grid)")
    (out / "sweep.json").write_text(json.dumps(report, indent=1))
    print(f"table: {out / 'sweep.csv'}" + (f", figure: {fig}" if fig else ""))


if __name__ == "__main__":
    main()
