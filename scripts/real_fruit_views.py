#!/usr/bin/python3
"""Fits single camera views of the real capsicum fruits, one fruit at a time, through fit_cloud.

usage: scripts/real_fruit_views.py [--set 0|1] [--bin-dir DIR] [--shared DIR] [--json OUT]
                                   [--keep DIR] [-- FIT_CLOUD_OPTIONS...]

The stress suite's peppers are drawn; these are the seven fruit meshes of ../shared/data's plant
(VG07_6_fruitonly.dae, the ground truth of both paper scenarios). Each fruit is put alone in a
scene (the plant written as OBJ by scene_truth --write-scene, split here into its connected parts,
vertices welded by position) and rendered with the
paper profile (render_view: its depth noise and blur) from cameras 0.3-0.5 m away around it, at
elevations from below to above; with nothing else in the scene every depth pixel is the fruit, so
the cloud is the fruit as the camera saw it, without the red test's dark pixels. Each cloud goes
to fit_cloud --json as a user would give it; the accepted fit nearest the true centre (within
3 cm) is scored against the mesh's enclosed volume. Set 0: elevations -40, -15, 15, 40 deg, six
azimuths (168 views); set 1: -50, -25, 0, 25, 50 deg, six other azimuths (210 views).
Prints mean / 5th / 10th percentile / worst volume accuracy (a view without a fit counts 0),
the share of true volumes inside the 90 % interval, its median half-width, the mean and spread
of log(true / fitted volume), the median centre error. Needs the built tools (scripts/build.sh). With --keep, renders already
in the folder are reused: give a fresh folder after changing the meshes or the renderer.
"""
import argparse
import json
import math
import os
import shutil
import statistics
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

SCENE = """name: fruit_meshes
frame: world
plants:
  - {{mesh: {mesh}, fruit_truth: {mesh}, position: [0, 0, 0], yaw: 0.0}}
materials:
  VG07frt0: {{rgb: [162, 154, 35], fruit: true}}
  VG07frt1: {{rgb: [176, 22, 14], fruit: true}}
  VG07frt2: {{rgb: [150, 18, 12], fruit: true}}
workspace:
  box_min: [-1, -1, 0]
  box_max: [1, 1, 2]
camera_start: {{position: [0.5, 0, 0.5], look_at: [0, 0, 0.5]}}
"""


def run(cmd):
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit("%s failed: %s" % (os.path.basename(cmd[0]), r.stderr.strip()[-400:]))
    return r.stdout


def split_obj(path, out_dir):
    """Writes one OBJ per connected part (vertices welded by position) and returns their paths."""
    vertices, faces, material = [], [], None
    mtllib = None
    with open(path) as f:
        for line in f:
            if line.startswith("v "):
                vertices.append(tuple(float(x) for x in line.split()[1:4]))
            elif line.startswith("usemtl"):
                material = line.split()[1]
            elif line.startswith("mtllib"):
                mtllib = line.split()[1]
            elif line.startswith("f "):
                faces.append(([int(t.split("/")[0]) - 1 for t in line.split()[1:]], material))
    first = {}
    weld = [first.setdefault(tuple(round(x, 6) for x in v), i) for i, v in enumerate(vertices)]
    parent = list(range(len(vertices)))

    def root(a):
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    for face, _ in faces:
        r = root(weld[face[0]])
        for j in face[1:]:
            parent[root(weld[j])] = r
    parts = {}
    for face, m in faces:
        parts.setdefault(root(weld[face[0]]), []).append((face, m))
    paths = []
    for n, part in enumerate(sorted(parts.values(), key=lambda p: min(min(f) for f, _ in p))):
        used = sorted({j for face, _ in part for j in face})
        index = {j: k + 1 for k, j in enumerate(used)}
        out = os.path.join(out_dir, "fruit_%d.obj" % n)
        with open(out, "w") as o:
            if mtllib:
                o.write("mtllib %s\n" % mtllib)
            for j in used:
                o.write("v %.7f %.7f %.7f\n" % vertices[j])
            current = None
            for face, m in part:
                if m != current:
                    o.write("usemtl %s\n" % m)
                    current = m
                o.write("f " + " ".join(str(index[j]) for j in face) + "\n")
        paths.append(out)
    return paths


def percentile(sorted_values, q):
    return sorted_values[int(math.floor(q * (len(sorted_values) - 1)))]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--set", type=int, default=0, choices=[0, 1])
    ap.add_argument("--bin-dir", default=os.path.join(ROOT, "build/devel/lib/fruit_shape_completion"))
    ap.add_argument("--shared", default=os.environ.get("FSC_SHARED_DATA", os.path.join(ROOT, "../shared/data")))
    ap.add_argument("--json", help="write every view's row and the summary here")
    ap.add_argument("--keep", help="render into this folder (kept) instead of a temporary one")
    ap.add_argument("fit_options", nargs="*", help="passed to fit_cloud (after --)")
    args = ap.parse_args()
    mesh = os.path.join(os.path.abspath(args.shared), "plants/VG07_6_fruitonly.dae")
    if not os.path.exists(mesh):
        sys.exit("real_fruit_views: %s not found (give --shared or FSC_SHARED_DATA)" % mesh)
    tool = lambda name: os.path.join(args.bin_dir, name)
    for name in ("scene_truth", "render_view", "fit_cloud"):
        if not os.path.exists(tool(name)):
            sys.exit("real_fruit_views: %s not built (scripts/build.sh)" % tool(name))

    work = args.keep or tempfile.mkdtemp(prefix="real_fruit_views_")
    os.makedirs(work, exist_ok=True)
    with open(os.path.join(work, "plant.yaml"), "w") as f:
        f.write(SCENE.format(mesh=mesh))
    run([tool("scene_truth"), "--scene", os.path.join(work, "plant.yaml"), "--write-scene", os.path.join(work, "plant")])
    fruit_objs = split_obj(os.path.join(work, "plant/plant_0.obj"), work)
    if len(fruit_objs) != 7:
        sys.exit("real_fruit_views: the plant split into %d parts, expected its 7 fruits" % len(fruit_objs))
    mtl = os.path.join(work, "plant/scene.mtl")
    if os.path.exists(mtl):
        shutil.copy(mtl, work)

    elevations = (-40, -15, 15, 40) if args.set == 0 else (-50, -25, 0, 25, 50)
    rows, seed = [], 1000 + 1000 * args.set
    for i, obj in enumerate(fruit_objs):
        scene = os.path.join(work, "fruit_%d.yaml" % i)
        with open(scene, "w") as f:
            f.write(SCENE.format(mesh=os.path.basename(obj)).replace(
                "fruit_truth: %s, " % os.path.basename(obj), ""))
        truth = json.loads(run([tool("scene_truth"), "--scene", scene, "--json"]))["fruits"]
        if len(truth) != 1:
            sys.exit("real_fruit_views: %s holds %d fruits, expected one" % (obj, len(truth)))
        c, volume = truth[0]["center"], truth[0]["volume_m3"]
        for el in elevations:
            for k in range(6):
                az = 2 * math.pi * k / 6 + 0.37 * i + 0.2 * el + 0.5 * args.set
                e = math.radians(el)
                d = 0.3 + 0.2 * ((k * 7 + i * 3 + el) % 5) / 4
                cam = [c[0] + d * math.cos(e) * math.cos(az), c[1] + d * math.cos(e) * math.sin(az),
                       c[2] + d * math.sin(e)]
                seed += 1
                out = os.path.join(work, "view_%d_%d_%d" % (i, el, k))
                if not os.path.exists(os.path.join(out, "full_cloud.ply")):
                    run([tool("render_view"), "--scene", scene, "--camera", ",".join("%.4f" % v for v in cam + c),
                         "--out", out, "--seed", str(seed)])
                fits = json.loads(run([tool("fit_cloud"), "--input", os.path.join(out, "full_cloud.ply"), "--json"]
                                      + args.fit_options))["fruits"]
                best = None
                for fit in fits:
                    dist = math.dist(fit["center"], c)
                    if fit["accepted"] and dist < 0.03 and (best is None or dist < best[0]):
                        best = (dist, fit)
                row = {"fruit": i, "elevation_deg": el, "azimuth_index": k, "distance_m": d, "found": best is not None,
                       "volume_accuracy": 0.0}
                if best is not None:
                    dist, fit = best
                    lo, hi = fit["volume_ci90_m3"]
                    row.update({"volume_accuracy": 1.0 - abs(fit["volume_m3"] - volume) / volume,
                                "true_over_fitted_volume": volume / fit["volume_m3"],
                                "center_error_mm": 1000.0 * dist, "inside_ci90": lo <= volume <= hi,
                                "ci90_relative_half_width": (hi - lo) / 2.0 / fit["volume_m3"],
                                "seen_share": fit["seen_share"], "points": fit["n_points"]})
                rows.append(row)

    acc = sorted(r["volume_accuracy"] for r in rows)
    found = [r for r in rows if r["found"]]
    logs = [math.log(r["true_over_fitted_volume"]) for r in found]
    summary = {
        "views": len(rows), "found": len(found), "mean": sum(acc) / len(acc), "p5": percentile(acc, 0.05),
        "p10": percentile(acc, 0.10), "worst": acc[0],
        "inside_ci90": sum(r.get("inside_ci90", False) for r in rows) / len(rows),
        "median_ci90_half_width": statistics.median(r["ci90_relative_half_width"] for r in found) if found else None,
        "mean_log_true_over_fitted": statistics.mean(logs) if logs else None,
        "sd_log_true_over_fitted": statistics.pstdev(logs) if logs else None,
        "median_center_error_mm": statistics.median(r["center_error_mm"] for r in found) if found else None,
    }
    print("set %d: %d views, %d fitted; volume accuracy mean %.3f, 5th percentile %.3f, 10th %.3f, worst %.3f; "
          "inside the 90 %% interval %.1f %% (median half-width %.1f %%); log(true / fitted) mean %+.3f, sd %.3f; "
          "median centre error %.1f mm" % (args.set, summary["views"], summary["found"], summary["mean"], summary["p5"],
                                          summary["p10"], summary["worst"], 100 * summary["inside_ci90"],
                                          100 * (summary["median_ci90_half_width"] or 0),
                                          summary["mean_log_true_over_fitted"] or 0,
                                          summary["sd_log_true_over_fitted"] or 0,
                                          summary["median_center_error_mm"] or 0))
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"set": args.set, "summary": summary, "views": rows}, f, indent=1)
    if not args.keep:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
