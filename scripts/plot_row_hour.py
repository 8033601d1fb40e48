#!/usr/bin/python3
"""An hour on the row: per-view work, insertView latency, memory and fruits over time.

usage: scripts/plot_row_hour.py DIR [--out FILE.png]

Reads DIR/trial_0.csv of a run_trials run on a row (e.g. run_trials --scene
procedural-row:1:100 --profile ideal --trolley --duration 3600) and prints a table per ten
minutes: views, insertView median and p95 [ms], the estimator's update (surface, clusters,
fits) median and p95 [ms], resident memory [MiB] and SE fruits at the end of the slice; and
draws the same over time (DIR/row_hour.png) when matplotlib is there.
"""
import csv
import os
import sys


def quantile(v, q):
    v = sorted(v)
    return v[min(len(v) - 1, int(q * len(v)))] if v else float("nan")


def main(argv):
    if len(argv) < 2 or argv[1] in ("-h", "--help"):
        print(__doc__.strip(), file=sys.stderr)
        return 2
    folder = argv[1]
    out = argv[3] if len(argv) >= 4 and argv[2] == "--out" else os.path.join(folder, "row_hour.png")
    path = os.path.join(folder, "trial_0.csv")
    try:
        rows = list(csv.DictReader(open(path)))
    except OSError as e:
        print(f"plot_row_hour: {e}", file=sys.stderr)
        return 1
    if not rows or "insert_ms" not in rows[0]:
        print(f"plot_row_hour: {path} has no views or no insert_ms column (an older run_trials?)", file=sys.stderr)
        return 1
    t = [float(r["time_s"]) for r in rows]
    ins = [float(r["insert_ms"]) for r in rows]
    upd = [float(r["fit_ms"]) for r in rows]
    rss = [float(r["rss_mib"]) for r in rows]
    fruits = [int(float(r["se_all_fruits"])) for r in rows]
    print("| minutes | views | insertView median / p95 [ms] | update median / p95 [ms] | RSS [MiB] | SE fruits |")
    print("|---|---|---|---|---|---|")
    slice_s = 600.0
    k = 0
    while k * slice_s < t[-1]:
        idx = [i for i, x in enumerate(t) if k * slice_s <= x < (k + 1) * slice_s]
        if idx:
            i_last = idx[-1]
            print(f"| {int(k * 10)}-{int(k * 10 + 10)} | {len(idx)} | {quantile([ins[i] for i in idx], 0.5):.1f} / "
                  f"{quantile([ins[i] for i in idx], 0.95):.1f} | {quantile([upd[i] for i in idx], 0.5):.1f} / "
                  f"{quantile([upd[i] for i in idx], 0.95):.1f} | {rss[i_last]:.0f} | {fruits[i_last]} |")
        k += 1
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("plot_row_hour: no matplotlib, table only", file=sys.stderr)
        return 0
    fig, ax = plt.subplots(3, 1, figsize=(9, 9), sharex=True)
    m = [x / 60.0 for x in t]
    ax[0].plot(m, upd, ".", ms=2, label="update (surface, clusters, fits)")
    ax[0].plot(m, ins, ".", ms=2, label="insertView")
    ax[0].set_ylabel("ms per view")
    ax[0].legend()
    ax[1].plot(m, rss)
    ax[1].set_ylabel("resident MiB")
    ax[2].plot(m, fruits)
    ax[2].set_ylabel("SE fruits")
    ax[2].set_xlabel("minutes")
    fig.tight_layout()
    fig.savefig(out, dpi=100)
    print(f"plot_row_hour: wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
