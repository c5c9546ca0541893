#!/usr/bin/env python3
"""Regenerate the shipped X-ray spectrum tables of rsasim (data/spectra/).

Tools (the shipped files were made with exactly these):
    Python 3.11.7, spekpy 2.5.4 (physics "spekpy-v2-casim", mu data "pene", its defaults),
    numpy 2.4.6.
Install:  pip install spekpy==2.5.4 numpy==2.4.6
Run:      python3 data/spectra/regen.py        (15 minutes on an idle core, 50 on a busy one)

Writes, beside this script:
  tungsten.tsv   unfiltered tungsten-anode tube spectra, one row per (anode angle, kVp)
  air_muen.tsv   NIST mass energy-absorption coefficient of dry air (Hubbell & Seltzer, NISTIR 5632,
                 Table 4), 1-200 keV, as shipped inside spekpy (data/tables/nist_muen_air.dat)
  checks.tsv     test data: SpekPy's mean energy, first HVL and fluence for a few filtered settings,
                 SpekPy's Al and Cu attenuation at the bin energies, and SpekPy spectra at angles
                 between the grid angles (for the interpolation test)
and prints the worst error of linear interpolation between grid angles against SpekPy.
"""
import json
import os
import sys

import numpy as np
import spekpy as sp

HERE = os.path.dirname(os.path.abspath(__file__))
KVP_MIN, KVP_MAX = 40, 150
ANGLES_DEG = list(range(6, 23, 2))  # 6, 8, ..., 22
DK_KEV = 1.0
# SpekPy gives photons per keV per cm^2 per mAs at z = 100 cm; per 1 keV bin per mm^2: /100.
PER_CM2_TO_PER_MM2 = 0.01
# Bins holding less than this fraction of the peak bin are left out of the per-bin error.
BIN_FLOOR = 1e-3

assert sp.__version__ == "2.5.4", f"spekpy {sp.__version__}: the shipped files need 2.5.4"
assert np.__version__ == "2.4.6", f"numpy {np.__version__}: the shipped files need 2.4.6"


def fmt(x):
    """Seven significant digits: far finer than SpekPy's own model uncertainty."""
    return f"{x:.7g}"


def tube(kvp, angle_deg):
    """Unfiltered spectrum: bin centres (keV) and photons per bin per mm^2 per mAs at 1000 mm."""
    s = sp.Spek(kvp=kvp, th=angle_deg, dk=DK_KEV)  # no filtration added: SpekPy starts with none
    k, f = s.get_spectrum()
    assert s.state.filtration.filters == [], "SpekPy added filtration"
    assert np.allclose(k, np.arange(1.5, kvp, 1.0)), f"unexpected bins {k[:3]}..{k[-1]}"
    return k, f * DK_KEV * PER_CM2_TO_PER_MM2


# The shipped tables: the bremsstrahlung continuum sampled every BREM_DK_KEV keV (rsasim
# interpolates it linearly onto its LINE_DK_KEV grid), and the characteristic lines in
# LINE_DK_KEV bins, so that an absorption edge of the scene (tantalum's K edge at 67.416 keV, a
# line's width away from tungsten's K-beta1 line at 67.24 keV) can fall between a line and the
# continuum on the side where it really is.
BREM_DK_KEV = 0.5
LINE_DK_KEV = 0.05


def continuum(kvp, angle_deg):
    """Bremsstrahlung only: bin centres 1.25, 1.75, ..., kvp - 0.25 keV and photons per
    BREM_DK_KEV bin per mm^2 per mAs at 1000 mm (SpekPy's density at the centre times the width)."""
    s = sp.Spek(kvp=kvp, th=angle_deg, dk=BREM_DK_KEV)
    k, f = s.get_spectrum(char=False)
    assert s.state.filtration.filters == [], "SpekPy added filtration"
    assert np.allclose(k, np.arange(1.0 + BREM_DK_KEV / 2, kvp, BREM_DK_KEV)), f"bins {k[:3]}"
    return k, f * BREM_DK_KEV * PER_CM2_TO_PER_MM2


def characteristic(kvp, angle_deg):
    """The characteristic lines: SpekPy's spectrum minus its bremsstrahlung in LINE_DK_KEV bins,
    as {bin centre rounded to 0.001 keV: photons per mm^2 per mAs at 1000 mm} (bins with lines)."""
    s = sp.Spek(kvp=kvp, th=angle_deg, dk=LINE_DK_KEV)
    k, total = s.get_spectrum()
    _, brem = s.get_spectrum(char=False)
    lines = (total - brem) * LINE_DK_KEV * PER_CM2_TO_PER_MM2
    assert np.all(lines >= -1e-9 * total.max()), "SpekPy's lines negative"
    return {round(float(e), 3): float(n) for e, n in zip(k, lines) if n > 0}


def write_tungsten():
    rows = []
    line_rows = []
    for angle in ANGLES_DEG:
        for kvp in range(KVP_MIN, KVP_MAX + 1):
            _, n = continuum(kvp, angle)
            rows.append("\t".join([str(angle), str(kvp)] + [fmt(v) for v in n]))
            line_rows.append((angle, kvp, characteristic(kvp, angle)))
        print(f"tungsten.tsv, tungsten_lines.tsv: angle {angle} done", file=sys.stderr)
    header = [
        "# rsasim tube spectra, bremsstrahlung only: tungsten anode, no added filtration (SpekPy",
        "# 2.5.4 defaults: physics spekpy-v2-casim, mu data pene), on the central axis at 1000 mm",
        "# from the focus. Columns: anode_angle_deg, kvp, then photons per mm^2 per mAs in each",
        f"# {BREM_DK_KEV} keV bin [1, 1.5), [1.5, 2), ..., [kvp - 0.5, kvp) keV (SpekPy's density at",
        "# the bin centre times the width). The characteristic lines are in tungsten_lines.tsv.",
        "# Made by data/spectra/regen.py; do not edit by hand.",
    ]
    with open(os.path.join(HERE, "tungsten.tsv"), "w") as out:
        out.write("\n".join(header + rows) + "\n")
    energies = sorted({e for _, _, lines in line_rows for e in lines})
    header = [
        "# rsasim tube spectra, characteristic lines of the tungsten anode (SpekPy 2.5.4, as in",
        "# tungsten.tsv): SpekPy's spectrum minus its bremsstrahlung in "
        f"{LINE_DK_KEV} keV bins. The",
        "# columns after anode_angle_deg and kvp are the bins centred at the energies (keV) of the",
        "# `energy_kev` row; values are photons per mm^2 per mAs at 1000 mm in that bin.",
        "# Made by data/spectra/regen.py; do not edit by hand.",
        "\t".join(["energy_kev", "-"] + [f"{e:.3f}" for e in energies]),
    ]
    rows = [
        "\t".join([str(a), str(kvp)] + [fmt(lines.get(e, 0.0)) for e in energies])
        for a, kvp, lines in line_rows
    ]
    with open(os.path.join(HERE, "tungsten_lines.tsv"), "w") as out:
        out.write("\n".join(header + rows) + "\n")


def write_air():
    path = os.path.join(os.path.dirname(sp.__file__), "data", "tables", "nist_muen_air.dat")
    with open(path) as f:
        data = json.load(f)
    e_kev = np.array(data["photon energy"]) * 1000.0
    muen = np.array(data["muen_over_rho_air"])
    lines = [
        "# Mass energy-absorption coefficient of dry air (near sea level), NIST: Hubbell & Seltzer,",
        "# NISTIR 5632, Table 4 (as shipped in spekpy 2.5.4, data/tables/nist_muen_air.dat).",
        "# An absorption edge appears as two rows at the same energy (below, then above the edge).",
        "# Interpolate linearly in log(energy)-log(coefficient), as NIST recommends.",
        "# energy_kev\tmuen_over_rho_cm2_per_g",
    ]
    for e, m in zip(e_kev, muen):
        if 1.0 - 1e-9 <= e <= 200.0 + 1e-9:
            # NIST lists an edge energy twice; spekpy's copy moves the second by 1e-5 keV.
            lines.append(f"{e:.5g}\t{m:.6g}")
    with open(os.path.join(HERE, "air_muen.tsv"), "w") as out:
        out.write("\n".join(lines) + "\n")


# (kVp, anode angle, mm Al, mm Cu): clinical settings, on and between grid angles.
SETTINGS = [
    (60, 10, 2.5, 0.0),
    (80, 12, 2.5, 0.0),
    (80, 13, 2.5, 0.0),
    (100, 14, 3.0, 0.1),
    (100, 11, 2.5, 0.0),
    (120, 16, 3.0, 0.1),
    (70, 15, 0.0, 0.0),
]
# Spectra at angles between grid angles, for the interpolation test.
BETWEEN = [(kvp, a) for kvp in (40, 80, 150) for a in (7, 13, 21)]


def write_checks():
    lines = [
        "# SpekPy 2.5.4 results that rsasim's tests reproduce (made by data/spectra/regen.py).",
        "# setting: kvp, anode_angle_deg, al_mm, cu_mm, mean_energy_kev, hvl1_mm_al (air kerma),",
        "#   fluence_per_mm2_per_mas (filtered), fluence_unfiltered_per_mm2_per_mas; at 1000 mm",
        "# density: material, g/cm^3 (SpekPy's)",
        "# mu: energy_kev, Al mu/rho cm^2/g, Cu mu/rho cm^2/g (SpekPy's pene data at the bin centres)",
        "# spectrum: kvp, anode_angle_deg, photons per mm^2 per mAs per 1 keV bin (SpekPy itself)",
    ]
    for kvp, angle, al, cu in SETTINGS:
        s = sp.Spek(kvp=kvp, th=angle, dk=DK_KEV)
        flu0 = s.get_flu() * PER_CM2_TO_PER_MM2
        if al > 0:
            s.filter("Al", al)
        if cu > 0:
            s.filter("Cu", cu)
        row = [kvp, angle, al, cu, s.get_emean(), s.get_hvl1("Al"),
               s.get_flu() * PER_CM2_TO_PER_MM2, flu0]
        lines.append("\t".join(["setting"] + [fmt(v) for v in row]))
    s = sp.Spek(kvp=KVP_MAX, th=12, dk=DK_KEV)
    k = s.model.k
    mu = {}
    for m in ("Al", "Cu"):
        mu_over_rho, rho = s.mu_data.get_mu_over_rho_composition(m, k)
        mu[m] = mu_over_rho
        lines.append(f"density\t{m}\t{fmt(rho)}")
    for i, e in enumerate(k):
        lines.append("\t".join(["mu", fmt(e), fmt(mu["Al"][i]), fmt(mu["Cu"][i])]))
    for kvp, angle in BETWEEN:
        _, n = tube(kvp, angle)
        lines.append("\t".join(["spectrum", str(kvp), str(angle)] + [fmt(v) for v in n]))
    with open(os.path.join(HERE, "checks.tsv"), "w") as out:
        out.write("\n".join(lines) + "\n")


def measure_interpolation():
    """Worst error of linear interpolation between grid angles, against SpekPy at odd angles."""
    worst_bin = worst_total = worst_mean = 0.0
    for kvp in range(KVP_MIN, KVP_MAX + 1, 10):
        for angle in range(ANGLES_DEG[0] + 1, ANGLES_DEG[-1], 2):
            k, lo = tube(kvp, angle - 1)
            _, hi = tube(kvp, angle + 1)
            _, exact = tube(kvp, angle)
            interp = 0.5 * (lo + hi)
            big = exact >= BIN_FLOOR * exact.max()
            worst_bin = max(worst_bin, np.max(np.abs(interp[big] / exact[big] - 1)))
            worst_total = max(worst_total, abs(interp.sum() / exact.sum() - 1))
            mean = lambda n: (n * k).sum() / n.sum()
            worst_mean = max(worst_mean, abs(mean(interp) - mean(exact)))
    print(f"interpolation between grid angles (kVp 40-150 step 10, angles 7-21 odd):")
    print(f"  worst per-bin relative error (bins >= {BIN_FLOOR:g} of the peak): {worst_bin:.4%}")
    print(f"  worst relative error of the photon total: {worst_total:.4%}")
    print(f"  worst mean-energy error: {worst_mean:.4f} keV")


if __name__ == "__main__":
    if sys.argv[1:] == ["--tungsten"]:
        write_tungsten()  # only the two tube tables (40 minutes on an idle core)
        sys.exit(0)
    write_air()
    write_checks()
    measure_interpolation()
    write_tungsten()
