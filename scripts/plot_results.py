#!/usr/bin/python3
"""Plots detected fruits over time from a run_trials output folder, like the paper's figures.

usage: scripts/plot_results.py DIR [--out FILE.png]

Reads DIR/trial_*.csv (one row per view) and draws, for Old and SE and the subsets all, MA0
and MA50, the number of detected fruits over simulated time: the mean over trials as a line and
the spread (min to max) as a band. A dashed line adds Old scored box against the fruit's voxel
box, as the upstream evaluator does. Writes DIR/fruits_over_time.png unless --out says otherwise.
Needs numpy and matplotlib (Debian: python3-numpy python3-matplotlib).
"""
import csv
import glob
import os
import sys


def main(argv):
    if len(argv) < 2 or argv[1] in ("-h", "--help"):
        print(__doc__.strip(), file=sys.stderr)
        return 2
    folder = argv[1]
    out = os.path.join(folder, "fruits_over_time.png")
    if len(argv) >= 4 and argv[2] == "--out":
        out = argv[3]
    files = sorted(glob.glob(os.path.join(folder, "trial_*.csv")))
    if not files:
        print(f"plot_results: no trial_*.csv in {folder}", file=sys.stderr)
        return 1
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        import numpy as np
    except ImportError as e:
        print(f"plot_results: {e} (install python3-numpy python3-matplotlib)", file=sys.stderr)
        return 1

    trials = []
    for f in files:
        with open(f, newline="") as fh:
            rows = list(csv.DictReader(fh))
        if rows:
            trials.append(rows)
    if not trials:
        print("plot_results: the trial files hold no views", file=sys.stderr)
        return 1
    duration = max(float(r[-1]["time_s"]) for r in trials)
    grid = np.linspace(0.0, duration, 200)

    def series(rows, column):
        # Step function: the value of the last view at or before each grid time (0 before the first).
        times = np.array([float(r["time_s"]) for r in rows])
        values = np.array([float(r[column]) for r in rows])
        idx = np.searchsorted(times, grid, side="right") - 1
        return np.where(idx >= 0, values[np.clip(idx, 0, None)], 0.0)

    fig, axes = plt.subplots(1, 3, figsize=(15, 4.2), sharey=True)
    for ax, subset in zip(axes, ("all", "ma0", "ma50")):
        for est, color, label in (("old", "tab:blue", "OLD"), ("se", "tab:red", "SE"),
                                  ("old_box", "tab:cyan", "OLD vs voxel box")):
            column = f"{est}_{subset}_fruits"
            if column not in trials[0][0]:
                continue  # folders written before the box ground truth existed
            data = np.array([series(rows, column) for rows in trials])
            ax.plot(grid, data.mean(axis=0), color=color, label=f"{label} (mean of {len(trials)})",
                    linestyle="--" if est == "old_box" else "-")
            ax.fill_between(grid, data.min(axis=0), data.max(axis=0), color=color, alpha=0.2)
        ax.set_title({"all": "all matched", "ma0": "MA0 (accuracy > 0)", "ma50": "MA50 (accuracy > 0.5)"}[subset])
        ax.set_xlabel("time [s]")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("detected fruits")
    axes[0].legend(loc="upper left")
    fig.suptitle(os.path.basename(os.path.normpath(folder)))
    fig.tight_layout()
    fig.savefig(out, dpi=100)
    print(out)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
