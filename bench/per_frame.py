#!/usr/bin/env python3
"""Trueness frame by frame over a dynamic exam's repeated sequences (issue 31).

For an output OUT of a scenario with [sequence] and a results file NAME in every run (frame)
folder, this takes, for each frame number k, the errors of the sequences' frame k and prints per
phantom and per degree of freedom the largest |trueness| over the frames (trueness of frame k =
the mean error over the sequences), the RMS and the largest single error. Position errors are
measured − true along the box axes (mm); orientation errors are the components of the small
rotation R_measured·R_trueᵀ about the box axes (degrees, from its antisymmetric part).

With --joint, the joint's Grood–Suntay kinematics are computed from the measured poses with the
truth's own formulas (docs: Conventions, "Dynamic exams") and compared with the truth's
`frame.joints`: the same statistics for flexion, ab/adduction, rotation (degrees) and the three
translations (mm). The anatomical frames are given as the scenario gives them.

Usage: bench/per_frame.py OUT NAME [--joint knee:femur:tibia] [--proximal-frame-mm X,Y,Z]
"""

import argparse
import json
import math
import pathlib
import statistics
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import stamp  # noqa: E402


def mat(rows):
    return [list(r) for r in rows]


def mul(a, b):
    return [[sum(a[i][k] * b[k][j] for k in range(3)) for j in range(3)] for i in range(3)]


def transpose(a):
    return [[a[j][i] for j in range(3)] for i in range(3)]


def col(a, j):
    return [a[i][j] for i in range(3)]


def dot(u, v):
    return sum(x * y for x, y in zip(u, v))


def cross(u, v):
    return [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]


def small_rotation_deg(r):
    """The rotation vector of a near-identity rotation, degrees (antisymmetric part)."""
    return [math.degrees((r[2][1] - r[1][2]) / 2), math.degrees((r[0][2] - r[2][0]) / 2),
            math.degrees((r[1][0] - r[0][1]) / 2)]


def jcs(p_pos, p_rot, d_pos, d_rot):
    """Grood–Suntay angles (deg) and translations (mm) between two anatomical frames."""
    e1, e3 = col(p_rot, 0), col(d_rot, 1)
    e2 = cross(e1, e3)
    n = math.sqrt(dot(e2, e2))
    e2 = [x / n for x in e2]
    alpha = math.atan2(-dot(e2, col(p_rot, 1)), dot(e2, col(p_rot, 2)))
    beta = math.asin(max(-1.0, min(1.0, -dot(e1, e3))))
    gamma = math.atan2(-dot(e2, col(d_rot, 0)), dot(e2, col(d_rot, 2)))
    h = [d - p for d, p in zip(d_pos, p_pos)]
    return [math.degrees(alpha), math.degrees(beta), math.degrees(gamma), dot(h, e1), dot(h, e2), dot(h, e3)]


def stats(by_frame):
    """Largest |trueness| over frames, RMS and largest |error| over all."""
    trueness = [statistics.fmean(errs) for errs in by_frame.values()]
    flat = [e for errs in by_frame.values() for e in errs]
    return (max(abs(t) for t in trueness), math.sqrt(statistics.fmean(e * e for e in flat)),
            max(abs(e) for e in flat), min(len(v) for v in by_frame.values()))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("out")
    ap.add_argument("name")
    ap.add_argument("--joint", help="ID:PROXIMAL:DISTAL, e.g. knee:femur:tibia")
    ap.add_argument("--proximal-frame-mm", default="0,0,0",
                    help="origin of the proximal anatomical frame in its phantom, unrotated")
    args = ap.parse_args()
    out = pathlib.Path(args.out)
    errors = {}  # (phantom, dof) -> {frame: [errors]}
    joint_errors = {}
    offset = [float(x) for x in args.proximal_frame_mm.split(",")]
    for run in sorted((out / "runs").iterdir()):
        truth = json.loads((run / "truth.json").read_text())
        frame = truth["frame"]["index"]
        measured = json.loads((run / args.name).read_text())
        poses = {}
        for m in measured["phantoms"]:
            if not m.get("rotation"):
                continue
            t = next(p for p in truth["phantoms"] if p["id"] == m["id"])
            poses[m["id"]] = (m, t)
            if t["kind"] == "calibration_box":
                continue
            dp = [a - b for a, b in zip(m["position_mm"], t["position_mm"])]
            dr = small_rotation_deg(mul(mat(m["rotation"]), transpose(mat(t["rotation"]))))
            for dof, e in zip(["x (mm)", "y (mm)", "z (mm)", "about x (°)", "about y (°)", "about z (°)"], dp + dr):
                errors.setdefault((m["id"], dof), {}).setdefault(frame, []).append(e)
        if args.joint:
            jid, prox, dist = args.joint.split(":")
            (mp, _), (md, _) = poses[prox], poses[dist]
            p_rot, d_rot = mat(mp["rotation"]), mat(md["rotation"])
            p_pos = [mp["position_mm"][i] + dot(p_rot[i], offset) for i in range(3)]
            got = jcs(p_pos, p_rot, md["position_mm"], d_rot)
            want = next(j for j in truth["frame"]["joints"] if j["id"] == jid)
            want = want["angles_deg"] + want["translation_mm"]
            for dof, g, w in zip(["flexion (°)", "ab/adduction (°)", "rotation (°)", "q1 (mm)", "q2 (mm)", "q3 (mm)"], got, want):
                joint_errors.setdefault(dof, {}).setdefault(frame, []).append(g - w)
    command = (f"bench/per_frame.py OUT {args.name}"
               + (f" --joint {args.joint} --proximal-frame-mm {args.proximal_frame_mm}" if args.joint else ""))
    print(stamp.line(command, note=f"OUT: {stamp.output_origin(args.out, args.name)}") + "\n")
    print("| what | degree of freedom | largest \\|trueness\\| over frames | RMS | largest \\|error\\| | sequences per frame |")
    print("|---|---|---:|---:|---:|---:|")
    for (phantom, dof), by_frame in errors.items():
        t, r, m, n = stats(by_frame)
        print(f"| {phantom} | {dof} | {t:.4f} | {r:.4f} | {m:.4f} | {n} |")
    for dof, by_frame in joint_errors.items():
        t, r, m, n = stats(by_frame)
        print(f"| joint {args.joint.split(':')[0]} | {dof} | {t:.4f} | {r:.4f} | {m:.4f} | {n} |")


if __name__ == "__main__":
    main()
