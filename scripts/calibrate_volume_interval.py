#!/usr/bin/python3
"""Makes and checks the model of volume_interval.cpp: the 5th and 95th percentiles of
log(true / fitted volume) as linear functions of the log of the fit's log-volume
spread (the spread its residuals and Jacobian imply), its seen share, its RMS residual beyond
3.5 and 5.5 mm and how few views saw it (log(MANY_VIEWS / views) when fewer; the suite's clouds
have no count), fitted by weighted linear quantile regression, with the floor for fits sized by
the axis bound.

  scripts/calibrate_volume_interval.py --suite stress_seed1.json --episodes DIR[,DIR...] \
      [--episodes DIR[,DIR...]] [--check-suite stress_seed2.json] [--check-episodes DIR[,DIR...]]

--suite: `fit_stress --json` output; --episodes (repeatable, one group each): run_trials output
folders (their final_fruits_*.csv, with the views column, and truth.csv; one fit per true fruit,
the nearest within 5 cm). Episodes run for 60 or 120 s give the fits a user reads before a run
ends. The suite and each group of episodes weigh alike. Prints the coefficients and, for the
--check sets, the share of true volumes inside the interval and the median half-width for fruits
seen half or more (the suite: by the share of the surface its views saw; episodes: by the fit's
seen share). Needs numpy and scipy (Debian: python3-numpy, python3-scipy).
"""
import argparse
import json

import numpy as np
from scipy import sparse
from scipy.optimize import linprog

from episode_fits import matched_fits

AT_BOUND_MM = 20.5  # a shortest axis within 2.5 % of min_axis (20 mm), as the pipeline decides
# The spread and the residual are clamped into these ranges before the model reads them (C++
# the same): outside them the pool has too few fits to say more.
SPREAD = (0.01, 0.5)
RMS_MM = (1.0, 8.0)
RMS_KNEES_MM = (3.5, 5.5)  # the residual widens the interval beyond each of these
MANY_VIEWS = 6.0  # fits seen in fewer views get a wider interval (0 views: not counted)
# The quantiles fitted: the 5th and 95th percentiles.
QUANTILES = (0.05, 0.95)


def suite_rows(path):
    """(seen share, rms mm, min axis mm, spread, true / fitted volume, true coverage, views) of the
    found fruits; the suite's clouds have no view count (0)."""
    rows = []
    def number(v):  # JSON writes a non-finite value as null
        return float('nan') if v is None else float(v)
    for f in json.load(open(path))['fruits']:
        if f['found']:
            rows.append((number(f['fit_coverage']), 1e3 * number(f['rms_m']), 1e3 * number(f['fit_min_axis_m']),
                         number(f['log_volume_spread']), number(f['true_over_fitted_volume']), number(f['coverage']), 0))
    return np.array(rows)


def episode_rows(dirs):
    rows = []
    for r, truth, _ in matched_fits(dirs):
        if 'views' not in r:
            raise SystemExit('calibrate_volume_interval: final_fruits CSVs without a views column in ' + ','.join(dirs))
        seen = float(r['seen_share'])
        rows.append((seen, float(r['rms_mm']), float(r['min_axis_mm']), float(r['log_volume_spread']),
                     float(truth['volume_cm3']) / float(r['volume_cm3']), seen, max(1, int(r['views']))))
    return np.array(rows)


def features(rows):
    spread = np.where(np.isfinite(rows[:, 3]), rows[:, 3], SPREAD[1])
    rms = np.clip(np.where(np.isfinite(rows[:, 1]), rows[:, 1], RMS_MM[1]), *RMS_MM)
    seen = np.clip(np.where(np.isfinite(rows[:, 0]), rows[:, 0], 0.0), 0, 1)  # as the C++: nonsense reads as unseen
    views = rows[:, 6]
    few_views = np.where(views > 0, np.maximum(0.0, np.log(MANY_VIEWS / np.maximum(views, 1))), 0.0)
    return np.column_stack([np.ones(len(rows)), np.log(np.clip(spread, *SPREAD)), seen,
                            np.maximum(rms - RMS_KNEES_MM[0], 0), np.maximum(rms - RMS_KNEES_MM[1], 0), few_views])


def quantile_regression(X, y, w, q, signs):
    """argmin_b sum_i w_i rho_q(y_i - X_i b), as a linear programme; signs[k] > 0 keeps b_k >= 0,
    < 0 keeps it <= 0, 0 leaves it free."""
    n, p = X.shape
    cost = np.concatenate([np.zeros(p), q * w, (1 - q) * w])
    A = sparse.hstack([sparse.csr_matrix(X), sparse.identity(n), -sparse.identity(n)], format='csr')
    bounds = [(0, None) if s > 0 else (None, 0) if s < 0 else (None, None) for s in signs] + [(0, None)] * (2 * n)
    r = linprog(cost, A_eq=A, b_eq=y, bounds=bounds, method='highs')
    if not r.success:
        raise SystemExit('calibrate_volume_interval: ' + r.message)
    return r.x[:p]


def make_model(parts):
    for p in parts:
        if (p[:, 2] > AT_BOUND_MM).sum() < 20:
            raise SystemExit('calibrate_volume_interval: a group has fewer than 20 fits off the axis bound')
    rows = np.vstack([p[p[:, 2] > AT_BOUND_MM] for p in parts])
    w = np.concatenate([np.full((p[:, 2] > AT_BOUND_MM).sum(), 1.0 / (p[:, 2] > AT_BOUND_MM).sum()) for p in parts])
    X, y = features(rows), np.log(rows[:, 4])
    # Monotone by construction: a larger spread or residual, or fewer views, never narrow the
    # interval, more of the fruit seen never widens it.
    lo = quantile_regression(X, y, w, QUANTILES[0], [0, -1, 1, -1, -1, -1])
    hi = quantile_regression(X, y, w, QUANTILES[1], [0, 1, -1, 1, 1, 1])
    at_bound = np.vstack([p[p[:, 2] <= AT_BOUND_MM] for p in parts])
    if len(at_bound) < 20:
        raise SystemExit('calibrate_volume_interval: fewer than 20 fits at the axis bound')
    # Rounded as volume_interval.cpp carries them (the bound's ends outward), so that the checks
    # below are the C++ model's.
    return (np.round(lo, 4), np.round(hi, 4), np.floor(100 * np.percentile(at_bound[:, 4], 5)) / 100,
            np.ceil(10 * np.percentile(at_bound[:, 4], 95)) / 10, len(at_bound))


def interval(model, rows):
    lo_b, hi_b, bound_lo, bound_hi, _ = model
    X = features(rows)
    lo, hi = np.exp(X @ lo_b), np.exp(X @ hi_b)
    at = rows[:, 2] <= AT_BOUND_MM
    lo[at] = np.minimum(lo[at], bound_lo)
    hi[at] = np.maximum(hi[at], bound_hi)
    return lo, hi


def check(name, rows, model):
    lo, hi = interval(model, rows)
    inside = (rows[:, 4] >= lo) & (rows[:, 4] <= hi)
    half = rows[:, 5] >= 0.5
    hw = 0.5 * (hi - lo)
    print(f'{name:40s} {len(rows):5d} fits  inside {100 * inside.mean():5.1f} %  median half-width, seen half '
          f'or more {100 * np.median(hw[half]) if half.any() else float("nan"):5.1f} %')


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--suite', required=True)
    ap.add_argument('--episodes', required=True, action='append', help='comma-separated run_trials folders (repeatable)')
    ap.add_argument('--check-suite')
    ap.add_argument('--check-episodes', action='append', default=[], help='comma-separated folders (repeatable)')
    a = ap.parse_args()
    parts = [suite_rows(a.suite)] + [episode_rows(group.split(',')) for group in a.episodes]
    for part, name in zip(parts, [a.suite] + a.episodes):
        if len(part) == 0:
            raise SystemExit('calibrate_volume_interval: no fits in ' + name)
    model = make_model(parts)
    print(f'features: 1, log(spread), seen share, RMS beyond 3.5 mm, RMS beyond 5.5 mm, log({MANY_VIEWS:g} / views) when fewer')
    print('lower end of log(true / fitted):', ', '.join(f'{v:.4f}' for v in model[0]))
    print('upper end:                      ', ', '.join(f'{v:.4f}' for v in model[1]))
    print(f'at the axis bound ({model[4]} fits): {model[2]:.2f} - {model[3]:.1f}')
    check('pool: suite', parts[0], model)
    for part, name in zip(parts[1:], a.episodes):
        check('pool: ' + name.split(',')[0] + ' ...', part, model)
    if a.check_suite:
        s = suite_rows(a.check_suite)
        check(a.check_suite, s, model)
        for lo, hi, label in [(0, .35, 'quarter'), (.35, .6, 'half'), (.6, .85, 'three quarters'), (.85, 1.1, 'full')]:
            m = (s[:, 5] >= lo) & (s[:, 5] < hi)
            check(f'  ... {label}', s[m], model)
    for dirs in a.check_episodes:
        check(dirs.split(',')[0] + ' ...', episode_rows(dirs.split(',')), model)


if __name__ == '__main__':
    main()
