"""The final fits of run_trials episodes matched to true fruits, for the calibration scripts
(calibrate_volume_interval.py, calibrate_center_radius.py): per trial, one fit per true fruit,
the nearest within 5 cm."""
import csv
import glob
import os

MATCH_CM = 5.0


def matched_fits(dirs):
    """Yields (final_fruits CSV row, true fruit's truth.csv row, distance in cm) for every
    run_trials output folder in `dirs`."""
    for d in dirs:
        truth = {int(r['truth']): r for r in csv.DictReader(open(os.path.join(d, 'truth.csv')))}
        for name in sorted(glob.glob(os.path.join(d, 'final_fruits_*.csv'))):
            best = {}
            for r in csv.DictReader(open(name)):
                t, dist = int(r['nearest_truth']), float(r['distance_cm'])
                if t >= 0 and dist <= MATCH_CM and (t not in best or dist < best[t][0]):
                    best[t] = (dist, r)
            for t, (dist, r) in best.items():
                yield r, truth[t], dist
