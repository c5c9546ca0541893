#!/usr/bin/env python3
"""Peers of rsasim's projector, measured on the scenes that `examples/bench_scene.rs` exports.

Sub-commands (each writes SCENE_DIR/<name>.json and prints what it measured):

  embree  SCENE_DIR   Embree 4 (PyPI `embreex`): the same rays (source -> every pixel centre,
                      tfar = 1 on the unnormalised direction, so only the segment) against the same
                      world-space triangles. Pinned to ONE core (sched_setaffinity before Embree
                      starts, so TBB sees one CPU). Times the scene build and the ray cast
                      separately; compares the hit mask with rsasim's pixel by pixel.
  gvxr    SCENE_DIR   gVirtualXray (PyPI `gvxr`), headless through EGL (Mesa llvmpipe where there
                      is no GPU): the same point source, detector frame and mesh (CoCrMo, 60 keV
                      monochromatic); times computeXRayImage() without and with Poisson noise.
  summary SCENE_DIR --criterion DIR [--protocol FILE] [--markdown FILE]
                      Ratios ours / peer from criterion's medians, the peers' JSON and the
                      protocol's wall time and peak RSS.

Timings are medians of --repeats runs (default 7) after one warm-up run.
"""

import argparse
import json
import os
import platform
import statistics
import sys
import time
from pathlib import Path


def load_scene(scene_dir):
    with open(Path(scene_dir) / "scene.json") as f:
        return json.load(f)


def pixel_rays(scene):
    """Origins (the source) and unnormalised directions (pixel centre - source), float32."""
    import numpy as np

    det = scene["detector"]
    w, h = det["pixels"]
    p00 = np.array(det["pixel00_centre_mm"], dtype=np.float64)
    su = np.array(det["step_u_mm"], dtype=np.float64)
    sv = np.array(det["step_v_mm"], dtype=np.float64)
    src = np.array(scene["source_mm"], dtype=np.float64)
    j, i = np.mgrid[0:h, 0:w]
    centres = p00 + i.reshape(-1, 1) * su + j.reshape(-1, 1) * sv
    directions = (centres - src).astype(np.float32)
    origins = np.broadcast_to(src.astype(np.float32), directions.shape).copy()
    return origins, np.ascontiguousarray(directions), w, h


def read_mask(scene_dir, name, w, h):
    import numpy as np

    return np.fromfile(Path(scene_dir) / name, dtype=np.uint8).reshape(h, w).astype(bool)


def read_peer(scene_dir, name):
    """The peer's `<name>.json` in `scene_dir`, or None when that peer did not run."""
    try:
        with open(Path(scene_dir) / f"{name}.json") as f:
            return json.load(f)
    except OSError:
        return None


def median_ms(samples):
    return 1e3 * statistics.median(samples)


def write_json(scene_dir, name, data):
    path = Path(scene_dir) / f"{name}.json"
    with open(path, "w") as f:
        json.dump(data, f, indent=2)
    print(f"wrote {path}")


def cmd_embree(args):
    # One core for everything Embree does: pin before the library (and TBB) start.
    os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    import numpy as np
    from embreex import mesh_construction, rtcore_scene

    from importlib.metadata import version

    scene = load_scene(args.scene_dir)
    origins, directions, w, h = pixel_rays(scene)
    dists = np.ones(len(origins), dtype=np.float32)
    out = {
        "peer": "Embree 4 via embreex " + version("embreex"),
        "cpus": sorted(os.sched_getaffinity(0)),
        "rays": int(len(origins)),
        "scenes": {},
    }
    for name, sc in scene["scenes"].items():
        tris = np.fromfile(Path(args.scene_dir) / sc["tris_f32"], dtype="<f4").reshape(-1, 3, 3)
        builds = []
        for _ in range(args.repeats):
            t = time.perf_counter()
            es = rtcore_scene.EmbreeScene()
            mesh_construction.TriangleMesh(es, tris)
            # embreex commits the scene on the first query: one ray commits it.
            es.run(origins[:1], directions[:1], dists=dists[:1], query="OCCLUDED")
            builds.append(time.perf_counter() - t)
        res = {"triangles": int(len(tris)), "build_ms": median_ms(builds)}
        for query in ("OCCLUDED", "INTERSECT"):
            es.run(origins, directions, dists=dists, query=query)  # warm-up
            times = []
            for _ in range(args.repeats):
                t = time.perf_counter()
                hits = es.run(origins, directions, dists=dists, query=query)
                times.append(time.perf_counter() - t)
            res[query.lower() + "_ms"] = median_ms(times)
            res[query.lower() + "_runs_ms"] = [1e3 * x for x in times]
        hit = (hits >= 0).reshape(h, w)
        res["hit_px"] = int(hit.sum())
        for which in ("binary", "traced"):
            ours = read_mask(args.scene_dir, sc["mask_" + which], w, h)
            res[f"disagree_px_vs_{which}"] = int((ours != hit).sum())
            res[f"ours_{which}_px"] = int(ours.sum())
        out["scenes"][name] = res
        print(
            f"embree {name}: build {res['build_ms']:.1f} ms, occluded {res['occluded_ms']:.1f} ms, "
            f"intersect {res['intersect_ms']:.1f} ms, {res['hit_px']} px hit, "
            f"{res['disagree_px_vs_binary']} / {res['disagree_px_vs_traced']} px differ from "
            "render_binary / render_binary_traced"
        )
    write_json(args.scene_dir, "embree", out)


def gvxr_geometry(gvxr, scene):
    """Point source and detector of `scene` (source_mm, detector as bench_scene writes them)."""
    import numpy as np

    det = scene["detector"]
    rot = np.array(det["rotation"])  # rows; columns are r, c, s
    gvxr.setSourcePosition(*scene["source_mm"], "mm")
    gvxr.usePointSource()
    gvxr.setDetectorPosition(*det["position_mm"], "mm")
    # gVXR needs right × up to point towards the source: right = r, up = c (r × c = s).
    # (With up = -c it renders nothing at all.) Its image then has our row order; the mask
    # checks try the flips anyway.
    gvxr.setDetectorUpVector(*rot[:, 1])
    gvxr.setDetectorRightVector(*rot[:, 0])
    gvxr.setDetectorNumberOfPixels(*det["pixels"])
    gvxr.setDetectorPixelSize(*det["pixel_pitch_mm"], "mm")


def gvxr_time(gvxr, image, repeats, noise, res):
    """Times computeXRayImage into `image` (median of `repeats` after a warm-up), with or
    without Poisson noise; stores xray_{clean,noise}_ms and _runs_ms in `res`."""
    if noise:
        gvxr.enablePoissonNoise()
        gvxr.setmAs(1.0)
    else:
        gvxr.disablePoissonNoise()
    gvxr.computeXRayImage(image)  # warm-up (shaders, buffers)
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        gvxr.computeXRayImage(image)
        times.append(time.perf_counter() - t)
    key = "noise" if noise else "clean"
    res[f"xray_{key}_ms"] = median_ms(times)
    res[f"xray_{key}_runs_ms"] = [1e3 * x for x in times]


def cmd_gvxr(args):
    import numpy as np
    from gvxrPython3 import gvxr

    from importlib.metadata import version

    scene = load_scene(args.scene_dir)
    det = scene["detector"]
    w, h = det["pixels"]
    out = {"peer": "gVirtualXray via gvxr " + version("gvxr"), "scenes": {}}

    t = time.perf_counter()
    gvxr.createOpenGLContext()
    out["context_ms"] = 1e3 * (time.perf_counter() - t)
    out["renderer"] = gvxr.getOpenGlRenderer()
    out["opengl"] = gvxr.getOpenGlVersion()
    out["LP_NUM_THREADS"] = os.environ.get("LP_NUM_THREADS", f"unset (llvmpipe: {os.cpu_count()} CPUs)")
    for name, sc in scene["scenes"].items():
        t = time.perf_counter()
        gvxr.removePolygonMeshesFromSceneGraph()
        gvxr_geometry(gvxr, scene)
        gvxr.setMonoChromatic(60, "keV", 1000)
        gvxr.loadMeshFile(name, str(Path(args.scene_dir) / sc["stl"]), "mm")
        # Atomic numbers: gvxr's setMixture with element symbols is "not yet implemented" and
        # leaves the mesh without a material (no attenuation at all).
        gvxr.setMixture(name, [27, 24, 42], [0.64, 0.29, 0.07])
        gvxr.setDensity(name, 8.3, "g/cm3")
        setup = time.perf_counter() - t
        image = np.zeros((h, w), dtype=np.single)
        res = {"setup_ms": 1e3 * setup, "material": "CoCrMo 64/29/7 wt%, 8.3 g/cm3", "energy": "60 keV mono"}
        for noise in (False, True):
            gvxr_time(gvxr, image, args.repeats, noise, res)
            if not noise:
                # Sanity check of the geometry: the shadow against rsasim's mask, allowing for a
                # flip of the image axes (gVXR's row order need not match ours).
                flat = float(np.max(image))
                shadow = image < 0.999 * flat
                ours = read_mask(args.scene_dir, sc["mask_binary"], w, h)
                best = min(
                    (int((ours != m).sum()), label)
                    for label, m in (
                        ("as is", shadow),
                        ("rows flipped", shadow[::-1, :]),
                        ("columns flipped", shadow[:, ::-1]),
                        ("both flipped", shadow[::-1, ::-1]),
                    )
                )
                res["shadow_px"] = int(shadow.sum())
                res["ours_px"] = int(ours.sum())
                res["disagree_px"], res["orientation"] = best
        gvxr.disablePoissonNoise()
        out["scenes"][name] = res
        print(
            f"gvxr {name}: setup {res['setup_ms']:.0f} ms, computeXRayImage {res['xray_clean_ms']:.1f} ms "
            f"(with Poisson noise {res['xray_noise_ms']:.1f} ms); shadow {res['shadow_px']} px vs ours "
            f"{res['ours_px']} px, {res['disagree_px']} px differ ({res['orientation']})"
        )
    try:
        gvxr.destroy()
    except Exception:  # noqa: BLE001 - teardown only
        pass
    write_json(args.scene_dir, "gvxr", out)


def criterion_median_ms(root, bench_id):
    path = Path(root) / bench_id / "new" / "estimates.json"
    try:
        with open(path) as f:
            return json.load(f)["median"]["point_estimate"] / 1e6
    except (OSError, KeyError, ValueError):
        return None


def machine():
    model, mem = "?", "?"
    try:
        with open("/proc/cpuinfo") as f:
            model = next(l.split(":", 1)[1].strip() for l in f if l.startswith("model name"))
        with open("/proc/meminfo") as f:
            kb = int(next(l.split()[1] for l in f if l.startswith("MemTotal")))
            mem = f"{kb / 2**20:.1f} GiB"
    except (OSError, StopIteration):
        pass
    return f"{model}, {os.cpu_count()} logical CPUs, {mem} RAM, {platform.system()} {platform.release()}"


def cmd_summary(args):
    d = Path(args.scene_dir)
    embree, gv = read_peer(d, "embree"), read_peer(d, "gvxr")
    protocol = None
    if args.protocol:
        try:
            with open(args.protocol) as f:
                protocol = json.load(f)
        except OSError:
            pass
    ours = lambda b: criterion_median_ms(args.criterion, b)  # noqa: E731
    emb = lambda s, k="occluded_ms": embree and embree["scenes"].get(s, {}).get(k)  # noqa: E731
    gvx = lambda s, k="xray_noise_ms": gv and gv["scenes"].get(s, {}).get(k)  # noqa: E731

    rows = []  # (what, ours, peer, peer value, target ratio (ours/peer) or None, note)

    def row(what, o, p, pv, target, fmt="ms"):
        ratio = o / pv if o is not None and pv else None
        if target is None:
            met = ""
        elif ratio is None:
            met = "n/a"
        else:
            met = "yes" if ratio <= target else "no"
        rows.append((what, o, p, pv, ratio, target, met))

    for scene, label in (("femur", "model"), ("sphere", "sphere")):
        pre = "mesh_" if scene == "femur" else ""
        desc = "femoral component (87k tri)" if scene == "femur" else "sphere (80k tri, ~20 %)"
        row(f"{desc}: render_binary, 1 core", ours(f"{label}/{pre}binary_1t"), "Embree rtcOccluded1, 1 core", emb(scene), 1.0)
        row(f"{desc}: render_binary_traced, 1 core", ours(f"{label}/{pre}traced_1t"), "Embree rtcOccluded1, 1 core", emb(scene), None)
        row(f"{desc}: trace + noise, all cores", ours(f"{label}/binary_noise"), "gVXR computeXRayImage + Poisson", gvx(scene), 1 / 20)
        row(f"{desc}: trace + noise, all cores", ours(f"{label}/binary_noise"), "gVXR computeXRayImage (no noise)", gvx(scene, "xray_clean_ms"), None)
    row("calibration (256 beads): render_binary, 1 core", ours("calibration/binary_1t"), "", None, None)
    row("calibration: trace + noise, all cores", ours("calibration/binary_noise"), "", None, None)
    row("noise alone (1440², level 0.45), 1 core", ours("noise/1t"), "", None, None)
    row("noise alone (1440², level 0.45), all cores", ours("noise/all"), "", None, None)

    fmt = lambda v, unit="ms": "n/a" if v is None else f"{v:.2f} {unit}" if v < 10 else f"{v:.1f} {unit}"  # noqa: E731
    lines = [
        f"Machine: {machine()}",
        "",
        "| what | ours | peer | peer time | ratio ours/peer | target | met |",
        "|---|---|---|---|---|---|---|",
    ]
    for what, o, p, pv, ratio, target, met in rows:
        if target is None:
            tgt = ""
        elif target < 1:
            tgt = f"≤ {target:g} (≥ {1 / target:g}× faster)"
        else:
            tgt = f"≤ {target:g}"
        lines.append(
            f"| {what} | {fmt(o)} | {p or '—'} | {fmt(pv) if p else '—'} | "
            f"{'—' if ratio is None else f'{ratio:.3f}'} | {tgt} | {met} |"
        )
    if protocol:
        wall, rss = protocol.get("wall_s"), protocol.get("peak_rss_kb")
        ok = wall is not None and rss is not None and wall <= 30 and rss / 1024 <= 500
        lines.append(
            f"| full biplanar.toml protocol (400 images, TIFF + EXR) | {wall} s wall, "
            f"{rss / 1024:.0f} MB peak RSS | — | — | — | ≤ 30 s, ≤ 500 MB | {'yes' if ok else 'no'} |"
        )
    lines.append("")
    if embree:
        for s, r in embree["scenes"].items():
            lines.append(
                f"- Embree {s}: {embree['peer']}, CPUs {embree['cpus']}, {embree['rays']} rays; "
                f"scene build {r['build_ms']:.1f} ms; rtcIntersect1 {r['intersect_ms']:.1f} ms; "
                f"hit mask differs from render_binary in {r['disagree_px_vs_binary']} px and from "
                f"render_binary_traced in {r['disagree_px_vs_traced']} px (of {r['hit_px']} hit)."
            )
    else:
        lines.append("- Embree: not measured (see the messages above).")
    if gv:
        for s, r in gv["scenes"].items():
            lines.append(
                f"- gVXR {s}: {gv['peer']}, {gv['renderer']}, threads {gv['LP_NUM_THREADS']}; setup "
                f"{r['setup_ms']:.0f} ms (+ context {gv['context_ms']:.0f} ms); computeXRayImage "
                f"{r['xray_clean_ms']:.1f} ms, with Poisson noise {r['xray_noise_ms']:.1f} ms; shadow "
                f"{r['shadow_px']} px vs ours {r['ours_px']} px ({r['disagree_px']} px differ, {r['orientation']})."
            )
    else:
        lines.append("- gVXR: not measured (see the messages above).")
    text = "\n".join(lines)
    print(text)
    if args.markdown:
        Path(args.markdown).write_text(text + "\n")
    write_json(args.scene_dir, "summary", {"rows": rows, "protocol": protocol, "machine": machine()})


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    for name in ("embree", "gvxr", "summary"):
        p = sub.add_parser(name)
        p.add_argument("scene_dir")
        p.add_argument("--repeats", type=int, default=7)
        if name == "summary":
            p.add_argument("--criterion", required=True, help="criterion's output folder (target/criterion)")
            p.add_argument("--protocol", help="JSON with wall_s and peak_rss_kb of the full protocol")
            p.add_argument("--markdown", help="also write the table to this file")
    args = ap.parse_args()
    {"embree": cmd_embree, "gvxr": cmd_gvxr, "summary": cmd_summary}[args.cmd](args)


if __name__ == "__main__":
    sys.exit(main())
