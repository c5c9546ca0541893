#!/usr/bin/env python3
"""Attenuation mode against its peers, on the scenes `examples/attenuation_bench.rs` exports
(DIR/attenuation.json). Driven by bench/attenuation.sh; see docs/src/results/peers.md.

Sub-commands:

  gvxr    DIR   gVirtualXray (PyPI `gvxr`), headless EGL: the same point source, detector and
                world-space surfaces (one gVXR mesh per material and displaced material: the six
                beads are one mesh), monochromatic scenes at their energy, the others with
                rsasim's spectrum as energy bins. Materials: the component scenes and
                `realistic_poly` as mass fractions (by Z) and density; `realistic_mono` as
                constant linear attenuation coefficients net of nesting (a part displacing
                another gets μ_part − μ_displaced, exact at one energy; rsasim adds the part's
                length to its material and takes it from the displaced one). Writes the
                transmission T = image / open-field image (f32) per scene and times
                computeXRayImage with and without Poisson noise.
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

from peers import gvxr_geometry, gvxr_time, machine, median_ms, pixel_rays, read_peer, write_json

# Scenes whose transmission is compared pixel by pixel; `realistic_poly` is timed only (with
# constant μ per mesh gVXR cannot net the nesting out over a spectrum, and with mixtures it
# counts the displaced material twice where parts nest).
SCENES = ("mono", "poly", "realistic_mono")
# Scenes given to gVXR as constant linear attenuation coefficients net of nesting.
NET_MU = ("realistic_mono",)
# Scenes whose image gVXR also renders from a finite focal spot (issue 12's speed peer; rsasim's
# counterpart is the scene `realistic_unsharp`): a 1.2 mm cube sampled by 3³ point sources
# (gVXR needs an odd count per axis; asked for 2 it warns and uses 3).
FOCAL_SPOT = ("realistic_mono",)
FOCAL_SPOT_SUBDIVISIONS = 3


def load(d):
    with open(Path(d) / "attenuation.json") as f:
        return json.load(f)


def raw(d, name, dtype, sc):
    import numpy as np

    w, h = sc["detector"]["pixels"]
    return np.fromfile(Path(d) / name, dtype=dtype).reshape(h, w)


def layers(d, sc):
    """rsasim's net path length per material in the beam, mm: shape (materials, h, w)."""
    import numpy as np

    w, h = sc["detector"]["pixels"]
    return np.fromfile(Path(d) / sc["lengths_f32"], dtype="<f4").reshape(-1, h, w).astype(np.float64)


def rsasim_transmission(sc, lengths, weighting):
    """T from rsasim's net path lengths per material (`layers`) with rsasim's μ and spectrum:
    photons per bin times detector efficiency, times the bin energy for `weighting == "energy"`."""
    import numpy as np

    mu = np.array([sc["mu_per_mm"][m] for m in sc["lengths_materials"]])  # (materials, bins)
    w = np.array(sc["spectrum_photons"]) * np.array(sc["efficiency"])
    if weighting == "energy":
        w = w * np.array(sc["energies_kev"])
    w = w / w.sum()
    t = np.zeros(lengths.shape[1:])
    for b, wb in enumerate(w):
        t += wb * np.exp(-np.tensordot(mu[:, b], lengths, axes=1))
    return t


def write_stl(path, tris):
    """Binary STL of triangles `tris` ((n, 3, 3) float32, mm); normals from the winding."""
    import numpy as np

    n = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
    rec = np.zeros(len(tris), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
    rec["n"], rec["v"] = n, tris
    with open(path, "wb") as f:
        f.write(b"rsasim bench: merged parts".ljust(80, b" "))
        f.write(np.uint32(len(tris)).tobytes())
        rec.tofile(f)


def gvxr_meshes(d, name, sc):
    """The scene's parts grouped into gVXR meshes: one per (material, displaced material), e.g.
    the six beads as one mesh. Returns [(label, stl path, material index, displaced material
    index or None, part labels)]; merged groups are written as DIR/NAME.gvxrK.stl."""
    import numpy as np

    groups = {}
    for p in sc["parts_exported"]:
        groups.setdefault((p["material"], p["parent_material"]), []).append(p)
    meshes = []
    for k, ((m, pm), ps) in enumerate(groups.items()):
        if len(ps) == 1:
            path = Path(d) / ps[0]["stl"]
        else:
            tris = np.concatenate([np.fromfile(Path(d) / p["tris_f32"], dtype="<f4").reshape(-1, 3, 3) for p in ps])
            path = Path(d) / f"{name}.gvxr{k}.stl"
            write_stl(path, tris)
        meshes.append((f"{name}_{k}", path, m, pm, [p["label"] for p in ps]))
    return meshes


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
    for name, sc in a["scenes"].items():
        if "parts_exported" not in sc:
            continue  # timed by rsasim only
        w, h = sc["detector"]["pixels"]
        gvxr.removePolygonMeshesFromSceneGraph()
        gvxr_geometry(gvxr, sc)
        mono = len(sc["energies_kev"]) == 1
        if mono:
            gvxr.setMonoChromatic(sc["energies_kev"][0], "keV", 1000)
        else:
            gvxr.resetBeamSpectrum()
            for e, n in zip(sc["energies_kev"], sc["spectrum_photons"]):
                gvxr.addEnergyBinToSpectrum(e, "keV", 1000 * n / sum(sc["spectrum_photons"]))
        meshes = gvxr_meshes(args.dir, name, sc)
        res = {"bins": len(sc["energies_kev"]), "meshes": [], "triangles": sum(p["triangles"] for p in sc["parts_exported"])}
        for label, path, m, pm, parts in meshes:
            gvxr.loadMeshFile(label, str(path), "mm")
            mat = sc["materials"][m]
            if name in NET_MU:
                mu = sc["mu_per_mm"][m][0] - (sc["mu_per_mm"][pm][0] if pm is not None else 0.0)
                gvxr.setLinearAttenuationCoefficient(label, 10.0 * mu, "cm-1")
                desc = f"μ = {mu:.6g} /mm ({mat['name']}" + (f" − {sc['materials'][pm]['name']})" if pm is not None else ")")
            else:
                zs = [int(z) for z, _ in mat["mass_fractions_z"]]
                ws = [float(x) for _, x in mat["mass_fractions_z"]]
                gvxr.setMixture(label, zs, ws)
                gvxr.setDensity(label, mat["density_g_cm3"], "g/cm3")
                desc = f"{mat['name']}: Z {zs}, w {ws}, {mat['density_g_cm3']} g/cm3"
            res["meshes"].append({"label": label, "parts": parts, "material": desc})
        image = np.zeros((h, w), dtype=np.single)
        for noise in (False, True):
            gvxr_time(gvxr, image, args.repeats, noise, res)
        if name in FOCAL_SPOT:
            # Issue 12's peer: the same image from a 1.2 mm focal spot, a cube gVXR samples by
            # FOCAL_SPOT_SUBDIVISIONS³ point sources, no noise; then back to the point source.
            spot = {}
            gvxr.setFocalSpot(*sc["source_mm"], 1.2, "mm", FOCAL_SPOT_SUBDIVISIONS)
            gvxr_time(gvxr, image, args.repeats, False, spot)
            res["focal_spot_sources"] = FOCAL_SPOT_SUBDIVISIONS**3
            res["focal_spot_ms"] = spot["xray_clean_ms"]
            res["focal_spot_runs_ms"] = spot["xray_clean_runs_ms"]
            gvxr.usePointSource()
            gvxr.setSourcePosition(*sc["source_mm"], "mm")
        gvxr.disablePoissonNoise()
        gvxr.computeXRayImage(image)
        clean = image.copy()
        # The open field: the same beam and detector with the meshes moved out of the beam.
        for label, *_ in meshes:
            gvxr.translateNode(label, 0.0, 1.0e5, 0.0, "mm")
        gvxr.computeXRayImage(image)
        open_field = image.copy()
        res["open_min"], res["open_max"] = float(open_field.min()), float(open_field.max())
        trans = (clean / np.where(open_field > 0, open_field, np.nan)).astype(np.float32)
        trans.tofile(Path(args.dir) / f"{name}.gvxr_T.f32")
        out["scenes"][name] = res
        if "focal_spot_ms" in res:
            print(f"gvxr {name}: focal spot of {res['focal_spot_sources']} sources {res['focal_spot_ms']:.1f} ms")
        print(
            f"gvxr {name}: computeXRayImage {res['xray_clean_ms']:.1f} ms, with Poisson noise "
            f"{res['xray_noise_ms']:.1f} ms ({res['bins']} bins, {len(meshes)} meshes, {res['triangles']} triangles); "
            f"open field {res['open_min']:.4g}..{res['open_max']:.4g}"
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
    out = {"peer": "Embree 4 via embreex " + version("embreex")}
    sc = a["scenes"].get("mono")
    if sc:
        origins, directions, w, h = pixel_rays(sc)
        tris = np.fromfile(Path(args.dir) / sc["parts_exported"][0]["tris_f32"], dtype="<f4").reshape(-1, 3, 3)
        es = rtcore_scene.EmbreeScene()
        mesh_construction.TriangleMesh(es, tris)
        t = time.perf_counter()
        lengths, odd = all_hits_lengths(es, origins, directions)
        ms = 1e3 * (time.perf_counter() - t)
        lengths.astype(np.float32).tofile(Path(args.dir) / "mono.embree_lengths.f32")
        out.update({"all_hits_ms": ms, "odd_rays": odd, "rays": int(len(origins))})
        print(f"embree: all hits along {len(origins)} rays in {ms:.0f} ms (Python loop included), {odd} rays with an odd hit count")
    # The realistic scene's soft-tissue cylinder, tessellated as gVXR gets it: every other part
    # nests in it, so its length is the sum of rsasim's net lengths over all materials. This
    # checks the tessellation (and rsasim's cylinder, caps included) where gVXR differs.
    sc = a["scenes"].get("realistic_mono")
    if sc:
        outer = [p for p in sc["parts_exported"] if p["parent"] is None]
        if len(outer) == 1:
            origins, directions, w, h = pixel_rays(sc)
            tris = np.fromfile(Path(args.dir) / outer[0]["tris_f32"], dtype="<f4").reshape(-1, 3, 3)
            es = rtcore_scene.EmbreeScene()
            mesh_construction.TriangleMesh(es, tris)
            lengths, odd = all_hits_lengths(es, origins, directions)
            lengths.astype(np.float32).tofile(Path(args.dir) / "realistic_mono.embree_outer_lengths.f32")
            out["realistic_mono_outer"] = {"part": outer[0]["label"], "odd_rays": odd}
            print(f"embree: realistic_mono's {outer[0]['label']} ({len(tris)} triangles), {odd} rays with an odd hit count")
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
    gv, emb = read_peer(d, "gvxr_attenuation"), read_peer(d, "embree_attenuation")
    res = {"machine": machine(), "rsasim_version": a["rsasim_version"], "transmission": {}, "lengths": None}
    lines = [f"Machine: {machine()}", ""]
    fmt = lambda s, k, pct=True: "n/a" if s.get("n", 0) == 0 else (f"{100 * s[k]:.3g} %" if pct else f"{s[k]:.3g}")  # noqa: E731

    # 1. Transmission, per pixel.
    lines += [
        "| scene | region | pixels | median rel. diff. | p95 | max |",
        "|---|---|---|---|---|---|",
    ]
    for name in SCENES:
        if name not in a["scenes"]:
            continue
        sc = a["scenes"][name]
        Ls = layers(d, sc)
        # Regions: the shadow of any part; its edge is the edge of any material's shadow (so
        # the outlines of the component, the bones and the beads inside the soft tissue count
        # as edge too).
        masks = Ls != 0
        shadow = masks.any(axis=0)
        edge = np.zeros_like(shadow)
        for m in masks:
            edge |= edges(m)
        inside = shadow & ~edge
        L = Ls[0]
        # rsasim's own image against its float model (photon counting: what the image holds).
        img = raw(d, sc["image_u16"], "<u2", sc).astype(np.float64)
        opn = raw(d, sc["open_u16"], "<u2", sc).astype(np.float64)
        t_img = img / np.where(opn > 0, opn, np.nan)
        t_pc = rsasim_transmission(sc, Ls, "photons")
        t_e = rsasim_transmission(sc, Ls, "energy")
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
            regions = [("inside", inside), ("edge", edge), ("open", ~shadow & ~edge)]
            if len(Ls) > 1:
                # The inside by the densest material each ray crosses.
                dens = np.array([sc["materials"][m]["density_g_cm3"] for m in sc["lengths_materials"]])
                densest = np.where(masks, dens[:, None, None], -1.0).argmax(axis=0)
                for k in np.argsort(-dens):
                    regions.append((f"inside, densest {sc['materials'][sc['lengths_materials'][k]]['name']}", inside & (densest == k)))
            for region, m in regions:
                if region.startswith("inside, ") and not m.any():
                    continue
                r[region] = stats(rel[m])
                s = r[region]
                lines.append(
                    f"| {name} | {region} | {s.get('n', 0)} | {fmt(s, 'median')} | {fmt(s, 'p95')} | {fmt(s, 'max')} |"
                )
            if name == "mono":
                # (one material: L is the component's path length)
                # Effective gVXR path length with rsasim's μ: ΔL = a + b·L (a: offset, mm; b: μ ratio − 1).
                mu = sc["mu_per_mm"][sc["lengths_materials"][0]][0]
                m = inside & (tg > 1e-30)
                lg = -np.log(tg[m]) / mu
                A = np.vstack([np.ones(m.sum()), L[m]]).T
                (off, slope), *_ = np.linalg.lstsq(A, lg - L[m], rcond=None)
                r["path_fit"] = {"offset_mm": float(off), "mu_ratio_minus_1": float(slope), "mu_rsasim_per_mm": mu}
                r["path_diff_mm"] = stats(lg - L[m])
                r["path_diff_median_signed_mm"] = float(np.median(lg - L[m]))
            if len(Ls) > 1:
                # Where only the outermost material is crossed: gVXR's path length minus rsasim's
                # (rsasim's μ), and the pixel where it is largest.
                k = int(np.argmin(dens))
                only = inside & masks[k] & (masks.sum(axis=0) == 1)
                mu = sc["mu_per_mm"][sc["lengths_materials"][k]][0]
                dl = np.where(only, -np.log(np.where(only, tg / t_e, 1.0)) / mu, 0.0)
                j = np.unravel_index(np.argmax(np.abs(dl)), dl.shape)
                r["outer_only_path_diff_mm"] = {
                    "pixels": int(only.sum()),
                    "median": float(np.median(dl[only])),
                    "max_abs": float(abs(dl[j])),
                    "at_row_col": [int(j[0]), int(j[1])],
                    "rsasim_length_mm": float(Ls[k][j]),
                }
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
        if "outer_only_path_diff_mm" in t:
            o = t["outer_only_path_diff_mm"]
            lines.append(
                f"- {name}, pixels crossing the outermost material only ({o['pixels']}): gVXR's path length minus rsasim's, "
                f"median {o['median']:+.4f} mm, largest {o['max_abs']:.3f} mm at row {o['at_row_col'][0]}, column "
                f"{o['at_row_col'][1]} (rsasim {o['rsasim_length_mm']:.2f} mm)."
            )
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

    epath = d / "realistic_mono.embree_outer_lengths.f32"
    if epath.exists() and "realistic_mono" in a["scenes"]:
        sc = a["scenes"]["realistic_mono"]
        L = layers(d, sc).sum(axis=0)
        E = raw(d, epath.name, "<f4", sc).astype(np.float64)
        shadow = (L > 0) | (E > 0)
        inside = shadow & ~edges(shadow)
        ab = stats(L[inside] - E[inside])
        res["outer_lengths"] = {"abs_mm": ab, "hit_disagree_px": int(((L > 0) != (E > 0)).sum())}
        lines.append(
            f"- realistic_mono, the soft-tissue cylinder (sum of rsasim's net lengths) vs Embree on its tessellation, "
            f"inside: median {fmt(ab, 'median', False)} mm, p95 {fmt(ab, 'p95', False)} mm, max {fmt(ab, 'max', False)} mm; "
            f"hit masks differ in {res['outer_lengths']['hit_disagree_px']} px."
        )

    # 3. Timing.
    sc = a["scenes"]
    lines += ["", "| image (1440²) | rsasim `attenuation::render` | gVXR computeXRayImage | ratio ours/peer |", "|---|---|---|---|"]
    tm = []
    rows = []
    for key, what in (("mono", "femoral component"), ("poly", "femoral component"), ("realistic_mono", "femur + bone + soft tissue + beads"), ("realistic_poly", "femur + bone + soft tissue + beads")):
        if key in sc:
            spec = "60 keV" if sc[key]["bins"] == 1 else f"{sc[key]['bins']} bins"
            rows.append((f"{what}, {spec}", sc[key]["render_ms"], (key, "xray_clean_ms")))
            noisy = sc[key].get("render_1000_photons_ms", sc[key]["render_ms"])
            rows.append((f"{what}, {spec}, with noise (1000 photons/px)", noisy, (key, "xray_noise_ms")))
    if "realistic_unsharp" in sc:
        rows.append((
            "femur + bone + soft tissue + beads, 60 keV, 2×2 rays per pixel, 3×3-sampled 1.2 mm focal spot, "
            "detector PSF, noise (10⁴ photons/px); gVXR: its 3³-sampled 1.2 mm focal spot, no noise",
            sc["realistic_unsharp"]["render_ms"],
            ("realistic_mono", "focal_spot_ms"),
        ))
    if "realistic" in sc:
        rows.append((f"biplanar_realistic as shipped (CsI, 10 mAs), {sc['realistic']['bins']} bins, with noise", sc["realistic"]["render_ms"], None))
    for label, ours, gkey in rows:
        g = gv["scenes"].get(gkey[0], {}).get(gkey[1]) if gv and gkey else None
        ratio = f"{ours / g:.3f}" if g else "—"
        tm.append({"what": label, "ours_ms": ours, "gvxr_ms": g})
        lines.append(f"| {label} | {ours:.1f} ms | {'—' if g is None else f'{g:.1f} ms'} | {ratio} |")
    lines.append(
        f"- rsasim: median of {a['repeats']} on {next(iter(sc.values()))['threads']} threads; rows without noise: "
        f"rsasim's expected image (the scene's `quantum_noise = false`) against gVXR's image without noise; "
        f"rows with noise: both draw Poisson noise at 1000 photons per pixel; the focal-spot row: rsasim with noise at 10⁴ photons "
        f"per pixel, gVXR without; gVXR: {gv['peer'] + ', ' + gv['renderer'] if gv else 'not measured'}."
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
