#!/usr/bin/env python3
"""Tables that a test, an example or a bench of rsasim prints, run and written (issue 33).

Each subcommand runs the program that measures (a `cargo test … --nocapture`, an example, a
bench or a bench script), reads what it prints and writes the table file under
docs/src/results/tables/ with bench/stamp.py's stamp as its first line. Timing tables add the
load average at the start and at the end.

    bench/printed.py detection OUT FILE     # reconstruct_realistic::measure_detection_on_an_output
                                            #   on an attenuation-mode output (bench/accuracy.py
                                            #   realistic and blurred call it)
    bench/printed.py bead-centres           # reconstruct_realistic::beads_are_found_…: centroid,
                                            #   Gaussian fit, sphere fit -> bead-centre-methods.md
    bench/printed.py sampling               # sampling:: -> sampling-bead-centroids.md
    bench/printed.py adaptive               # examples/adaptive_check.rs on the blurred scenario
                                            #   -> adaptive-sampling.md
    bench/printed.py adaptive-crop          # sampling::adaptive_sampling_stays_within_its_bound_…
                                            #   (the knee crop) -> adaptive-crop.md
    bench/printed.py exr-encoders [OUT]     # examples/encoder_levels.rs on a biplanar output
                                            #   (simulated when OUT is not given) -> exr-encoders.md
    bench/printed.py detector-response      # benches/response.rs's CPU-time lines
                                            #   -> detector-response-speed.md
    bench/printed.py reconstruct-speed [OUT]   # bench/reconstruct.sh -> reconstruct-speed.md
    bench/printed.py fuzz [N] [--only KIND,…]  # examples/fuzz_inputs.rs received N (default
                                            #   20000) per command -> receiving-fuzz.md (hours)
    bench/printed.py attenuation-speed [--venv DIR]   # bench/attenuation.sh (rsasim against
                                            #   gVirtualXray and Embree) -> attenuation-speed.md,
                                            #   attenuation-transmission.md, attenuation-pathlength.md
    bench/printed.py binary-peers [--venv DIR]   # bench/run.sh --no-protocol (the binary
                                            #   projector and noise against Embree and gVirtualXray,
                                            #   the per-stage image bench) -> binary-vs-peers.md,
                                            #   binary-peer-details.md, binary-per-stage.md
    bench/printed.py first-run-cost         # bench/first_run.sh: a fresh clone's first build,
                                            #   run and test -> first-run-cost.md
    bench/printed.py protocols [--rounds N] [--baseline BIN]   # the binary, realistic and
                                            #   blurred protocols on 10-run shards, alternated with
                                            #   an older build -> protocols-speed.md
    bench/printed.py reconstruct-study [--rounds N] [--baseline BIN [--baseline-scenario FILE]]
                                            #   `rsasim reconstruct` on the 4-patient attenuation
                                            #   study, alternated with an older build on its own
                                            #   output -> reconstruct-study-speed.md
    bench/printed.py blurred-ladder [--rounds N]   # the sharp protocol turned into the blurred
                                            #   one an option at a time, each step against the
                                            #   binary protocol -> blurred-cost-ladder.md
    bench/printed.py protocol [--rounds N]  # the whole binary protocol: wall, CPU, peak RSS, size
                                            #   -> protocol-full.md
    bench/printed.py shards [--repeats N]   # bench/shards.sh: one run against 2 shards + merge
                                            #   -> shards-merge.md
    bench/printed.py missed-beads [OUT]     # examples/missed_beads.rs on 10 runs of the blurred
                                            #   protocol (shard 0/10, simulated when OUT is not
                                            #   given) -> missed-beads.md

Tests run from the release integration-test binary (`cargo test --release --locked --test
integration`), so one build serves every test table; RSASIM_TEST_BIN names that executable to run
it without cargo, RSASIM_BIN the rsasim binary (bench/stamp.py). --tables DIR writes elsewhere.
Standard library only.
"""

import argparse
import json
import os
import pathlib
import re
import shutil
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import stamp  # noqa: E402

ROOT = stamp.ROOT
TABLES = ROOT / stamp.TABLES


def log(msg):
    print(f"[{time.strftime('%H:%M:%S')}] {msg}", file=sys.stderr, flush=True)


def run(cmd, env=None, check=True):
    """Runs cmd in the repository, returns stdout + stderr (both printed to the log on failure)."""
    log(" ".join(map(str, cmd)))
    t0 = time.monotonic()
    done = subprocess.run([str(c) for c in cmd], cwd=ROOT, capture_output=True, text=True,
                          env={**os.environ, **(env or {})})
    log(f"  {time.monotonic() - t0:.1f} s")
    if check and done.returncode != 0:
        sys.exit(f"{' '.join(map(str, cmd))} failed ({done.returncode}):\n{done.stdout[-4000:]}\n{done.stderr[-4000:]}")
    return done.stdout + "\n" + done.stderr


def cargo_test(filter_, env=None, ignored=False):
    """Runs the release integration tests matching filter_ with --nocapture: through cargo, or
    the test executable $RSASIM_TEST_BIN when set (built by `cargo test --release --locked
    --test integration --no-run`; one build then serves every table without cargo deciding to
    rebuild in between)."""
    if os.environ.get("RSASIM_TEST_BIN"):
        cmd = [os.environ["RSASIM_TEST_BIN"], filter_, "--nocapture", "--test-threads=1"]
    else:
        cmd = ["cargo", "test", "--release", "--locked", "--test", "integration", filter_, "--",
               "--nocapture", "--test-threads=1"]
    if ignored:
        cmd.append("--ignored")
    return run(cmd, env)


def write(args_or_dir, name, command, table, binary=None, load_start=None, note=None):
    d = args_or_dir if isinstance(args_or_dir, pathlib.Path) else (
        pathlib.Path(args_or_dir.tables).resolve() if args_or_dir.tables else TABLES)
    stamp.write(d / name, command, table, binary, load_start, note)


def detection(out, path, command, binary=None):
    """The detection table of an existing attenuation-mode output, written to `path`."""
    text = cargo_test("reconstruct_realistic::measure_detection_on_an_output",
                      {"RSASIM_MEASURE_OUT": str(out)}, ignored=True)
    # With --nocapture the test's first line follows libtest's "test … ... " on the same line.
    rows = [l[l.index("|"):] for l in text.splitlines() if "|" in l and l.rstrip().endswith("|")]
    if len(rows) < 3:
        sys.exit(f"no detection table in the test's output:\n{text[-3000:]}")
    rows = [re.sub(r"^\| ×(\d+(?:\.\d+)?) ", lambda m: f"| ×{float(m.group(1)):g} ", r) for r in rows]
    stamp.write(path, command, "\n".join(rows), binary or stamp.release_binary(build=False),
                note="box beads of the plates facing each beamline and model beads, those the truth "
                     "marks as partly over metal left out; found: a detection within 1.5 px")


def cmd_detection(args):
    detection(pathlib.Path(args.out).resolve(), pathlib.Path(args.file).resolve(),
              f"bench/printed.py detection {args.out} {args.file}")


def cmd_bead_centres(args):
    binary = stamp.release_binary()
    text = cargo_test("reconstruct_realistic::beads_are_found_at_every_exposure_sharp_and_blurred_and_never_over_the_metal")
    pat = re.compile(r"^×([\d.]+) σ ([\d.]+): centroid mean ([\d.]+) p95 ([\d.]+); "
                     r"Gaussian fit mean ([\d.]+) p95 ([\d.]+); sphere fit mean ([\d.]+) p95 ([\d.]+) px$")
    rows = ["| images | centroid: mean / p95 (px) | Gaussian fit: mean / p95 (px) "
            "| sphere fit: mean / p95 (px) |", "|---|---|---|---|"]
    for line in text.splitlines():
        m = pat.match(line.strip())
        if m:
            factor, blur, cm, cp, gm, gp, pm, pp = m.groups()
            what = "sharp" if float(blur) == 0 else f"blurred after sampling (σ {float(blur):g} px)"
            rows.append(f"| {what}, exposure ×{float(factor):g} | {cm} / {cp} | {gm} / {gp} | {pm} / {pp} |")
    if len(rows) < 3:
        sys.exit(f"no centroid lines in the test's output:\n{text[-3000:]}")
    write(args, "bead-centre-methods.md", "bench/printed.py bead-centres", "\n".join(rows), binary,
          note="from `cargo test --release --test integration reconstruct_realistic::"
               "beads_are_found_at_every_exposure_sharp_and_blurred_and_never_over_the_metal -- --nocapture`; "
               "box beads of the test's own attenuation-mode scene, the same candidates measured three ways")


def cmd_sampling(args):
    binary = stamp.release_binary()
    text = cargo_test("sampling::")
    # The tests run in name order; the rows are keyed by kind and put in the table's order.
    found = {}
    n = lambda x: f"{int(x):,}"  # noqa: E731
    for line in text.splitlines():
        line = line.strip()
        m = re.match(r"^point sampling p95 ([\d.]+) px; 8×8: p95 ([\d.]+) px, max ([\d.]+) px over (\d+) beads$", line)
        if m:
            found["point"] = f"| one ray per pixel centre (the paper) | {m[1]} px | | {n(m[4])} |"
            found["area"] = f"| **`pixel_samples = 8`** (issue 12's target ≤ 0.02 px) | **{m[2]} px** | {m[3]} px | {n(m[4])} |"
        m = re.match(r"^(\d)×\d: p95 ([\d.]+) px, max ([\d.]+) px over (\d+) beads$", line)
        if m:
            found[f"area {m[1]}"] = f"| `pixel_samples = {m[1]}` | {m[2]} px | {m[3]} px | {n(m[4])} |"
        m = re.match(r"^(Uniform|Gaussian) 1\.2 mm spot, 8×8: p95 ([\d.]+) px, max ([\d.]+) px over (\d+) beads$", line)
        if m:
            found[m[1]] = f"| 8 × 8 and a 1.2 mm {m[1].replace('Uniform', 'uniform')} spot (3 × 3) | {m[2]} px | {m[3]} px | {n(m[4])} |"
        m = re.match(r"^attenuation, (\d+) beads: point p95 ([\d.]+) px; 8×8 p95 ([\d.]+) px \(max ([\d.]+)\)$", line)
        if m:
            found["attenuation point"] = f"| attenuation mode, bead absorption `1 − Q/S_open`, one ray | {m[2]} px | | {n(m[1])} |"
            found["attenuation area"] = f"| attenuation mode, 8 × 8 | {m[3]} px | {m[4]} px | {n(m[1])} |"
    order = ["point", "area 2", "area 4", "area 6", "area", "Uniform", "Gaussian", "attenuation point",
             "attenuation area"]
    rows = ["| 1 mm bead centroid vs truth, paper protocol geometry, noise 0 | p95 | max | beads |",
            "|---|---|---|---|"] + [found[k] for k in order if k in found]
    if len(rows) < 4:
        sys.exit(f"no sampling lines in the tests' output:\n{text[-3000:]}")
    write(args, "sampling-bead-centroids.md", "bench/printed.py sampling", "\n".join(rows), binary,
          note="from `cargo test --release --test integration sampling:: -- --nocapture`, which prints "
               "these rows only (no max for one ray)")


def cmd_adaptive(args):
    binary = stamp.release_binary()
    start = stamp.load()
    text = run(["cargo", "run", "--release", "--locked", "--quiet", "--example", "adaptive_check", "--",
                "scenarios/biplanar_realistic_blurred.toml"])
    rows = ["| image | pixels kept at one ray | max \\|ΔQ\\|/√Q | p99.9 | mean ΔQ/√Q | max \\|ΔE\\|/(E/√Q) | full sampling (s) | adaptive (s) |",
            "|---|---:|---:|---:|---:|---:|---:|---:|"]
    for line in text.splitlines():
        c = [x.strip() for x in line.strip().strip("|").split("|")]
        if len(c) == 9 and c[0] not in ("exposure",) and not c[0].startswith("---"):
            exposure, det, one, full, fast, mx, p999, mean, de = c
            rows.append(f"| {exposure}, {det} | {one} | {mx} | {p999} | {mean} | {de} | {full} | {fast} |")
    if len(rows) < 3:
        sys.exit(f"no rows in adaptive_check's output:\n{text[-3000:]}")
    write(args, "adaptive-sampling.md", "bench/printed.py adaptive", "\n".join(rows), binary, load_start=start,
          note="from `cargo run --release --example adaptive_check -- scenarios/biplanar_realistic_blurred.toml` "
               "(run 0, full size); the differences are exact, the seconds depend on the load")


def cmd_missed_beads(args):
    binary = stamp.release_binary()
    tmp = tempfile.mkdtemp(prefix="rsasim-missed.")
    try:
        if args.out:
            out = pathlib.Path(args.out).resolve()
        else:
            run([binary, ROOT / "scenarios/biplanar_realistic_blurred.toml", "--shard", "0/10",
                 "--out", pathlib.Path(tmp) / "blurred"])
            out = pathlib.Path(tmp) / "blurred" / "shard-0-of-10"
        text = run(["cargo", "run", "--release", "--locked", "--quiet", "--example", "missed_beads", "--", out])
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    rows = [l for l in text.splitlines() if l.startswith("|")]
    if len(rows) < 3:
        sys.exit(f"no rows in missed_beads' output:\n{text[-3000:]}")
    write(args, "missed-beads.md", f"bench/printed.py missed-beads{' ' + args.out if args.out else ''}",
          "\n".join(rows), binary,
          note="from `cargo run --release --example missed_beads -- OUT` on `scenarios/"
               "biplanar_realistic_blurred.toml --shard 0/10` (10 runs, two per exposure level); "
               "every box bead the truth puts on a calibration image, not over an implant")


def simulate_biplanar(binary, tmp):
    out = pathlib.Path(tmp) / "biplanar"
    run([binary, ROOT / "scenarios/biplanar.toml", "--out", out])
    return out


def cmd_exr_encoders(args):
    binary = stamp.release_binary()
    tmp = tempfile.mkdtemp(prefix="rsasim-exr.")
    try:
        out = pathlib.Path(args.out).resolve() if args.out else simulate_biplanar(binary, tmp)
        run(["cargo", "build", "--release", "--locked", "--quiet", "--example", "encoder_levels"])
        start = stamp.load()
        text = run(["cargo", "run", "--release", "--locked", "--quiet", "--example", "encoder_levels", "--", out])
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    # It prints one section per format ("TIFF: … MB per image …", then its table); keep EXR's.
    sections = re.split(r"(?m)^(\S+): ([\d.]+) MB per image before compression$", text)
    table = None
    for i in range(1, len(sections) - 2, 3):
        if sections[i].upper() == "EXR":
            raw = sections[i + 1]
            body = [l for l in sections[i + 2].splitlines() if l.startswith("|")]
            body[0] = f"| encoder | EXR ZIP blocks ({raw} MB raw per image): ms per image | MB | of raw |"
            table = "\n".join(body)
    if table is None:
        sys.exit(f"no EXR section in encoder_levels' output:\n{text[-3000:]}")
    write(args, "exr-encoders.md", f"bench/printed.py exr-encoders{' ' + args.out if args.out else ''}",
          table, binary, load_start=start,
          note="from `cargo run --release --example encoder_levels -- OUT` on a scenarios/biplanar.toml "
               "output; one thread, best of 3; the times compare with each other only")


def cmd_detector_response(args):
    binary = stamp.release_binary()
    start = stamp.load()
    # The CPU-time lines come before criterion's own benchmarks; a filter that matches none of
    # them skips those.
    text = run(["cargo", "bench", "--locked", "--bench", "response", "--", "^no-criterion-benchmark$"])
    ms = dict(re.findall(r"(?m)^(\w+): ([\d.]+) ms of CPU \(all threads\)$", text))
    labels = [
        ("poly30_raw", "`render` (the sharp path: expected values, Poisson, digitisation in one pass)"),
        ("poly30_expected_image", "`expected` (Q, E and S_open of every pixel)"),
        ("from_expected_plain", "`render_expected`, every option off (Poisson and digitisation; same bytes as `render`)"),
        ("from_expected_psf", "… with `psf = { sigma_mm = 0.15 }` (5 taps per axis at 0.2986 mm)"),
        ("from_expected_scatter", "… with `scatter = { ratio = 0.3, sigma_mm = 40 }` (Q and E blurred, 134 px σ)"),
        ("from_expected_scatter_psf_e", "… with both and `electronic_noise_dn = 2`"),
    ]
    rows = ["| step | CPU time |", "|---|---|"]
    for key, label in labels:
        if key not in ms:
            sys.exit(f"benches/response.rs printed no line for {key}:\n{text[-3000:]}")
        rows.append(f"| {label} | {float(ms[key]):.0f} ms |")
    write(args, "detector-response-speed.md", "bench/printed.py detector-response", "\n".join(rows), binary,
          load_start=start,
          note="from `cargo bench --bench response`'s CPU-time lines: CPU time of the process summed over "
               "threads, median of 3, 30 energy bins, 1440²")


# Model-based RSA's target per run, from the issue that asked for it: under 2 s.
RECONSTRUCT_TARGET = {"silhouette": "< 2 s"}


def cmd_reconstruct_speed(args):
    binary = stamp.release_binary()
    start = stamp.load()
    text = run(["bash", "bench/reconstruct.sh"] + ([args.out] if args.out else []),
               {"RSASIM_BIN": str(binary)})
    rows = ["| `--model-method` | per run (calibration of both beamlines + the model), one core | peak memory | target |",
            "|---|---|---|---|"]
    rss = re.findall(r"peak RSS (\d+) kB", text)
    for k, m in enumerate(re.finditer(r"(?m)^(\w+)\s+([\d.]+) s for (\d+) runs: ([\d.]+) s per run on one core$", text)):
        mem = f"{int(rss[k]) / 1024:.0f} MB" if k < len(rss) else "—"
        rows.append(f"| `{m[1]}` | {float(m[4]):.2f} s ({float(m[2]):.1f} s for {m[3]} runs) | {mem} | "
                    f"{RECONSTRUCT_TARGET.get(m[1], '')} |")
    if len(rows) < 3:
        sys.exit(f"no timings in bench/reconstruct.sh's output:\n{text[-3000:]}")
    write(args, "reconstruct-speed.md", f"bench/printed.py reconstruct-speed{' ' + args.out if args.out else ''}",
          "\n".join(rows), binary, load_start=start,
          note="from `bench/reconstruct.sh` (`RAYON_NUM_THREADS=1`, every run of scenarios/biplanar.toml); "
               "wall time, so a loaded machine inflates it")


FUZZ_KINDS = {
    "export-xmalab": "`export --to xmalab`",
    "export-autoscoper": "`export --to autoscoper`",
    "evaluate": "`evaluate`",
    "verify": "`verify`",
    "merge": "`merge`",
    "sweep-merge": "`sweep --merge`",
    "evaluate-sweep": "`evaluate` on a sweep folder",
    "reconstruct-sweep": "`reconstruct` on a sweep folder",
    "reconstruct": "`reconstruct`",
    "evaluate-study": "`evaluate` on a study",
}


def cmd_fuzz(args):
    binary = stamp.release_binary()
    run(["cargo", "build", "--release", "--locked", "--quiet", "--example", "fuzz_inputs"])
    example = stamp.target_dir() / "release" / "examples" / "fuzz_inputs"
    kinds = args.only.split(",") if args.only else list(FUZZ_KINDS)
    start = stamp.load()
    rows = ["| command | mutants | exit 0 | exit 1 | exit 2 | failures | time |", "|---|---:|---:|---:|---:|---:|---:|"]
    for kind in kinds:
        text = run([example, "received", args.n, "--only", kind], {"RSASIM_BIN": str(binary)}, check=False)
        for m in re.finditer(r"(?m)^\| ([\w-]+) \| (\d+) \| (\d+) \| (\d+) \| (\d+) \| (\d+) \| (\d+) s \|$", text):
            cells = [f"{int(x):,}" for x in m.groups()[1:]]
            rows.append(f"| {FUZZ_KINDS.get(m[1], m[1])} | " + " | ".join(cells) + " s |")
    write(args, "receiving-fuzz.md", f"bench/printed.py fuzz {args.n}" + (f" --only {args.only}" if args.only else ""),
          "\n".join(rows), binary, load_start=start,
          note=f"from `examples/fuzz_inputs.rs received {args.n} --only KIND` per command (seeds 0 to "
               f"{int(args.n) - 1:,}); a failure is an exit other than 0 or 2 (1 for reconstruct), a hang or a crash")


# The target for the ratio ours/peer on the realistic scene (issue 11): at most 0.05.
ATTENUATION_TARGET = "≤ 0.05"


def cmd_attenuation_speed(args):
    binary = stamp.release_binary()
    start = stamp.load()
    cmd = ["bash", "bench/attenuation.sh"] + (["--venv", args.venv] if args.venv else [])
    run(cmd)
    summary = json.loads((ROOT / "bench/results/attenuation/summary_attenuation.json").read_text())
    rows = ["| image | rsasim `attenuation::render` | gVXR `computeXRayImage` | ratio ours/peer | issue's target |",
            "|---|---|---|---|---|"]
    for t in summary["timing"]:
        g = t.get("gvxr_ms")
        ratio = f"{t['ours_ms'] / g:.3f}" if g else "—"
        # Issue 32: every like-for-like row (both images with noise, or both without). The
        # focal-spot row is not: gVXR's image has no noise there, rsasim's has.
        like_for_like = g and "focal spot" not in t["what"]
        target = ATTENUATION_TARGET if like_for_like else ""
        if like_for_like:
            ratio = f"**{ratio}**"
        rows.append(f"| {t['what']} | {t['ours_ms']:.1f} ms | {'—' if g is None else f'{g:.0f} ms'} | {ratio} | {target} |")
    command = "bench/printed.py attenuation-speed" + (f" --venv {args.venv}" if args.venv else "")
    write(args, "attenuation-speed.md", command,
          "\n".join(rows), binary, load_start=start,
          note="from `bench/attenuation.sh` (medians of 5 after a warm-up; its summary_attenuation.json "
               "in bench/results/attenuation/); gVXR on the same machine")
    # The same run's checks, as bench/peers_attenuation.py's summary.md prints them: the
    # transmission against gVXR (its table and the lines under it) and the path lengths against
    # Embree. Blocks of summary.md are separated by blank lines.
    blocks = [b.strip() for b in (ROOT / "bench/results/attenuation/summary.md").read_text().split("\n\n")]
    for name, head, what in (
            ("attenuation-transmission.md", "| scene | region |",
             "per-pixel transmission T, gVXR against rsasim (relative difference), then the lines under the table"),
            ("attenuation-pathlength.md", "| path length vs Embree |",
             "path lengths, rsasim against Embree on the same triangles")):
        at = [i for i, blk in enumerate(blocks) if blk.startswith(head)]
        if not at:
            sys.exit(f"bench/results/attenuation/summary.md has no table starting {head!r}")
        text = blocks[at[0]]
        if at[0] + 1 < len(blocks) and blocks[at[0] + 1].startswith("- "):
            text += "\n\n" + blocks[at[0] + 1]
        write(args, name, command, text, binary, load_start=start,
              note=f"from `bench/attenuation.sh` (its summary.md in bench/results/attenuation/): {what}")


def cmd_binary_peers(args):
    """bench/run.sh without its protocol step (protocol-full.md times that): the criterion
    medians of the binary projector and noise, the per-stage image bench and the peers (Embree,
    gVirtualXray) on the same scenes, written as three tables."""
    binary = stamp.release_binary()
    start = stamp.load()
    began = time.time()
    run(["bash", "bench/run.sh", "--no-protocol"] + (["--venv", args.venv] if args.venv else []))
    results = ROOT / "bench/results"

    def fresh(name):
        # bench/run.sh reuses an older peer JSON when a peer fails; a table must not.
        path = results / name
        if not path.is_file() or path.stat().st_mtime < began:
            sys.exit(f"{path} was not written by this run of bench/run.sh (see bench/results/*.log)")
        return json.loads(path.read_text())

    embree, gvxr = fresh("embree.json"), fresh("gvxr.json")
    command = "bench/printed.py binary-peers" + (f" --venv {args.venv}" if args.venv else "")
    write(args, "binary-vs-peers.md", command, binary_vs_peers(fresh("summary.json")), binary, load_start=start,
          note="ours: criterion medians (`cargo bench --bench projector`); peers: medians of "
               f"{os.environ.get('BENCH_REPEATS', '7')} after a warm-up (`bench/peers.py`); same machine, same run")
    write(args, "binary-peer-details.md", command, binary_peer_details(embree, gvxr), binary, load_start=start,
          note=f"{embree['peer']} (`bench/peers.py embree`, pinned to one CPU); {gvxr['peer']} "
               f"(`bench/peers.py gvxr`) on {gvxr['renderer']}, threads {gvxr['LP_NUM_THREADS']}")
    write(args, "binary-per-stage.md", command, binary_per_stage((results / "images.log").read_text()), binary,
          load_start=start, note="`cargo bench --bench images` (its bench/results/images.log): one image, one thread "
                                 "for the trace, median of 7, ms")


def binary_vs_peers(summary):
    """The rows of `bench/peers.py summary` (its summary.json) as the ours-against-peers table."""
    fmt = lambda v: "—" if v is None else f"{v:.2f} ms" if v < 10 else f"{v:.1f} ms"  # noqa: E731
    rows = ["| what | ours | peer | peer time | ratio ours/peer | target | met |", "|---|---:|---|---:|---:|---|---|"]
    for what, ours, peer, peer_ms, ratio, target, met in summary["rows"]:
        if target is None:
            tgt, r = "", "—" if ratio is None else f"{ratio:.3f}"
        else:
            tgt = f"≤ {target:g} (≥ {1 / target:g}× faster)" if target < 1 else f"≤ {target:g}"
            r = "n/a" if ratio is None else f"**{ratio:.3f}**"
            met = {"yes": "yes", "no": "**no**"}.get(met, met)
        rows.append(f"| {what} | {fmt(ours)} | {peer or '—'} | {fmt(peer_ms) if peer else '—'} | {r} | {tgt} | {met} |")
    return "\n".join(rows)


def binary_peer_details(embree, gvxr):
    """The peers' set-up, image times and agreement with rsasim, from their JSON files."""
    names = {"femur": "femoral component", "sphere": "sphere"}
    rows = ["| peer, scene | set-up | image | agreement with rsasim |", "|---|---|---|---|"]
    for scene, r in embree["scenes"].items():
        rows.append(f"| Embree, {names.get(scene, scene)} | scene build (BVH) {r['build_ms']:.1f} ms, 1 core | "
                    f"rtcOccluded1 {r['occluded_ms']:.1f} ms, rtcIntersect1 {r['intersect_ms']:.1f} ms | "
                    f"hit mask against `render_binary`: {r['disagree_px_vs_binary']:,} px differ, against "
                    f"`render_binary_traced`: {r['disagree_px_vs_traced']:,} ({r['hit_px']:,} px hit) |")
    for scene, r in gvxr["scenes"].items():
        rows.append(f"| gVXR, {names.get(scene, scene)} | scene {r['setup_ms']:.0f} ms (OpenGL context "
                    f"{gvxr['context_ms']:.0f} ms, once) | {r['xray_clean_ms']:.1f} ms, {r['xray_noise_ms']:.1f} ms "
                    f"with Poisson noise | shadow {r['shadow_px']:,} px against our {r['ours_px']:,}: "
                    f"{r['disagree_px']:,} px differ |")
    return "\n".join(rows)


def binary_per_stage(log_text):
    """The per-stage table from what `cargo bench --bench images` printed (benches/images.rs)."""
    bvh = re.search(r"^femur BVH build \((\d+) triangles\): ([\d.]+) ms$", log_text, re.M)
    stage = re.compile(r"^(calibration|model)\s+image 1440² \((\d+) covered px\): trace ([\d.]+) ms, noise ([\d.]+) ms, "
                       r"TIFF ([\d.]+) ms, EXR ([\d.]+) ms, total ([\d.]+) ms$", re.M)
    found = stage.findall(log_text)
    if not bvh or len(found) != 2:
        sys.exit(f"bench/results/images.log lacks the per-stage lines:\n{log_text[-2000:]}")
    what = {"calibration": "calibration (256 beads, {} px covered)",
            "model": "model (femoral component + 6 beads, {} px covered)"}
    rows = ["| image | trace | noise | TIFF | EXR | total |", "|---|---:|---:|---:|---:|---:|"]
    for name, covered, *ms in found:
        rows.append(f"| {what[name].format(f'{int(covered):,}')} | " + " | ".join(ms) + " |")
    rows += ["", f"The femoral component's BVH ({int(bvh.group(1)):,} triangles, for `render_binary_traced`) "
                 f"took {bvh.group(2)} ms to build, outside these timings."]
    return "\n".join(rows)


# Issue 32's targets for the realistic protocols against the binary one (10-run copies).
PROTOCOL_TARGET = {"biplanar_realistic": "≤ 2.5", "biplanar_realistic_blurred": "≤ 8"}
PROTOCOLS = ("biplanar", "biplanar_realistic", "biplanar_realistic_blurred")


def timed(binary, scenario, out):
    """Wall, CPU (user + system) seconds and peak RSS (kB) of one simulation of 10 runs
    (`--shard 0/10`): `scenario` is a shipped scenario's name or a scenario file's path."""
    path = scenario if isinstance(scenario, pathlib.Path) else f"scenarios/{scenario}.toml"
    shutil.rmtree(out, ignore_errors=True)
    with tempfile.NamedTemporaryFile("r") as t:
        run(["/usr/bin/time", "-o", t.name, "-f", "%e %U %S %M", str(binary), path,
             "--out", str(out), "--shard", "0/10"])
        wall, user, system, rss = t.read().split()[-4:]
    shutil.rmtree(out, ignore_errors=True)
    return float(wall), float(user) + float(system), int(rss)


def cmd_protocols(args):
    binary = stamp.release_binary()
    baseline = pathlib.Path(args.baseline).resolve() if args.baseline else None
    root = pathlib.Path("/dev/shm") if pathlib.Path("/dev/shm").is_dir() else pathlib.Path(tempfile.gettempdir())
    out = pathlib.Path(tempfile.mkdtemp(dir=root, prefix="rsasim-protocols."))
    start = stamp.load()
    mine = {s: [] for s in PROTOCOLS}
    theirs = {s: [] for s in PROTOCOLS}
    try:
        for r in range(args.rounds):
            for s in PROTOCOLS:
                # This build and the baseline alternate, so both see the same load.
                mine[s].append(timed(binary, s, out / "a"))
                log(f"round {r + 1} {s}: {mine[s][-1]}")
                if baseline:
                    theirs[s].append(timed(baseline, s, out / "b"))
                    log(f"round {r + 1} {s}, baseline: {theirs[s][-1]}")
    finally:
        shutil.rmtree(out, ignore_errors=True)
    med = lambda v: sorted(v)[len(v) // 2]  # noqa: E731 (median of an odd count)
    head = "| scenario (`--shard 0/10`: 10 runs, 80 files) | wall | CPU | peak RSS | ÷ binary, wall | ÷ binary, CPU | issue 32's target |"
    rows = [head, "|---|---:|---:|---:|---:|---:|---|"]
    if baseline:
        rows[0] += " baseline wall | this ÷ baseline, wall |"
        rows[1] += "---:|---:|"
    for s in PROTOCOLS:
        walls, cpus = [m[0] for m in mine[s]], [m[1] for m in mine[s]]
        ratio_wall = med([a[0] / b[0] for a, b in zip(mine[s], mine["biplanar"])])
        ratio_cpu = med([a[1] / b[1] for a, b in zip(mine[s], mine["biplanar"])])
        row = (f"| `{s}.toml` | {med(walls):.2f} s | {med(cpus):.2f} s | {max(m[2] for m in mine[s]) / 1024:.0f} MB | "
               f"{ratio_wall:.2f} | {ratio_cpu:.2f} | {PROTOCOL_TARGET.get(s, '')} |")
        if baseline:
            row += (f" {med([t[0] for t in theirs[s]]):.2f} s | "
                    f"{med([a[0] / b[0] for a, b in zip(mine[s], theirs[s])]):.3f} |")
        rows.append(row)
    command = f"bench/printed.py protocols --rounds {args.rounds}" + (f" --baseline {args.baseline}" if baseline else "")
    note = (f"medians over {args.rounds} rounds; in each round the three scenarios run one after the other"
            + (" (each followed by the baseline binary)" if baseline else "")
            + ", output on tmpfs; ratios are taken round by round, then their median")
    if baseline:
        note += f"; baseline: `{run([str(baseline), '--version']).strip()}`"
    write(args, "protocols-speed.md", command, "\n".join(rows), binary, load_start=start, note=note)


# The blurred protocol built up from the sharp one, one option at a time (issue 32): each step is
# a point of a sweep (`rsasim sweep --no-run`), so it is the shipped scenario with those keys set.
LADDER_UP = """name = "ladder_up"
scenario = "{root}/scenarios/biplanar_realistic.toml"

[[parameters]]
key = "imaging.detector.psf.sigma_mm"
values = [0.15]
"""
LADDER_DOWN = """name = "ladder_down"
scenario = "{root}/scenarios/biplanar_realistic_blurred.toml"
combine = "zip"

[[parameters]]
key = "imaging.pixel_samples"
values = [1, 1, 2]

[[parameters]]
key = "imaging.focal_spot.samples"
values = [1, 1, 1]

[[parameters]]
key = "imaging.focal_spot.heel_percent_per_100_mm"
values = [0.0, 0.0, 0.0]

[[parameters]]
key = "imaging.detector.electronic_noise_dn"
values = [0.0, 2.0, 2.0]
"""


def cmd_blurred_ladder(args):
    binary = stamp.release_binary()
    root = pathlib.Path("/dev/shm") if pathlib.Path("/dev/shm").is_dir() else pathlib.Path(tempfile.gettempdir())
    work = pathlib.Path(tempfile.mkdtemp(dir=root, prefix="rsasim-ladder."))
    start = stamp.load()
    try:
        for name, text in (("up", LADDER_UP), ("down", LADDER_DOWN)):
            (work / f"{name}.toml").write_text(text.format(root=ROOT))
            run([binary, "sweep", work / f"{name}.toml", "--no-run", "--out", work / name])
        steps = [
            ("`biplanar.toml`: binary images", "biplanar"),
            ("`biplanar_realistic.toml`: attenuation, one ray per pixel from a point source", "biplanar_realistic"),
            ("+ detector PSF (σ 0.15 mm)", work / "up/points/p00.toml"),
            ("+ scatter (SPR 0.2, σ 40 mm)", work / "down/points/p00.toml"),
            ("+ electronic noise (2 DN)", work / "down/points/p01.toml"),
            ("+ 2 × 2 rays per pixel", work / "down/points/p02.toml"),
            ("+ 1.2 mm focal spot (3 × 3 sub-sources, heel 10 %/100 mm): "
             "`biplanar_realistic_blurred.toml`", "biplanar_realistic_blurred"),
        ]
        times = [[] for _ in steps]
        for r in range(args.rounds):
            for k, (label, scenario) in enumerate(steps):
                times[k].append(timed(binary, scenario, work / "out"))
                log(f"round {r + 1} {label}: {times[k][-1]}")
    finally:
        shutil.rmtree(work, ignore_errors=True)
    med = lambda v: sorted(v)[len(v) // 2]  # noqa: E731 (median of an odd count)
    rows = ["| step (each adds to the one above; `--shard 0/10`: 10 runs, 80 files) | wall | CPU | "
            "÷ binary, wall | the step's own cost ÷ binary, wall |",
            "|---|---:|---:|---:|---:|"]
    for k, (label, _) in enumerate(steps):
        ratio = med([a[0] / b[0] for a, b in zip(times[k], times[0])])
        own = "" if k == 0 else f"{med([(a[0] - p[0]) / b[0] for a, p, b in zip(times[k], times[k - 1], times[0])]):+.2f}"
        rows.append(f"| {label} | {med([t[0] for t in times[k]]):.2f} s | {med([t[1] for t in times[k]]):.2f} s | "
                    f"{ratio:.2f} | {own} |")
    note = (f"medians over {args.rounds} rounds; in each round the steps run one after the other, output on "
            "tmpfs; ratios are taken round by round, then their median. Every step but the first two is a "
            "point of `rsasim sweep --no-run` on the shipped scenario (the keys this command sets are in "
            "bench/printed.py, LADDER_UP and LADDER_DOWN); issue 32's target for the last row is ≤ 8")
    write(args, "blurred-cost-ladder.md", f"bench/printed.py blurred-ladder --rounds {args.rounds}",
          "\n".join(rows), binary, load_start=start, note=note)


# The realistic study `reconstruct` is timed on (issue 32: at least 3× faster than 0.6.0).
STUDY = "scenarios/tka_migration_attenuation.toml"


def timed_reconstruct(binary, out):
    """Wall, CPU (user + system) seconds and peak RSS (kB) of `rsasim reconstruct OUT`, its earlier
    results removed first."""
    for f in out.glob("runs/*/measured-rsasim-*.json"):
        f.unlink()
    with tempfile.NamedTemporaryFile("r") as t:
        run(["/usr/bin/time", "-o", t.name, "-f", "%e %U %S %M", str(binary), "reconstruct", str(out)])
        wall, user, system, rss = t.read().split()[-4:]
    return float(wall), float(user) + float(system), int(rss)


def cmd_reconstruct_study(args):
    binary = stamp.release_binary()
    baseline = pathlib.Path(args.baseline).resolve() if args.baseline else None
    # Under the system's temporary folder, which 0.6.0 accepts (it refuses /dev/shm); the images
    # are read once before the rounds, so the page cache serves them as tmpfs would.
    work = pathlib.Path(tempfile.mkdtemp(prefix="rsasim-reconstruct-study."))
    try:
        run([binary, STUDY, "--out", work / "a"])
        if baseline:
            scenario = pathlib.Path(args.baseline_scenario or STUDY).resolve()
            run([baseline, scenario, "--out", work / "b"])
        start = stamp.load()
        mine, theirs = [], []
        for r in range(args.rounds):
            mine.append(timed_reconstruct(binary, work / "a"))
            log(f"round {r + 1}: {mine[-1]}")
            if baseline:
                theirs.append(timed_reconstruct(baseline, work / "b"))
                log(f"round {r + 1}, baseline: {theirs[-1]}")
        runs = len(list((work / "a").glob("runs/*/truth.json")))
    finally:
        shutil.rmtree(work, ignore_errors=True)
    med = lambda v: sorted(v)[len(v) // 2]  # noqa: E731 (median of an odd count)
    rows = ["| build | wall | CPU | peak RSS |", "|---|---:|---:|---:|"]
    rows.append(f"| this build | {med([m[0] for m in mine]):.1f} s | {med([m[1] for m in mine]):.1f} s | "
                f"{max(m[2] for m in mine) / 1024:.0f} MB |")
    if baseline:
        rows.append(f"| baseline | {med([t[0] for t in theirs]):.1f} s | {med([t[1] for t in theirs]):.1f} s | "
                    f"{max(t[2] for t in theirs) / 1024:.0f} MB |")
        rows.append(f"| baseline ÷ this build (issue 32: ≥ 3) | "
                    f"{med([b[0] / a[0] for a, b in zip(mine, theirs)]):.2f} | "
                    f"{med([b[1] / a[1] for a, b in zip(mine, theirs)]):.2f} | |")
    command = f"bench/printed.py reconstruct-study --rounds {args.rounds}" + (
        f" --baseline {args.baseline}" if baseline else "") + (
        f" --baseline-scenario {args.baseline_scenario}" if baseline and args.baseline_scenario else "")
    note = (f"`rsasim reconstruct OUT` on `{STUDY}` ({runs} runs, 2 images each), medians over "
            f"{args.rounds} rounds" + (", each followed by the baseline on its own output of the same study"
                                       if baseline else "")
            + "; ratios are taken round by round, then their median")
    if baseline:
        note += f"; baseline: `{run([str(baseline), '--version']).strip()}`"
    write(args, "reconstruct-study-speed.md", command, "\n".join(rows), binary, load_start=start, note=note)


def cmd_first_run(args):
    start = stamp.load()
    text = run(["bash", "bench/first_run.sh"])
    vals = dict(re.findall(r"(?m)^(\w+)=(.*)$", text))
    need = ["build_release_s", "run_s", "target_release_gb", "registry_gb", "output_gb", "build_test_s",
            "test_s", "target_debug_gb"]
    if any(k not in vals for k in need):
        sys.exit(f"bench/first_run.sh printed no figures:\n{text[-3000:]}")
    mmss = lambda s: f"{int(float(s)) // 60} min {int(float(s)) % 60} s"  # noqa: E731
    rows = ["| | first time | disk |", "|---|---|---|",
            f"| `cargo run --release -- scenarios/biplanar.toml` | {mmss(vals['build_release_s'])} to build, "
            f"then {float(vals['run_s']):.0f} s to run | {vals['target_release_gb']} GB build (`target/release`), "
            f"{vals['registry_gb']} GB crate sources, {vals['output_gb']} GB output |",
            f"| `cargo test --locked` | {mmss(vals['build_test_s'])} to build, then {mmss(vals['test_s'])} to run | "
            f"{vals['target_debug_gb']} GB build (`target/debug`) |"]
    d = pathlib.Path(args.tables).resolve() if args.tables else TABLES
    stamp.write(d / "first-run-cost.md", "bench/printed.py first-run-cost", "\n".join(rows), load_start=start,
                version_line=vals.get("version"), commit_text=vals.get("commit"),
                note="a fresh clone with an empty target folder and crate cache (fetched first, not timed); "
                     "build jobs as cargo chooses")


def cmd_adaptive_crop(args):
    binary = stamp.release_binary()
    text = cargo_test("sampling::adaptive_sampling_stays_within_its_bound_of_full_sampling")
    m = re.search(r"adaptive vs full, knee crop 360²: max \|ΔQ\|/√Q ([\d.]+), max \|ΔE\|/\(E/√Q\) ([\d.]+); "
                  r"([\d.]+) % of pixels keep one ray; (\d+) pixels where one ray is off by > 0\.1 SD, "
                  r"(\d+) of them refined", text)
    if not m:
        sys.exit(f"no crop line in the test's output:\n{text[-3000:]}")
    q, e, kept, off, refined = m.groups()
    rows = ["| 360² crop of the knee, 60 keV, 2 × 2 rays, 1.2 mm spot of 3 × 3 | value | the test requires |",
            "|---|---:|---|",
            f"| largest \\|ΔQ\\|/√Q of any pixel, adaptive against full sampling | {q} | ≤ 0.1 |",
            f"| largest \\|ΔE\\|/(E/√Q) | {e} | ≤ 0.1 |",
            f"| pixels kept at one ray | {kept} % | > 50 % |",
            f"| pixels where one ray is off by more than 0.1 SD | {int(off):,} | > 1,000 |",
            f"| of those, refined | {int(refined):,} | all |"]
    write(args, "adaptive-crop.md", "bench/printed.py adaptive-crop", "\n".join(rows), binary,
          note="from `cargo test --release --test integration sampling::adaptive_sampling_stays_within_its_bound"
               "_of_full_sampling -- --nocapture`")


def cmd_protocol(args):
    binary = stamp.release_binary()
    root = pathlib.Path("/dev/shm") if pathlib.Path("/dev/shm").is_dir() else pathlib.Path(tempfile.gettempdir())
    out = pathlib.Path(tempfile.mkdtemp(dir=root, prefix="rsasim-protocol."))
    start = stamp.load()
    rounds = []
    try:
        for r in range(args.rounds):
            shutil.rmtree(out / "p", ignore_errors=True)
            with tempfile.NamedTemporaryFile("r") as t:
                run(["/usr/bin/time", "-o", t.name, "-f", "%e %U %S %M", str(binary), "scenarios/biplanar.toml",
                     "--out", str(out / "p")])
                wall, user, system, rss = t.read().split()[-4:]
            files = [f for f in (out / "p").rglob("*") if f.is_file()]
            rounds.append((float(wall), float(user) + float(system), int(rss), sum(f.stat().st_size for f in files),
                           len(files)))
            log(f"round {r + 1}: {rounds[-1]}")
    finally:
        shutil.rmtree(out, ignore_errors=True)
    med = lambda v: sorted(v)[len(v) // 2]  # noqa: E731 (median of an odd count)
    wall, cpu = med([x[0] for x in rounds]), med([x[1] for x in rounds])
    rss_mb = max(x[2] for x in rounds) / 1024
    size, files = rounds[0][3], rounds[0][4]
    ok = lambda b: "yes" if b else "**no**"  # noqa: E731
    rows = ["| `scenarios/biplanar.toml`, 100 runs | measured | target | met |", "|---|---:|---|---|",
            f"| wall | {wall:.1f} s | ≤ 30 s | {ok(wall <= 30)} |",
            f"| CPU (user + system) | {cpu:.1f} s ({100 * cpu / wall:.0f} % of wall) | | |",
            f"| peak RSS | {rss_mb:.0f} MB | ≤ 500 MB | {ok(rss_mb <= 500)} |",
            f"| output | {size / 1e9:.2f} GB in {files:,} files | | |"]
    write(args, "protocol-full.md", f"bench/printed.py protocol --rounds {args.rounds}", "\n".join(rows), binary,
          load_start=start, note=f"medians over {args.rounds} runs of the whole protocol (peak RSS: the largest), "
                                 "output on tmpfs")


def cmd_shards(args):
    binary = stamp.release_binary()
    start = stamp.load()
    text = run(["bash", "bench/shards.sh"], env={"RSASIM": str(binary), "REPEATS": str(args.repeats)})
    pat = re.compile(r"^repeat (\d+): single ([\d.]+) s; (\d+) shards ([\d.]+) s \+ merge ([\d.]+) s = ([\d.]+) s "
                     r"\(([+-][\d.]+) %\); merged = single, byte for byte$")
    reps = [m.groups() for m in map(pat.match, text.splitlines()) if m]
    if len(reps) != args.repeats:
        sys.exit(f"bench/shards.sh printed {len(reps)} repeats, not {args.repeats}:\n{text[-3000:]}")
    count = reps[0][2]
    rows = [f"| repeat | one run | {count} shards, one after the other | merge | shards + merge | against one run |",
            "|---|---:|---:|---:|---:|---:|"]
    for i, single, _, shards, merge, total, pct in reps:
        rows.append(f"| {i} | {float(single):.2f} s | {float(shards):.2f} s | {float(merge):.2f} s | {float(total):.2f} s | {pct} % |")
    med = lambda k: sorted(float(r[k]) for r in reps)[len(reps) // 2]  # noqa: E731 (odd count)
    ms, msh, mm, mt = med(1), med(3), med(4), med(5)
    rows.append(f"| median | {ms:.2f} s | {msh:.2f} s ({100 * (msh / ms - 1):+.1f} %) | {mm:.2f} s | {mt:.2f} s | "
                f"**{100 * (mt / ms - 1):+.1f} %** (target ≤ +5 %: {'met' if mt / ms <= 1.05 else 'not met'}) |")
    write(args, "shards-merge.md", f"bench/printed.py shards --repeats {args.repeats}", "\n".join(rows), binary,
          load_start=start, note="`bench/shards.sh` on `scenarios/biplanar.toml`: the whole protocol as one run, "
                                 "then as 2 shards and `rsasim merge`, alternated; output in the temporary folder "
                                 "(on disk); the merged folder equals the single run byte for byte")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--tables", default=None, help="write the tables here (default docs/src/results/tables)")
    sub = ap.add_subparsers(dest="which", required=True)
    p = sub.add_parser("detection")
    p.add_argument("out")
    p.add_argument("file")
    for name in ("bead-centres", "sampling", "adaptive", "adaptive-crop", "detector-response", "first-run-cost"):
        sub.add_parser(name)
    for name in ("exr-encoders", "reconstruct-speed"):
        sub.add_parser(name).add_argument("out", nargs="?")
    p = sub.add_parser("fuzz")
    p.add_argument("n", nargs="?", default="20000")
    p.add_argument("--only", default=None)
    sub.add_parser("attenuation-speed").add_argument("--venv", default=None)
    sub.add_parser("binary-peers").add_argument("--venv", default=None)
    p = sub.add_parser("protocols")
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--baseline", default=None, help="an older rsasim binary, timed alternately")
    sub.add_parser("protocol").add_argument("--rounds", type=int, default=3)
    sub.add_parser("blurred-ladder").add_argument("--rounds", type=int, default=3)
    p = sub.add_parser("reconstruct-study")
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--baseline", default=None, help="an older rsasim binary, timed alternately")
    p.add_argument("--baseline-scenario", default=None,
                   help="the study's scenario as the baseline reads it (default: this one)")
    sub.add_parser("shards").add_argument("--repeats", type=int, default=3)
    sub.add_parser("missed-beads").add_argument("out", nargs="?")
    args = ap.parse_args()
    {
        "detection": cmd_detection, "bead-centres": cmd_bead_centres, "sampling": cmd_sampling,
        "adaptive": cmd_adaptive, "exr-encoders": cmd_exr_encoders,
        "detector-response": cmd_detector_response, "reconstruct-speed": cmd_reconstruct_speed,
        "fuzz": cmd_fuzz, "attenuation-speed": cmd_attenuation_speed, "first-run-cost": cmd_first_run,
        "protocols": cmd_protocols, "adaptive-crop": cmd_adaptive_crop, "protocol": cmd_protocol,
        "shards": cmd_shards, "reconstruct-study": cmd_reconstruct_study,
        "missed-beads": cmd_missed_beads, "blurred-ladder": cmd_blurred_ladder,
        "binary-peers": cmd_binary_peers,
    }[args.which](args)


if __name__ == "__main__":
    main()
