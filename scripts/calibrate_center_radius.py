#!/usr/bin/python3
"""Makes and checks the table of center_uncertainty.cpp: the 90th percentile of the distance
from a fitted to the true fruit centre, per RMS class and seen-share knot.

  scripts/calibrate_center_radius.py --suite stress_seed1.json --episodes DIR[,DIR...] \
      [--check-suite stress_seed2.json] [--check-episodes DIR[,DIR...]]

--suite: `fit_stress --json` output; --episodes: run_trials output folders (their
final_fruits_*.csv; one fit per true fruit, the nearest within 5 cm). Prints the table (mm) and,
for the --check sets, the share of true centres within the radius and the median radius.
Needs numpy (Debian: python3-numpy).
"""
import argparse
import json

import numpy as np

from episode_fits import matched_fits

KNOTS = [0.45, 0.55, 0.65, 0.75, 0.84, 0.92, 0.97, 1.0]
CLASS_RMS_MM = [3.5, 5.5]
AT_BOUND_MM = 20.5  # a shortest axis within 2.5 % of min_axis (20 mm), as the pipeline decides


def suite_rows(path):
    """(seen share, rms mm, min axis mm, centre error mm, true coverage) of the found fruits."""
    rows = []
    for f in json.load(open(path))['fruits']:
        if f['found']:
            rows.append((f['fit_coverage'], 1e3 * f['rms_m'], 1e3 * f['fit_min_axis_m'], f['center_error_mm'],
                         f['coverage']))
    return np.array(rows)


def episode_rows(dirs):
    return np.array([(float(r['seen_share']), float(r['rms_mm']), float(r['min_axis_mm']), 10 * dist, 1.0)
                     for r, _, dist in matched_fits(dirs)])


def rms_class(rms_mm):
    # An RMS on a class bound belongs to the class below, as in center_uncertainty.cpp.
    return np.digitize(rms_mm, CLASS_RMS_MM, right=True)


def make_table(pool, min_fits=20):
    edges = [0.0] + [(KNOTS[i] + KNOTS[i + 1]) / 2 for i in range(len(KNOTS) - 1)] + [1.01]
    table = np.full((3, len(KNOTS)), np.nan)
    for c in range(3):
        for k in range(len(KNOTS)):
            m = (rms_class(pool[:, 1]) == c) & (pool[:, 0] >= edges[k]) & (pool[:, 0] < edges[k + 1]) & \
                (pool[:, 2] > AT_BOUND_MM)
            if m.sum() >= min_fits:
                table[c, k] = np.percentile(pool[m, 3], 90)
    for c in range(3):  # a thin bin takes the class below's value; in the first class, the next better-seen knot's
        for k in range(len(KNOTS) - 1, -1, -1):
            if np.isnan(table[c, k]):
                if c > 0:
                    table[c, k] = table[c - 1, k]
                elif k + 1 < len(KNOTS):
                    table[c, k] = table[c, k + 1]
    if np.isnan(table).any():
        raise SystemExit('calibrate_center_radius: too few fits for the best-seen, lowest-residual bin')
    for c in range(3):  # less seen: never smaller
        for k in range(len(KNOTS) - 2, -1, -1):
            table[c, k] = max(table[c, k], table[c, k + 1])
    for c in range(1, 3):  # a larger residual: never smaller
        table[c] = np.maximum(table[c], table[c - 1])
    at_bound = pool[pool[:, 2] <= AT_BOUND_MM]
    if len(at_bound) < min_fits:
        raise SystemExit('calibrate_center_radius: fewer than %d fits at the axis bound' % min_fits)
    return np.ceil(table * 2) / 2, np.ceil(np.percentile(at_bound[:, 3], 90) * 2) / 2


def radius(table, at_bound_mm, row):
    r = np.interp(row[0], KNOTS, table[rms_class(row[1])])
    return max(r, at_bound_mm) if row[2] <= AT_BOUND_MM else r


def check(name, rows, table, at_bound_mm):
    r = np.array([radius(table, at_bound_mm, row) for row in rows])
    inside = rows[:, 3] <= r
    print(f'{name:34s} {len(rows):5d} fits  inside {100 * inside.mean():5.1f} %  median radius {np.median(r):4.1f} mm')


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--suite', required=True)
    ap.add_argument('--episodes', required=True, help='comma-separated run_trials folders')
    ap.add_argument('--check-suite')
    ap.add_argument('--check-episodes', action='append', default=[], help='comma-separated folders (repeatable)')
    a = ap.parse_args()
    parts = [suite_rows(a.suite), episode_rows(a.episodes.split(','))]
    if any(len(p) == 0 for p in parts):
        raise SystemExit('calibrate_center_radius: no fits in ' + (a.suite if len(parts[0]) == 0 else a.episodes))
    pool = np.vstack(parts)
    table, at_bound_mm = make_table(pool)
    print('seen share knots:', KNOTS)
    for c, row in enumerate(table):
        print(f'RMS class {c}:', ', '.join(f'{v:.1f}' for v in row))
    print(f'at bound: {at_bound_mm:.1f} mm')
    if a.check_suite:
        s = suite_rows(a.check_suite)
        check(a.check_suite, s, table, at_bound_mm)
        for lo, hi, label in [(0, .35, 'quarter'), (.35, .6, 'half'), (.6, .85, 'three quarters'), (.85, 1.1, 'full')]:
            m = (s[:, 4] >= lo) & (s[:, 4] < hi)
            check(f'  ... {label}', s[m], table, at_bound_mm)
    for dirs in a.check_episodes:
        check(dirs.split(',')[0] + ' ...', episode_rows(dirs.split(',')), table, at_bound_mm)


if __name__ == '__main__':
    main()
