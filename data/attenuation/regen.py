#!/usr/bin/env python3
"""Regenerate the shipped attenuation data of rsasim byte for byte.

    python3 data/attenuation/regen.py            # writes the three files beside this script
    python3 data/attenuation/regen.py --check    # also prints the comparison against NIST

Tools (pinned; other versions may change the last digits):
    Python 3.11, xraylib 4.3.0 (PyPI `xraylib`), xraydb 4.5.8 (PyPI `xraydb`), numpy 2.4.

Writes:
    elements.tsv   z, symbol, name, atomic_mass (g/mol, xraydb/IUPAC), density_g_cm3 (xraylib
                   ElementDensity = NIST XCOM Table 1 densities)
    mu_rho.tsv     z, energy_kev, mu_rho_cm2_g: xraylib CS_Total (coherent + incoherent +
                   photoelectric, cm^2/g) on a log grid of 50 points per decade from 1 to 200 keV,
                   plus every absorption edge of xraylib's cross-section data in that range as two
                   rows with the same energy: the value just below, then the value at/above it.
    materials.toml the shipped material library (density, mass fractions by element, source).
"""
import math
import os
import sys

import numpy as np
import xraydb
import xraylib
import xraylib_np

HERE = os.path.dirname(os.path.abspath(__file__))
E_MIN_KEV = 1.0
E_MAX_KEV = 200.0
PER_DECADE = 50
# Jump search: a fine log scan, then bisection.
SCAN_PER_DECADE = 20000
JUMP_MIN = 0.003  # |d ln mu| across one scan step that counts as an edge
EPS = 1.0e-3  # the two points each side an edge value is extrapolated from: J(1 +- EPS), J(1 +- 2 EPS)
SNAP = 3.0e-3  # an edge within this relative distance of xraylib's EdgeEnergy takes that energy
KEEP_OUT = 2.5e-3  # grid points this close to an edge are dropped (they would straddle the jump)

REFINE_TOL = 1.0e-3  # a segment whose midpoint misses xraylib by more than this is split
REFINE_DEPTH = 8
SHELLS = ["K", "L1", "L2", "L3", "M1", "M2", "M3", "M4", "M5", "N1", "N2", "N3", "N4", "N5", "N6", "N7"]


def mu(z, e_kev):
    return float(xraylib.CS_Total(z, float(e_kev)))


def edge_energies(z):
    out = []
    for s in SHELLS:
        try:
            e = xraylib.EdgeEnergy(z, getattr(xraylib, s + "_SHELL"))
        except ValueError:
            continue
        if e > 0:
            out.append(e)
    return out


def find_jumps(z):
    """Energies where xraylib's CS_Total for element z is discontinuous, in [E_MIN, E_MAX]."""
    n = int(round(math.log10(E_MAX_KEV / E_MIN_KEV) * SCAN_PER_DECADE)) + 1
    xs = np.logspace(math.log10(E_MIN_KEV), math.log10(E_MAX_KEV), n)
    ln = np.log(xraylib_np.CS_Total(np.array([z]), xs)[0])
    d = np.abs(np.diff(ln))
    jumps = []
    for i in range(len(d)):
        if d[i] < JUMP_MIN:
            continue
        nb = max(d[max(i - 3, 0):i].max(initial=0.0), d[i + 1:i + 4].max(initial=0.0))
        if d[i] < 5.0 * nb:
            continue
        lo, hi = xs[i], xs[i + 1]
        llo, lhi = ln[i], ln[i + 1]
        for _ in range(80):
            m = math.sqrt(lo * hi)
            lm = math.log(mu(z, m))
            if abs(lm - llo) < abs(lm - lhi):
                lo = m
            else:
                hi = m
        jumps.append(hi)
    return jumps


def extrapolate(z, e1, e2, target):
    """log-log line through (e1, mu(e1)) and (e2, mu(e2)), evaluated at target."""
    l1, l2 = math.log(mu(z, e1)), math.log(mu(z, e2))
    t = (math.log(target) - math.log(e1)) / (math.log(e2) - math.log(e1))
    return math.exp(l1 + t * (l2 - l1))


def element_rows(z):
    edges = []
    known = edge_energies(z)
    for j in find_jumps(z):
        near = [e for e in known if abs(e / j - 1.0) <= SNAP]
        r = min(near, key=lambda e: abs(e / j - 1.0)) if near else j
        below = extrapolate(z, j * (1 - 2 * EPS), j * (1 - EPS), r)
        above = extrapolate(z, j * (1 + EPS), j * (1 + 2 * EPS), r)
        edges.append((r, j, below, above))
    grid = [10.0 ** (k / PER_DECADE) for k in range(int(math.log10(E_MAX_KEV) * PER_DECADE) + 1)]
    if grid[-1] < E_MAX_KEV:
        grid.append(E_MAX_KEV)
    rows = []
    for e in grid:
        if any(min(r, j) * (1 - KEEP_OUT) <= e <= max(r, j) * (1 + KEEP_OUT) for r, j, _, _ in edges):
            # The table ends stay; they must lie outside the span between the edge's row energy
            # and the data's jump, so that their value is on the right side of the edge.
            if e in (E_MIN_KEV, E_MAX_KEV):
                if any(min(r, j) <= e <= max(r, j) for r, j, _, _ in edges):
                    sys.exit(f"Z={z}: an edge lies on the table end {e} keV")
            else:
                continue
        rows.append((e, 0, mu(z, e)))
    for r, _, below, above in edges:
        rows.append((r, 0, below))
        rows.append((r, 1, above))
    rows.sort(key=lambda t: (t[0], t[1]))
    return refine(z, rows), edges


def refine(z, rows):
    """Insert geometric midpoints where log-log interpolation misses xraylib by more than REFINE_TOL
    (near-edge structure below a few keV), recursively, at most REFINE_DEPTH times per segment."""
    out = [rows[0]]
    for nxt in rows[1:]:
        out.extend(split(z, out[-1], nxt, REFINE_DEPTH))
        out.append(nxt)
    return out


def split(z, a, b, depth):
    (e0, _, v0), (e1, _, v1) = a, b
    if e1 <= e0 or depth == 0:
        return []
    m = math.sqrt(e0 * e1)
    exact = mu(z, m)
    if abs(math.exp(0.5 * (math.log(v0) + math.log(v1))) / exact - 1.0) <= REFINE_TOL:
        return []
    mid = (m, 0, exact)
    return split(z, a, mid, depth - 1) + [mid] + split(z, mid, b, depth - 1)


def fmt(x):
    return "%.6e" % x


def write_elements():
    lines = ["z\tsymbol\tname\tatomic_mass\tdensity_g_cm3"]
    for z in range(1, 93):
        name = xraydb.atomic_name(z).capitalize()
        lines.append("\t".join([str(z), xraylib.AtomicNumberToSymbol(z), name,
                                "%.6f" % xraydb.atomic_mass(z), fmt(xraylib.ElementDensity(z))]))
    return "\n".join(lines) + "\n"


def write_mu():
    lines = ["z\tenergy_kev\tmu_rho_cm2_g"]
    all_edges = {}
    for z in range(1, 93):
        rows, edges = element_rows(z)
        all_edges[z] = edges
        for e, _, v in rows:
            lines.append("%d\t%s\t%s" % (z, fmt(e), fmt(v)))
    return "\n".join(lines) + "\n", all_edges


# ---------------------------------------------------------------- materials
def formula_fractions(atoms):
    """Mass fractions of a formula given as [(symbol, count)], with xraydb atomic masses."""
    masses = [(s, n * xraydb.atomic_mass(s)) for s, n in atoms]
    total = sum(m for _, m in masses)
    return [(s, m / total) for s, m in masses]


# (name, density g/cm3, [(symbol, mass fraction)], source). Fractions are written with 6 decimals;
# rsasim normalises each list exactly to 1 when it loads it.
NIST_T2 = "Hubbell & Seltzer, NISTIR 5632 (NIST SRD 126), Table 2"
MATERIALS = [
    ("tantalum", 16.65, [("Ta", 1.0)], "pure element; density of tantalum metal (NIST Table 1: 16.654)"),
    ("cocr_f75", 8.3,
     [("Co", 0.633), ("Cr", 0.285), ("Mo", 0.060), ("Ni", 0.0025), ("Fe", 0.0035), ("Si", 0.007),
      ("Mn", 0.005), ("C", 0.0025), ("N", 0.0015)],
     "ASTM F75 cast Co-28Cr-6Mo: Cr 27-30, Mo 5-7, Ni <= 0.5, Fe <= 0.75, Si <= 1, Mn <= 1, "
     "C <= 0.35, N <= 0.25, Co balance (wt %); nominal Cr 28.5, Mo 6.0, minor elements at typical "
     "mid-range values; density 8.3 g/cm3"),
    ("ti6al4v", 4.43,
     [("Ti", 0.8967), ("Al", 0.060), ("V", 0.040), ("Fe", 0.0020), ("O", 0.0013)],
     "ASTM F136 Ti-6Al-4V ELI: Al 5.5-6.5, V 3.5-4.5, Fe <= 0.25, O <= 0.13, Ti balance (wt %); "
     "nominal Al 6.0, V 4.0, Fe 0.20, O 0.13; density 4.43 g/cm3"),
    ("steel_316l", 8.0,
     [("Fe", 0.630), ("Cr", 0.180), ("Ni", 0.140), ("Mo", 0.026), ("Mn", 0.018), ("Si", 0.005),
      ("N", 0.0008), ("C", 0.0002)],
     "ASTM F138 316L: Cr 17-19, Ni 13-15, Mo 2.25-3, Mn <= 2, Si <= 0.75, N <= 0.1, C <= 0.03, "
     "Fe balance (wt %); nominal Cr 18, Ni 14, Mo 2.6, Mn 1.8, Si 0.5, N 0.08, C 0.02; density 8.0 g/cm3"),
    ("uhmwpe", 0.94, formula_fractions([("C", 2), ("H", 4)]),
     "ultra-high-molecular-weight polyethylene (C2H4)n, fractions from the formula; density 0.94 g/cm3 "
     "(ISO 5834-2: 0.927-0.944)"),
    ("pmma", 1.19, formula_fractions([("C", 5), ("H", 8), ("O", 2)]),
     "polymethyl methacrylate (C5H8O2)n, fractions from the formula (" + NIST_T2 + ": H 0.080538, "
     "C 0.599848, O 0.319614); density 1.19 g/cm3"),
    ("bone_cortical", 1.92,
     [("H", 0.034), ("C", 0.155), ("N", 0.042), ("O", 0.435), ("Na", 0.001), ("Mg", 0.002),
      ("P", 0.103), ("S", 0.003), ("Ca", 0.225)],
     "Bone, Cortical (ICRU-44), " + NIST_T2),
    ("bone_cancellous", 1.18,
     [("H", 0.085), ("C", 0.404), ("N", 0.028), ("O", 0.367), ("Na", 0.001), ("Mg", 0.001),
      ("P", 0.034), ("S", 0.002), ("Cl", 0.001), ("K", 0.001), ("Ca", 0.076)],
     "adult spongiosa (trabecular bone with marrow), ICRU Report 46 after Woodard & White, "
     "Br J Radiol 59 (1986) 1209; density 1.18 g/cm3"),
    ("soft_tissue", 1.06,
     [("H", 0.102), ("C", 0.143), ("N", 0.034), ("O", 0.708), ("Na", 0.002), ("P", 0.003),
      ("S", 0.003), ("Cl", 0.002), ("K", 0.003)],
     "Tissue, Soft (ICRU-44), " + NIST_T2),
    ("water", 1.0, [("H", 0.111898), ("O", 0.888102)], "Water, Liquid, " + NIST_T2),
    ("air", 0.001205, [("C", 0.000124), ("N", 0.755268), ("O", 0.231781), ("Ar", 0.012827)],
     "Air, Dry (near sea level), " + NIST_T2),
    ("aluminium", 2.699, [("Al", 1.0)], "pure element; NIST Table 1 density 2.699"),
    ("copper", 8.96, [("Cu", 1.0)], "pure element; NIST Table 1 density 8.960"),
    ("csi", 4.51, [("Cs", 0.511549), ("I", 0.488451)], "Cesium Iodide, " + NIST_T2),
]


def write_materials():
    out = ["# The shipped material library of rsasim, written by data/attenuation/regen.py.",
           "# density_g_cm3 in g/cm3; composition = element symbol -> mass fraction (summing to 1",
           "# within 1e-3; rsasim normalises it exactly). Order here is the order of library().", ""]
    for name, rho, fr, src in MATERIALS:
        total = sum(w for _, w in fr)
        assert abs(total - 1.0) <= 1e-6, (name, total)
        out.append("[[material]]")
        out.append('name = "%s"' % name)
        out.append("density_g_cm3 = %s" % repr(float(rho)))
        out.append("composition = { %s }" % ", ".join("%s = %.6f" % (s, w) for s, w in fr))
        out.append('source = "%s"' % src)
        out.append("")
    return "\n".join(out)


# ---------------------------------------------------------------- checks against NIST
# NIST SRD 126 (Hubbell & Seltzer, NISTIR 5632), Tables 3 and 4, mu/rho in cm2/g.
NIST_E = [20, 30, 40, 50, 60, 80, 100, 150]
NIST = {
    "water": [0.8096, 0.3756, 0.2683, 0.2269, 0.2059, 0.1837, 0.1707, 0.1505],
    "aluminium": [3.441, 1.128, 0.5685, 0.3681, 0.2778, 0.2018, 0.1704, 0.1378],
    "copper": [33.79, 10.92, 4.862, 2.613, 1.593, 0.7630, 0.4584, 0.2217],
    "tantalum": [63.34, 21.87, 10.25, 5.717, 3.569, 7.587, 4.302, 1.531],
    "bone_cortical": [4.001, 1.331, 0.6655, 0.4242, 0.3148, 0.2229, 0.1855, 0.1480],
    "soft_tissue": [0.8230, 0.3790, 0.2688, 0.2264, 0.2048, 0.1823, 0.1693, 0.1492],
    "csi": [26.86, 9.045, 22.97, 12.87, 7.921, 3.677, 2.035, 0.7290],
}


def check(mu_text):
    table = {}
    for line in mu_text.splitlines()[1:]:
        z, e, v = line.split("\t")
        table.setdefault(int(z), []).append((float(e), float(v)))

    def interp(z, e):
        rows = table[z]
        i = max(k for k, r in enumerate(rows) if r[0] <= e)
        if rows[i][0] == e:
            return rows[i][1]
        (e0, v0), (e1, v1) = rows[i], rows[i + 1]
        t = math.log(e / e0) / math.log(e1 / e0)
        return math.exp(math.log(v0) + t * (math.log(v1) - math.log(v0)))

    mats = {m[0]: m for m in MATERIALS}
    worst = 0.0
    for name, vals in NIST.items():
        fr = mats[name][2]
        for e, ref in zip(NIST_E, vals):
            got = sum(w * interp(xraylib.SymbolToAtomicNumber(s), e) for s, w in fr)
            worst = max(worst, abs(got / ref - 1))
    print("table vs NIST Tables 3/4 at 20-150 keV: max relative deviation %.2e" % worst)
    # Interpolation error of the log grid: geometric midpoints against xraylib directly.
    for lo in (E_MIN_KEV, 5.0):
        worst = (0.0, 0, 0.0)
        for z, rows in table.items():
            for (e0, _), (e1, _) in zip(rows, rows[1:]):
                if e1 <= e0 or e0 < lo:
                    continue
                m = math.sqrt(e0 * e1)
                d = abs(interp(z, m) / mu(z, m) - 1)
                if d > worst[0]:
                    worst = (d, z, m)
        print("log-log interpolation vs xraylib at segment midpoints >= %g keV: max %.2e (Z=%d, %.3f keV)"
              % ((lo,) + worst))


def main():
    el = write_elements()
    mu_text, edges = write_mu()
    mats = write_materials()
    for fname, text in (("elements.tsv", el), ("mu_rho.tsv", mu_text), ("materials.toml", mats)):
        with open(os.path.join(HERE, fname), "w", newline="\n") as f:
            f.write(text)
    if "--check" in sys.argv:
        n_edges = sum(len(v) for v in edges.values())
        unsnapped = [(z, "%.4f" % r) for z, v in edges.items() for r, j, _, _ in v if r == j]
        print("edges: %d; not at an xraylib EdgeEnergy (kept where the data jump): %s" % (n_edges, unsnapped))
        check(mu_text)


if __name__ == "__main__":
    main()
