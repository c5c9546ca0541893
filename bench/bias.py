#!/usr/bin/env python3
"""Controlled experiment for the reference program's biases on realistic images (issue 32).

Runs `scenarios/biplanar_realistic.toml` at exposure x1 with each unsharpness option switched on
alone, then all together (as `biplanar_realistic_blurred.toml` has them), reconstructs every run
with `rsasim reconstruct` (DLT calibration, markers), and prints per variant, over runs and both
beamlines:

  - the source depth error: the measured source minus the true one, along the line from the true
    detector centre to the true source (mm; negative: the source measured nearer the detector);
  - the lateral source error (mm, the rest of the error vector);
  - the femur's position error (mm) and the box beads matched per view.

Every variant shares the base scenario's seed, so runs compare draw by draw. A variant named
`NAME/PROFILE` reconstructs the images of variant NAME again with `--bead-centre PROFILE`: the
same images, only the bead-centre model changed. `NAME/edge-on` and `NAME/skip` reconstruct them
again with `--edge-on-plates fit` or `skip`: the DLT fits, or leaves out, the beads of the plates
seen edge-on (by default it leaves them out where the plates are imaged, as here, except in the
variant "bare", which is "all" with the plates given no thickness: "all, plates not imaged").

Usage: bench/bias.py [--runs N] [--bin PATH] [--variants a,b,...]
Prints a Markdown table stamped with commit, machine and date.
"""

import argparse
import json
import math
import pathlib
import re
import subprocess
import sys
import tempfile

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import stamp  # noqa: E402

ROOT = stamp.ROOT

# What each variant adds to [imaging] and [imaging.detector] of biplanar_realistic.toml: the
# blurred scenario's settings, one at a time.
SPOT = 'focal_spot = { size_mm = 1.2, profile = "uniform", samples = 3 }'
SPOT_HEEL = ('focal_spot = { size_mm = 1.2, profile = "uniform", samples = 3, '
             'heel_percent_per_100_mm = 10.0, anode_direction = "-c" }')
VARIANTS = {
    "sharp": ([], []),
    "area": (["pixel_samples = 2"], []),
    "spot": ([SPOT], []),
    "spot+heel": ([SPOT_HEEL], []),
    "psf": ([], ["psf = { sigma_mm = 0.15 }"]),
    "scatter": ([], ["scatter = { ratio = 0.2, sigma_mm = 40.0 }"]),
    "noise": ([], ["electronic_noise_dn = 2.0"]),
    "all": (["pixel_samples = 2", SPOT_HEEL],
            ["psf = { sigma_mm = 0.15 }", "scatter = { ratio = 0.2, sigma_mm = 40.0 }",
             "electronic_noise_dn = 2.0"]),
}
# "all" with the box's acrylic plates not imaged (no thickness: the beads float in the air), so
# a plate seen edge-on is no dense band along its beads.
VARIANTS["bare"] = VARIANTS["all"]
BARE = {"bare"}
# What the table calls a variant, where it is not its name.
LABELS = {"bare": "all, plates not imaged"}


# The rows of the table: the variants, two of them measured again with Gaussian bead centres
# (the reference program fits a sphere's profile to the beads of their sharp images), three with
# the edge-on plates' beads fitted in the DLT (left out by default where the plates are imaged),
# and "all" with plates not imaged, its edge-on plates' beads left out and (by default) fitted.
ROWS = ["sharp", "sharp/gaussian", "sharp/edge-on", "area", "spot", "spot+heel", "psf", "scatter",
        "scatter/gaussian", "scatter/edge-on", "noise", "all", "all/edge-on",
        "bare/skip", "bare"]


# The shipped protocol of biplanar_realistic.toml, which scenario_text rewrites.
LEVELS = [2.0, 1.0, 0.5, 0.25, 0.125]
RUNS_PER_LEVEL = 20


def scenario_text(runs, imaging, detector, levels=(1.0,), bare=False):
    """biplanar_realistic.toml with `runs` runs per level at the exposure `levels` and the
    variant's lines added to [imaging] and [imaging.detector]; `bare`: its plates' thickness
    removed (not imaged)."""
    text = (ROOT / "scenarios/biplanar_realistic.toml").read_text()
    if bare:
        plates = re.compile(r"^thickness_mm = 8\.0.*$", re.M)
        if len(plates.findall(text)) != 4:
            sys.exit("scenarios/biplanar_realistic.toml no longer has the four 8 mm plates bench/bias.py expects")
        text = plates.sub("", text)
    old_levels = "exposure_levels = [%s]" % ", ".join(repr(x) for x in LEVELS)
    if old_levels not in text or f"runs_per_level = {RUNS_PER_LEVEL}" not in text:
        sys.exit("scenarios/biplanar_realistic.toml no longer has the protocol bench/bias.py expects")
    text = text.replace('file = "models/', f'file = "{ROOT}/scenarios/models/')
    text = text.replace(old_levels, "exposure_levels = [%s]" % ", ".join(repr(x) for x in levels))
    text = text.replace(f"runs_per_level = {RUNS_PER_LEVEL}", f"runs_per_level = {runs}")
    text = text.replace("mas = 10.0", "\n".join(["mas = 10.0"] + imaging), 1)
    text = text.replace('polarity = "radiograph"', "\n".join(detector + ['polarity = "radiograph"']), 1)
    return text


def run(cmd):
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode != 0:
        sys.exit(f"{' '.join(map(str, cmd))} failed:\n{done.stderr}")
    return done.stdout + done.stderr


def mean_sd(v):
    if not v:
        return float("nan"), float("nan")
    m = sum(v) / len(v)
    sd = math.sqrt(sum((x - m) ** 2 for x in v) / (len(v) - 1)) if len(v) > 1 else 0.0
    return m, sd


def measure(out, results="measured-rsasim-dlt-markers.json"):
    depth, lateral, femur, matched = [], [], [], []
    for run_dir in sorted((out / "runs").iterdir()):
        truth = json.loads((run_dir / "truth.json").read_text())
        found = run_dir / results
        if not found.exists():
            continue
        measured = json.loads(found.read_text())
        det_of = {d["source"]: d for d in truth["detectors"]}
        for src in truth["sources"]:
            m = next((s for s in measured["sources"] if s["id"] == src["id"]), None)
            if m is None:
                continue
            det = det_of[src["id"]]
            axis = [a - b for a, b in zip(src["position_mm"], det["position_mm"])]
            n = math.sqrt(sum(a * a for a in axis))
            axis = [a / n for a in axis]
            err = [a - b for a, b in zip(m["position_mm"], src["position_mm"])]
            d = sum(e * a for e, a in zip(err, axis))
            depth.append(d)
            lateral.append(math.sqrt(max(0.0, sum(e * e for e in err) - d * d)))
        for d in measured["detectors"]:
            q = d.get("quality") or {}
            if q.get("beads_used") is not None:
                matched.append(q["beads_used"])
        t = next(p for p in truth["phantoms"] if p["id"] == "femur")
        m = next((p for p in measured["phantoms"] if p["id"] == "femur"), None)
        if m is not None:
            femur.append(math.dist(m["position_mm"], t["position_mm"]))
    return depth, lateral, femur, matched


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=4)
    ap.add_argument("--bin", default=None, help="rsasim binary (default: the release build, built)")
    ap.add_argument("--variants", default=",".join(ROWS))
    args = ap.parse_args()
    binary = args.bin
    if binary is None:
        binary = str(stamp.release_binary())
    print(stamp.line(f"bench/bias.py --runs {args.runs}", binary) + "\n")
    print("| variant | source depth error, mm (mean ± SD) | lateral source error, mm | femur position error, mm | box beads used per view |")
    print("|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.variants.split(","):
            variant, _, how = name.partition("/")
            if variant not in VARIANTS or how not in ("", "gaussian", "sphere", "edge-on", "skip"):
                sys.exit(f"unknown variant {name}: one of {', '.join(VARIANTS)}, optionally /gaussian, /sphere, /edge-on or /skip")
            imaging, detector = VARIANTS[variant]
            slug = re.sub(r"[^a-z0-9+]+", "-", variant)
            out = pathlib.Path(tmp) / slug
            if not out.exists():
                scen = pathlib.Path(tmp) / f"{slug}.toml"
                scen.write_text(scenario_text(args.runs, imaging, detector, bare=variant in BARE))
                run([binary, str(scen), "--out", str(out), "--allow-dir", str(ROOT / "scenarios/models")])
            measured = f"measured-rsasim-dlt-markers{'-' + how if how else ''}.json"
            how_args = (["--edge-on-plates", "fit"] if how == "edge-on"
                        else ["--edge-on-plates", "skip"] if how == "skip"
                        else ["--bead-centre", how] if how else [])
            run([binary, "reconstruct", str(out), *how_args, *(["--measured", measured] if how else [])])
            depth, lateral, femur, matched = measure(out, measured)
            fmt = lambda v: "%.3f ± %.3f (n %d)" % (*mean_sd(v), len(v))
            shown = LABELS.get(variant, variant)
            label = (f"{shown}, edge-on plates fitted" if how == "edge-on"
                     else f"{shown}, edge-on plates skipped" if how == "skip"
                     else f"{shown}, {how.capitalize() if how == 'gaussian' else how} bead centres" if how
                     else shown)
            print(f"| {label} | {fmt(depth)} | {fmt(lateral)} | {fmt(femur)} | {fmt(matched)} |", flush=True)


if __name__ == "__main__":
    main()
