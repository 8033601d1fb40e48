#!/usr/bin/env python3
"""A short seeded run_trials run (ideal profile: no wall time on the clock, so deterministic)
must give the checked-in results.json: the same scene, views and fruit counts, and accuracies and
centre errors within small tolerances (other compilers round differently). Guards refactoring:
moving files or swapping libraries must not change what the instrument measures.
Without shape targets: with them the views follow the fits, and fits that differ in their last
digits from one machine to another (seen between two VMs of the same kind) sent an episode to
other views, which no tolerance on the figures can absorb.
Regenerate after a deliberate change of behaviour:
  run_trials --scene procedural:3 --profile ideal --trials 2 --duration 30 --jobs 2 --no-shape-targets --out DIR
and copy DIR/results.json without wall_s_per_trial into test/data/."""
import json
import subprocess
import sys
import tempfile

exe, expected_path = sys.argv[1], sys.argv[2]
with tempfile.TemporaryDirectory() as out:
    subprocess.run([exe, "--scene", "procedural:3", "--profile", "ideal", "--trials", "2", "--duration", "30",
                    "--jobs", "2", "--no-shape-targets", "--out", out], check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    got = json.load(open(out + "/results.json"))
expected = json.load(open(expected_path))
problems = []


def compare(path, a, b):
    if isinstance(b, dict):
        for k in b:
            if k not in a:
                problems.append(f"{path}/{k}: missing")
            else:
                compare(f"{path}/{k}", a[k], b[k])
    elif isinstance(b, (int, float)) and not isinstance(b, bool) and b is not None:
        leaf = path.rsplit("/", 2)
        tol = 0.0
        if "accuracy" in path:
            tol = 0.01
        elif "center_error" in path:
            tol = 0.05
        elif "rate" in path:
            tol = 1e-4
        if a is None or abs(a - b) > tol + 1e-9 * abs(b):
            problems.append(f"{path}: {a} != {b} (tolerance {tol})")
    elif a != b:
        problems.append(f"{path}: {a!r} != {b!r}")


compare("", got, expected)
if problems:
    print("run_trials results changed:\n  " + "\n  ".join(problems[:30]))
    sys.exit(1)
print("run_trials results unchanged")
