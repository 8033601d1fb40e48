"""fit_stress --camera-views scans the same cases as the default caps, and a camera sees no more
of a fruit than faces it: one view that is not an all-round one sees under half of the surface
(a camera 0.3 m or more away sees at most about 46 % of a 12 cm sphere), and never more than
the cap of the same share would.

usage: fit_stress_camera_views.py FIT_STRESS"""
import json
import os
import subprocess
import sys
import tempfile


def run(tool, out, *extra):
    subprocess.run([tool, '--fruits', '40', '--seed', '3', '--json', out, *extra], check=True,
                   stdout=subprocess.DEVNULL)
    with open(out) as f:
        return json.load(f)


def main():
    tool = sys.argv[1]
    with tempfile.TemporaryDirectory() as tmp:
        caps = run(tool, os.path.join(tmp, 'caps.json'))
        cams = run(tool, os.path.join(tmp, 'cams.json'), '--camera-views')
    failures = []
    if caps.get('views') != 'cap' or cams.get('views') != 'camera':
        failures.append('the JSON does not say which views: %r / %r' % (caps.get('views'), cams.get('views')))
    single = 0
    for a, b in zip(caps['fruits'], cams['fruits']):
        same = all(a[k] == b[k] for k in ('kind', 'diameter_m', 'views', 'noise_m', 'blur_m', 'outliers', 'neighbour'))
        if not same:
            failures.append('case %d differs between the modes' % a['index'])
        if a['views'] == 1 and a['coverage'] < 0.85:
            single += 1
            if not b['coverage'] < 0.5:
                failures.append('case %d: one camera saw %.3f of the surface' % (a['index'], b['coverage']))
            if b['coverage'] > a['coverage'] + 0.01:
                failures.append('case %d: the camera saw %.3f, the cap of that share %.3f' %
                                (a['index'], b['coverage'], a['coverage']))
    if single < 5:
        failures.append('only %d single partial views drawn; the check needs more' % single)
    if len(caps['fruits']) != 40 or len(cams['fruits']) != 40:
        failures.append('expected 40 fruits per run')
    for f in failures:
        print('FAIL:', f)
    print('%d single partial views checked' % single)
    return 1 if failures else 0


if __name__ == '__main__':
    sys.exit(main())
