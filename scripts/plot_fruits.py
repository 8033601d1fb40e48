#!/usr/bin/python3
"""Draws a fruit report (export_fruits, map_tool --export-fruits) as one PNG: a top view of the
fruits coloured by volume, and a histogram of their volumes.

usage: scripts/plot_fruits.py FRUITS.csv|FRUITS.json [--out FRUITS.png]

Needs Debian's python3-matplotlib (scripts/setup.sh installs it); run it with /usr/bin/python3.
"""
import csv
import json
import math
import os
import sys


def read_fruits(path):
    if path.endswith(".json"):
        with open(path) as f:
            rows = json.load(f)["fruits"]
    else:
        with open(path, newline="") as f:
            rows = list(csv.DictReader(f))
    fruits = []
    for r in rows:
        try:
            x, y, v = float(r["x"]), float(r["y"]), float(r["volume_m3"])
        except (KeyError, TypeError, ValueError) as e:
            raise SystemExit(f"plot_fruits: {path}: a row without x, y and volume_m3 ({e})")
        if all(math.isfinite(t) for t in (x, y, v)):
            fruits.append((int(float(r["id"])), x, y, v * 1e6))  # volume in cm^3
    return fruits


def main(argv):
    if len(argv) < 2 or argv[1] in ("-h", "--help"):
        print(__doc__.strip(), file=sys.stderr)
        return 2
    path = argv[1]
    out = os.path.splitext(path)[0] + ".png"
    if len(argv) == 4 and argv[2] == "--out":
        out = argv[3]
    elif len(argv) != 2:
        print(__doc__.strip(), file=sys.stderr)
        return 2
    fruits = read_fruits(path)
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (top, hist) = plt.subplots(1, 2, figsize=(11, 4.5), gridspec_kw={"width_ratios": [1.2, 1]})
    if fruits:
        xs, ys, vs = [f[1] for f in fruits], [f[2] for f in fruits], [f[3] for f in fruits]
        sc = top.scatter(xs, ys, c=vs, s=[20 + 2 * v for v in vs], cmap="viridis", edgecolors="k", linewidths=0.5)
        fig.colorbar(sc, ax=top, label="volume [cm$^3$]")
        for fid, x, y, _ in fruits:
            top.annotate(str(fid), (x, y), textcoords="offset points", xytext=(4, 4), fontsize=7)
        hist.hist(vs, bins=max(5, min(30, len(vs) // 2)), color="tab:red", edgecolor="k")
        total = sum(vs)
        hist.set_title(f"{len(vs)} fruits, {total:.0f} cm$^3$ in all, median {sorted(vs)[len(vs) // 2]:.0f} cm$^3$")
    else:
        top.text(0.5, 0.5, "no fruits", ha="center", va="center", transform=top.transAxes)
    top.set_xlabel("x [m]")
    top.set_ylabel("y [m]")
    top.set_aspect("equal", adjustable="datalim")
    top.set_title("top view (map frame)")
    hist.set_xlabel("volume [cm$^3$]")
    hist.set_ylabel("fruits")
    fig.tight_layout()
    fig.savefig(out, dpi=120)
    print(f"plot_fruits: {len(fruits)} fruits from {path} drawn to {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
