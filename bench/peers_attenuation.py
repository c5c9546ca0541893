#!/usr/bin/env python3
"""Attenuation mode against its peers, on the scenes `examples/attenuation_bench.rs` exports
(DIR/attenuation.json). Driven by bench/attenuation.sh; see BENCHMARKS.md, "Attenuation mode".

Sub-commands:

  gvxr    DIR   gVirtualXray (PyPI `gvxr`), headless EGL: the same point source, detector and
                world-space mesh, the component's material as its mass fractions (by Z) and
                density; `mono` at 60 keV and `poly` with rsasim's spectrum as energy bins. Writes
                the transmission T = image / open-field image (f32) per scene and times
                computeXRayImage: mono, mono + Poisson noise, poly, poly + Poisson noise.
  embree  DIR   Embree 4 (PyPI `embreex`), one core: every hit along every pixel ray (repeated
                rtcIntersect1 from just past the last hit), sorted hits paired entry/exit and
                summed: the path length in the mesh per pixel (f32), timed.
  summary DIR [--markdown FILE]
                Per-pixel comparisons (rsasim vs gVXR transmission, rsasim vs Embree path
                length; inside the shadow, at its edge) and the timing table ours / peer.

Timings are medians of --repeats runs (default 5) after one warm-up run.
"""

import argparse
import json
import os
import sys
import time
from pathlib import Path

from peers import gvxr_geometry, gvxr_time, machine, median_ms, pixel_rays, write_json

SCENES = ("mono", "poly")


def load(d):
    with open(Path(d) / "attenuation.json") as f:
        return json.load(f)


def raw(d, name, dtype, sc):
    import numpy as np

    w, h = sc["detector"]["pixels"]
    return np.fromfile(Path(d) / name, dtype=dtype).reshape(h, w)


def rsasim_transmission(sc, lengths, weighting):
    """T from rsasim's path lengths with rsasim's μ and spectrum: photons per bin times detector
    efficiency, times the bin energy for `weighting == "energy"`."""
    import numpy as np

    mu = np.array(sc["mu_per_mm"][sc["material_index"]])
    w = np.array(sc["spectrum_photons"]) * np.array(sc["efficiency"])
    if weighting == "energy":
        w = w * np.array(sc["energies_kev"])
    w = w / w.sum()
    t = np.zeros(lengths.shape)
    for mb, wb in zip(mu, w):
        t += wb * np.exp(-mb * lengths.astype(np.float64))
    return t


def cmd_gvxr(args):
    import numpy as np
    from gvxrPython3 import gvxr

    from importlib.metadata import version

    a = load(args.dir)
    out = {"peer": "gVirtualXray via gvxr " + version("gvxr"), "scenes": {}}
    t = time.perf_counter()
    gvxr.createOpenGLContext()
    out["context_ms"] = 1e3 * (time.perf_counter() - t)
    out["renderer"] = gvxr.getOpenGlRenderer()
    out["LP_NUM_THREADS"] = os.environ.get("LP_NUM_THREADS", f"unset (llvmpipe: {os.cpu_count()} CPUs)")
    for name in SCENES:
        sc = a["scenes"][name]
        w, h = sc["detector"]["pixels"]
        mat = sc["materials"][sc["material_index"]]
        gvxr.removePolygonMeshesFromSceneGraph()
        gvxr_geometry(gvxr, sc)
        if name == "mono":
            gvxr.setMonoChromatic(sc["energies_kev"][0], "keV", 1000)
        else:
            gvxr.resetBeamSpectrum()
            for e, n in zip(sc["energies_kev"], sc["spectrum_photons"]):
                gvxr.addEnergyBinToSpectrum(e, "keV", 1000 * n / sum(sc["spectrum_photons"]))
        gvxr.loadMeshFile(name, str(Path(args.dir) / sc["stl"]), "mm")
        zs = [int(z) for z, _ in mat["mass_fractions_z"]]
        ws = [float(x) for _, x in mat["mass_fractions_z"]]
        gvxr.setMixture(name, zs, ws)
        gvxr.setDensity(name, mat["density_g_cm3"], "g/cm3")
        image = np.zeros((h, w), dtype=np.single)
        res = {"bins": len(sc["energies_kev"]), "material": f"{mat['name']}: Z {zs}, w {ws}, {mat['density_g_cm3']} g/cm3"}
        for noise in (False, True):
            gvxr_time(gvxr, image, args.repeats, noise, res)
        gvxr.disablePoissonNoise()
        gvxr.computeXRayImage(image)
        clean = image.copy()
        # The open field: the same beam and detector with the mesh moved out of the beam.
        gvxr.translateNode(name, 0.0, 1.0e5, 0.0, "mm")
        gvxr.computeXRayImage(image)
        open_field = image.copy()
        res["open_min"], res["open_max"] = float(open_field.min()), float(open_field.max())
        white = np.array(gvxr.getWhiteImage(), dtype=np.float64)
        res["white_image_range"] = [float(white.min()), float(white.max())] if white.size else None
        trans = (clean / np.where(open_field > 0, open_field, np.nan)).astype(np.float32)
        trans.tofile(Path(args.dir) / f"{name}.gvxr_T.f32")
        out["scenes"][name] = res
        print(
            f"gvxr {name}: computeXRayImage {res['xray_clean_ms']:.1f} ms, with Poisson noise "
            f"{res['xray_noise_ms']:.1f} ms ({res['bins']} bins); open field {res['open_min']:.4g}..{res['open_max']:.4g}"
        )
    try:
        gvxr.destroy()
    except Exception:  # noqa: BLE001 - teardown only
        pass
    write_json(args.dir, "gvxr_attenuation", out)


def all_hits_lengths(es, origins, directions, max_hits=64):
    """Path length in the mesh per ray (mm): every hit along the segment, paired in order.
    Returns (lengths, rays with an odd number of hits)."""
    import numpy as np

    n = len(origins)
    norm = np.linalg.norm(directions.astype(np.float64), axis=1)
    eps_t = 1e-3 / norm  # step 1 µm past a hit
    t_done = np.zeros(n)
    hits = [[] for _ in range(n)]
    active = np.arange(n)
    for _ in range(max_hits):
        if active.size == 0:
            break
        o = (origins[active] + (t_done[active, None] * directions[active])).astype(np.float32)
        d = np.ascontiguousarray(directions[active])
        dists = (1.0 - t_done[active]).astype(np.float32)
        r = es.run(o, d, dists=dists, query="INTERSECT", output=1)
        hit = r["primID"] >= 0
        t_hit = t_done[active] + r["tfar"].astype(np.float64)
        for k in np.nonzero(hit)[0]:
            hits[active[k]].append(t_hit[k])
        t_done[active[hit]] = t_hit[hit] + eps_t[active[hit]]
        active = active[hit]
    lengths = np.zeros(n)
    odd = 0
    for i in np.nonzero([len(x) > 0 for x in hits])[0]:
        ts = sorted(hits[i])
        if len(ts) % 2:
            odd += 1
            ts = ts[:-1]
        lengths[i] = norm[i] * sum(ts[k + 1] - ts[k] for k in range(0, len(ts), 2))
    return lengths, odd


def cmd_embree(args):
    os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    import numpy as np
    from embreex import mesh_construction, rtcore_scene

    from importlib.metadata import version

    a = load(args.dir)
    sc = a["scenes"]["mono"]
    origins, directions, w, h = pixel_rays(sc)
    tris = np.fromfile(Path(args.dir) / sc["tris_f32"], dtype="<f4").reshape(-1, 3, 3)
    es = rtcore_scene.EmbreeScene()
    mesh_construction.TriangleMesh(es, tris)
    t = time.perf_counter()
    lengths, odd = all_hits_lengths(es, origins, directions)
    ms = 1e3 * (time.perf_counter() - t)
    lengths.astype(np.float32).tofile(Path(args.dir) / "mono.embree_lengths.f32")
    out = {"peer": "Embree 4 via embreex " + version("embreex"), "all_hits_ms": ms, "odd_rays": odd, "rays": int(len(origins))}
    print(f"embree: all hits along {len(origins)} rays in {ms:.0f} ms (Python loop included), {odd} rays with an odd hit count")
    write_json(args.dir, "embree_attenuation", out)


def edges(mask):
    """Pixels of `mask` or next to it (8-neighbourhood) whose neighbourhood is not uniform."""
    import numpy as np

    m = np.pad(mask, 1, mode="edge")
    h, w = mask.shape
    any_in = np.zeros_like(mask)
    all_in = np.ones_like(mask)
    for dj in (0, 1, 2):
        for di in (0, 1, 2):
            s = m[dj : dj + h, di : di + w]
            any_in |= s
            all_in &= s
    return any_in & ~all_in


def stats(x):
    import numpy as np

    x = np.abs(x[np.isfinite(x)])
    if x.size == 0:
        return {"n": 0}
    return {"n": int(x.size), "median": float(np.median(x)), "p95": float(np.percentile(x, 95)), "max": float(x.max())}


def cmd_summary(args):
    import numpy as np

    d = Path(args.dir)
    a = load(d)

    def peer(name):
        try:
            with open(d / f"{name}.json") as f:
                return json.load(f)
        except OSError:
            return None

    gv, emb = peer("gvxr_attenuation"), peer("embree_attenuation")
    res = {"machine": machine(), "rsasim_version": a["rsasim_version"], "transmission": {}, "lengths": None}
    lines = [f"Machine: {machine()}", ""]
    fmt = lambda s, k, pct=True: "n/a" if s.get("n", 0) == 0 else (f"{100 * s[k]:.3g} %" if pct else f"{s[k]:.3g}")  # noqa: E731

    # 1. Transmission, per pixel.
    lines += [
        "| scene | region | pixels | median rel. diff. | p95 | max |",
        "|---|---|---|---|---|---|",
    ]
    for name in SCENES:
        sc = a["scenes"][name]
        L = raw(d, sc["lengths_f32"], "<f4", sc).astype(np.float64)
        shadow = L > 0
        edge = edges(shadow)
        inside = shadow & ~edge
        # rsasim's own image against its float model (photon counting: what the image holds).
        img = raw(d, sc["image_u16"], "<u2", sc).astype(np.float64)
        opn = raw(d, sc["open_u16"], "<u2", sc).astype(np.float64)
        t_img = img / np.where(opn > 0, opn, np.nan)
        t_pc = rsasim_transmission(sc, L, "photons")
        t_e = rsasim_transmission(sc, L, "energy")
        ok = inside & (t_pc > 0.02)
        r = {"image_vs_model_inside_T_gt_0.02": stats(t_img[ok] / t_pc[ok] - 1)}
        gpath = d / f"{name}.gvxr_T.f32"
        if gpath.exists():
            tg = raw(d, gpath.name, "<f4", sc).astype(np.float64)
            # gVXR integrates energy; compare with rsasim's energy-weighted T (same as photon
            # weighting for mono).
            rel = tg / t_e - 1
            gshadow = tg < 0.999
            r["gvxr_shadow_px"], r["ours_shadow_px"] = int(gshadow.sum()), int(shadow.sum())
            r["shadow_disagree_px"] = int((gshadow != shadow).sum())
            for region, m in (("inside", inside), ("edge", edge), ("open", ~shadow & ~edge)):
                r[region] = stats(rel[m])
                s = r[region]
                lines.append(
                    f"| {name} | {region} | {s.get('n', 0)} | {fmt(s, 'median')} | {fmt(s, 'p95')} | {fmt(s, 'max')} |"
                )
            if name == "mono":
                # Effective gVXR path length with rsasim's μ: ΔL = a + b·L (a: offset, mm; b: μ ratio − 1).
                mu = sc["mu_per_mm"][sc["material_index"]][0]
                m = inside & (tg > 1e-30)
                lg = -np.log(tg[m]) / mu
                A = np.vstack([np.ones(m.sum()), L[m]]).T
                (off, slope), *_ = np.linalg.lstsq(A, lg - L[m], rcond=None)
                r["path_fit"] = {"offset_mm": float(off), "mu_ratio_minus_1": float(slope), "mu_rsasim_per_mm": mu}
                r["path_diff_mm"] = stats(lg - L[m])
                r["path_diff_median_signed_mm"] = float(np.median(lg - L[m]))
        res["transmission"][name] = r
    lines.append("")
    m = res["transmission"].get("mono", {})
    if "path_fit" in m:
        f = m["path_fit"]
        lines.append(
            f"- mono, gVXR's path length from its T with rsasim's μ ({f['mu_rsasim_per_mm']:.4g} /mm), minus rsasim's: "
            f"median {m['path_diff_median_signed_mm']:+.3f} mm; fit ΔL = {f['offset_mm']:+.3f} mm + {f['mu_ratio_minus_1']:+.4f}·L."
        )
    for name in SCENES:
        t = res["transmission"].get(name, {})
        if "gvxr_shadow_px" in t:
            lines.append(
                f"- {name}: shadow (T < 0.999) gVXR {t['gvxr_shadow_px']} px, rsasim (L > 0) {t['ours_shadow_px']} px, "
                f"{t['shadow_disagree_px']} px differ; rsasim's u16 image / open field vs its float model inside "
                f"(T > 0.02): median {fmt(t['image_vs_model_inside_T_gt_0.02'], 'median')}, "
                f"max {fmt(t['image_vs_model_inside_T_gt_0.02'], 'max')}."
            )

    # 2. Path lengths against Embree.
    epath = d / "mono.embree_lengths.f32"
    if epath.exists():
        sc = a["scenes"]["mono"]
        L = raw(d, sc["lengths_f32"], "<f4", sc).astype(np.float64)
        E = raw(d, epath.name, "<f4", sc).astype(np.float64)
        shadow = (L > 0) | (E > 0)
        edge = edges(shadow)
        inside = shadow & ~edge
        lr = {}
        lines += ["", "| path length vs Embree | pixels | median abs. | p95 abs. | max abs. | median rel. | p95 rel. |", "|---|---|---|---|---|---|---|"]
        for region, m in (("inside", inside), ("edge", edge)):
            ab, rl = stats(L[m] - E[m]), stats((L[m] - E[m]) / np.maximum(E[m], 1e-9))
            lr[region] = {"abs_mm": ab, "rel": rl}
            lines.append(
                f"| {region} | {ab.get('n', 0)} | {fmt(ab, 'median', False)} mm | {fmt(ab, 'p95', False)} mm | "
                f"{fmt(ab, 'max', False)} mm | {fmt(rl, 'median')} | {fmt(rl, 'p95')} |"
            )
        lr["hit_disagree_px"] = int(((L > 0) != (E > 0)).sum())
        lr["odd_rays"] = emb["odd_rays"] if emb else None
        res["lengths"] = lr
        lines.append(f"- hit masks differ in {lr['hit_disagree_px']} px; Embree rays with an odd hit count: {lr['odd_rays']}.")

    # 3. Timing.
    sc = a["scenes"]
    lines += ["", "| image (1440²) | rsasim `attenuation::render` | gVXR computeXRayImage | ratio ours/peer |", "|---|---|---|---|"]
    tm = []
    for label, ours, gkey in (
        ("femoral component, 60 keV", sc["mono"]["render_ms"], ("mono", "xray_clean_ms")),
        ("femoral component, 60 keV, with noise", sc["mono"]["render_ms"], ("mono", "xray_noise_ms")),
        (f"femoral component, {sc['poly']['bins']} bins", sc["poly"]["render_ms"], ("poly", "xray_clean_ms")),
        (f"femoral component, {sc['poly']['bins']} bins, with noise", sc["poly"]["render_ms"], ("poly", "xray_noise_ms")),
        (f"femur + bone + soft tissue + beads, {sc['realistic']['bins']} bins, with noise", sc["realistic"]["render_ms"], None),
    ):
        g = gv["scenes"][gkey[0]][gkey[1]] if gv and gkey else None
        ratio = f"{ours / g:.3f}" if g else "—"
        tm.append({"what": label, "ours_ms": ours, "gvxr_ms": g})
        lines.append(f"| {label} | {ours:.1f} ms | {'—' if g is None else f'{g:.1f} ms'} | {ratio} |")
    lines.append(
        f"- rsasim: median of {a['repeats']} on {sc['mono']['threads']} threads, noise always included "
        f"(quantum noise is part of `attenuation::render`); gVXR: {gv['peer'] + ', ' + gv['renderer'] if gv else 'not measured'}."
    )
    res["timing"] = tm
    text = "\n".join(lines)
    print(text)
    if args.markdown:
        Path(args.markdown).write_text(text + "\n")
    write_json(d, "summary_attenuation", res)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    for name in ("gvxr", "embree", "summary"):
        p = sub.add_parser(name)
        p.add_argument("dir")
        p.add_argument("--repeats", type=int, default=5)
        if name == "summary":
            p.add_argument("--markdown", help="also write the tables to this file")
    args = ap.parse_args()
    {"gvxr": cmd_gvxr, "embree": cmd_embree, "summary": cmd_summary}[args.cmd](args)


if __name__ == "__main__":
    sys.exit(main())
