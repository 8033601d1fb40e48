#!/usr/bin/python3
"""Compares two run_trials output folders at given times, e.g. with and without shape targets.

usage: scripts/compare_trials.py DIR_A DIR_B [--at 60,180] [--column se_ma50_fruits]

DIR_A and DIR_B may each list several folders, comma-separated, whose trials are pooled (e.g. two
runs with --seed 1 and --seed 21). Besides the column it prints, per side, the failed moves per
episode from each folder's results.json.

For each time t it takes, per trial, the column's value at the last view captured at or before
t (0 before the first view), and prints both means and standard deviations, the difference,
Welch's t statistic and a two-sided permutation p-value (20 000 random relabellings of the
trials; no SciPy needed). Trials are independent episodes, so the test compares two samples.
"""
import csv
import glob
import json
import math
import os
import random
import sys


def trial_files(folders):
    out = []
    for folder in folders.split(","):
        out += sorted(glob.glob(os.path.join(folder, "trial_*.csv")))
    return out


def failed_moves(folders):
    out = []
    for folder in folders.split(","):
        try:
            with open(os.path.join(folder, "results.json")) as f:
                out += json.load(f).get("failed_moves", [])
        except (OSError, ValueError):
            pass
    return out


def values_at(folders, column, t):
    out = []
    for path in trial_files(folders):
        value = 0.0
        with open(path, newline="") as f:
            for row in csv.DictReader(f):
                if float(row["time_s"]) > t:
                    break
                value = float(row[column])
        out.append(value)
    return out


def mean_std(v):
    m = sum(v) / len(v)
    s = math.sqrt(sum((x - m) ** 2 for x in v) / (len(v) - 1)) if len(v) > 1 else 0.0
    return m, s


def welch_t(a, b):
    (ma, sa), (mb, sb) = mean_std(a), mean_std(b)
    se = math.sqrt(sa * sa / len(a) + sb * sb / len(b))
    return (ma - mb) / se if se > 0 else float("nan")


def permutation_p(a, b, rounds=20000, seed=1):
    rng = random.Random(seed)
    observed = abs(sum(a) / len(a) - sum(b) / len(b))
    pooled = a + b
    extreme = 0
    for _ in range(rounds):
        rng.shuffle(pooled)
        x, y = pooled[: len(a)], pooled[len(a):]
        if abs(sum(x) / len(x) - sum(y) / len(y)) >= observed - 1e-12:
            extreme += 1
    return (extreme + 1) / (rounds + 1)


def main(argv):
    if len(argv) < 3 or argv[1] in ("-h", "--help"):
        print(__doc__.strip(), file=sys.stderr)
        return 2
    a_dir, b_dir = argv[1], argv[2]
    times, column = [60.0, 180.0], "se_ma50_fruits"
    rest = argv[3:]
    while rest:
        if rest[0] == "--at" and len(rest) > 1:
            times = [float(x) for x in rest[1].split(",")]
        elif rest[0] == "--column" and len(rest) > 1:
            column = rest[1]
        else:
            print(__doc__.strip(), file=sys.stderr)
            return 2
        rest = rest[2:]
    print(f"{column}: A = {a_dir}, B = {b_dir}")
    print("   t [s]  A mean +- std (n)      B mean +- std (n)      A - B   Welch t  permutation p")
    for t in times:
        a, b = values_at(a_dir, column, t), values_at(b_dir, column, t)
        if len(a) < 2 or len(b) < 2:
            print(f"compare_trials: need at least 2 trials in each folder, have {len(a)} and {len(b)}", file=sys.stderr)
            return 1
        (ma, sa), (mb, sb) = mean_std(a), mean_std(b)
        print(f"{t:8.0f}  {ma:6.2f} +- {sa:5.2f} ({len(a):2d})    {mb:6.2f} +- {sb:5.2f} ({len(b):2d})   "
              f"{ma - mb:+6.2f}  {welch_t(a, b):7.2f}  {permutation_p(a, b):.4f}")
    fa, fb = failed_moves(a_dir), failed_moves(b_dir)
    if fa and fb:
        (ma, _), (mb, _) = mean_std(fa), mean_std(fb)
        ratio = f"{ma / mb:.2f}x" if mb > 0 else "n/a"
        print(f"failed moves per episode: A {ma:.2f} ({len(fa)}), B {mb:.2f} ({len(fb)}), A / B = {ratio}, "
              f"permutation p {permutation_p(fa, fb):.4f}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
