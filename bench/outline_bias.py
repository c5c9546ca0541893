#!/usr/bin/env python3
"""Controlled experiment for the silhouette fit's orientation error on blurred images (issue 32,
item 5).

Takes one run of `scenarios/biplanar_realistic.toml` (the same seed and draws as
`biplanar_realistic_blurred.toml`, so run ids compare) and simulates it alone (`--shard K/N`)
with the blurred scenario's unsharpness options one at a time, with all of them (the blurred
scenario itself), with all of them and the box's plates not imaged (bench/bias.py's "bare"),
and with none (the sharp scenario). Every variant runs at an exposure so high
that quantum noise is negligible (`--exposure`, default ×50 of 10 mAs); the sharp and the
blurred variant also run at the run's own exposure level, to show whether noise matters. Each is
reconstructed with `rsasim reconstruct OUT --model-method silhouette`, and the femur's pose is
compared with the truth:

  - the rotation error as a rotation vector in the scanner frame, degrees (x, y, z; in these
    scenarios beamline 1 looks along z and beamline 2 along x, so y is the axis perpendicular to
    both beams), and its length (the orientation error);
  - the position error (mm) and the fit's mean contour distance (px).

Usage: bench/outline_bias.py [--run n2-r03] [--exposure 50] [--bin PATH]
Prints a Markdown table stamped with commit, machine and date.
"""

import argparse
import json
import math
import pathlib
import sys
import tempfile

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import stamp  # noqa: E402
from bias import BARE, LABELS, LEVELS, RUNS_PER_LEVEL, VARIANTS, run, scenario_text  # noqa: E402


def rotation_vector_deg(r):
    """The rotation vector (axis times angle, degrees) of the 3×3 rotation matrix r."""
    c = max(-1.0, min(1.0, (r[0][0] + r[1][1] + r[2][2] - 1.0) / 2.0))
    angle = math.acos(c)
    if angle < 1e-12:
        return [0.0, 0.0, 0.0]
    s = 2.0 * math.sin(angle)
    axis = [(r[2][1] - r[1][2]) / s, (r[0][2] - r[2][0]) / s, (r[1][0] - r[0][1]) / s]
    return [math.degrees(angle) * a for a in axis]


def femur_error(run_dir):
    truth = json.loads((run_dir / "truth.json").read_text())
    measured = json.loads((run_dir / "measured-rsasim-dlt-silhouette.json").read_text())
    t = next(p for p in truth["phantoms"] if p["id"] == "femur")
    m = next(p for p in measured["phantoms"] if p["id"] == "femur")
    rt, rm = t["rotation"], m["rotation"]
    # rm · rtᵀ: the rotation that takes the true orientation to the measured one.
    e = [[sum(rm[i][k] * rt[j][k] for k in range(3)) for j in range(3)] for i in range(3)]
    quality = m.get("quality") or {}
    return (rotation_vector_deg(e), math.dist(m["position_mm"], t["position_mm"]),
            quality.get("contour_distance_px", float("nan")))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--run", default="n2-r03", help="run id nL-rR of the realistic protocol")
    ap.add_argument("--exposure", type=float, default=50.0, help="the noise-free exposure factor")
    ap.add_argument("--bin", default=None, help="rsasim binary (default: the release build, built)")
    args = ap.parse_args()
    try:
        level, index = (int(x[1:]) for x in args.run.split("-"))
        assert args.run == f"n{level}-r{index:02d}" and level < len(LEVELS) and index < RUNS_PER_LEVEL
    except (ValueError, AssertionError):
        sys.exit(f"--run {args.run}: expected nL-rRR with L < {len(LEVELS)}, RR < {RUNS_PER_LEVEL}")
    shard = f"{level * RUNS_PER_LEVEL + index}/{len(LEVELS) * RUNS_PER_LEVEL}"
    binary = args.bin or str(stamp.release_binary())
    own = LEVELS[level]
    command = f"bench/outline_bias.py --run {args.run} --exposure {args.exposure:g}"
    print(stamp.line(command, binary) + "\n")
    print(f"Run {args.run} (`--shard {shard}`), femur by `--model-method silhouette`.\n")
    print("| variant | exposure | rotation error about x, y, z (°) | orientation error (°) | position error (mm) | contour distance (px) |")
    print("|---|---|---|---:|---:|---:|")
    cases = [(name, args.exposure) for name in VARIANTS] + [("sharp", own), ("all", own)]
    with tempfile.TemporaryDirectory() as tmp:
        for name, factor in cases:
            imaging, detector = VARIANTS[name]
            scen = pathlib.Path(tmp) / f"{name}-{factor:g}.toml"
            levels = list(LEVELS)
            levels[level] = factor
            scen.write_text(scenario_text(RUNS_PER_LEVEL, imaging, detector, levels, bare=name in BARE))
            out = pathlib.Path(tmp) / f"{name}-{factor:g}"
            run([binary, str(scen), "--out", str(out), "--shard", shard,
                 "--allow-dir", str(stamp.ROOT / "scenarios/models")])
            folder = next(out.iterdir())
            run([binary, "reconstruct", str(folder), "--model-method", "silhouette"])
            rot, pos, contour = femur_error(folder / "runs" / args.run)
            label = "all (the blurred scenario)" if name == "all" else LABELS.get(name, name)
            print(f"| {label} | ×{factor:g} | {rot[0]:+.3f}, {rot[1]:+.3f}, {rot[2]:+.3f} | "
                  f"{math.sqrt(sum(a * a for a in rot)):.3f} | {pos:.3f} | {contour:.3f} |", flush=True)


if __name__ == "__main__":
    main()
