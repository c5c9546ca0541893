#!/usr/bin/env python3
"""The worst single runs of a model's results, per exposure (or noise) level (issue 32, item 5).

ISO 5725 trueness and precision summarise a level; a vendor also needs to know whether any one
run went wrong. For each run of OUT with a results file NAME, this compares the model's measured
pose with the truth: the position error (mm, the distance between the origins) and the
orientation error (degrees, the angle of R_measured · R_trueᵀ), and prints per level the runs
scored, the largest of each, and the runs beyond the bounds.

Usage: bench/per_run.py OUT NAME [--model femur] [--bound-mm 0.1] [--bound-deg 0.1]
"""

import argparse
import json
import math
import pathlib
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import stamp  # noqa: E402


def angle_deg(a, b):
    """The rotation angle between two rotation matrices given as rows, degrees."""
    trace = sum(a[i][k] * b[i][k] for i in range(3) for k in range(3))
    return math.degrees(math.acos(max(-1.0, min(1.0, (trace - 1.0) / 2.0))))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("out")
    ap.add_argument("name")
    ap.add_argument("--model", default="femur")
    ap.add_argument("--bound-mm", type=float, default=0.1)
    ap.add_argument("--bound-deg", type=float, default=0.1)
    args = ap.parse_args()
    out = pathlib.Path(args.out)
    levels = {}
    for run in sorted((out / "runs").iterdir()):
        truth = json.loads((run / "truth.json").read_text())
        factor = truth.get("exposure_factor")
        level = f"×{factor}" if factor is not None else f"noise {truth['noise_level']}"
        row = levels.setdefault(level, {"runs": 0, "missing": 0, "mm": [], "deg": [], "beyond": []})
        row["runs"] += 1
        results = run / args.name
        measured = json.loads(results.read_text()) if results.exists() else {"phantoms": []}
        m = next((p for p in measured["phantoms"] if p["id"] == args.model and p.get("rotation")), None)
        if m is None:
            row["missing"] += 1
            continue
        t = next(p for p in truth["phantoms"] if p["id"] == args.model)
        mm = math.dist(m["position_mm"], t["position_mm"])
        deg = angle_deg(m["rotation"], t["rotation"])
        row["mm"].append(mm)
        row["deg"].append(deg)
        if mm > args.bound_mm or deg > args.bound_deg:
            row["beyond"].append(f"{truth['id']} ({mm:.3f} mm, {deg:.3f}°)")
    command = (f"bench/per_run.py OUT {args.name} --model {args.model} --bound-mm {args.bound_mm} "
               f"--bound-deg {args.bound_deg}")
    print(stamp.line(command, note=f"OUT: {stamp.output_origin(args.out, args.name)}") + "\n")
    print(f"| level | runs | not found | largest position error, mm | largest orientation error, ° | "
          f"runs beyond {args.bound_mm} mm or {args.bound_deg}° |")
    print("|---|---:|---:|---:|---:|---|")
    for level, row in sorted(levels.items(), key=lambda kv: kv[0]):
        worst_mm = max(row["mm"], default=float("nan"))
        worst_deg = max(row["deg"], default=float("nan"))
        beyond = ", ".join(row["beyond"]) or "none"
        print(f"| {level} | {row['runs']} | {row['missing']} | {worst_mm:.3f} | {worst_deg:.3f} | {beyond} |")


if __name__ == "__main__":
    main()
