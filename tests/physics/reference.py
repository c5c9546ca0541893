#!/usr/bin/env python3
"""The independent physics reference of tests/physics.rs: attenuation from xraylib, tube spectra
from SpekPy, nothing from rsasim but the question asked.

Tools (pinned in tests/physics/requirements.txt; .ci/run installs them in a venv):
    spekpy 2.5.4 (its default physics "spekpy-v2-casim" and mu data "pene"), xraylib 4.3.0,
    numpy 2.4.6.

Reads one JSON request on standard input and prints one JSON answer:

    {"mu_rho": [{"composition": {"Ta": 1.0}, "energies_kev": [20, 60]}, ...],
     "edges": ["Ta", "Cs", ...],
     "beams": [{"kvp": 85, "anode_angle_deg": 12,
                "filtration": [{"composition": {"Al": 1.0}, "density_g_cm3": 2.699,
                                "thickness_mm": 2.5}],
                "response": "energy_integrating" | "photon_counting",
                "scintillator": {"composition": {...}, "density_g_cm3": 4.51,
                                 "thickness_mm": 0.6} | null,
                "steps": [{"composition": {...}, "density_g_cm3": ..., "thickness_mm": ...}]}]}

Answer: "mu_rho": per request the mass attenuation coefficients (cm2/g) by the mixture rule over
xraylib.CS_Total (coherent + incoherent + photoelectric); "edges": per symbol the K, L1, L2 and
L3 edge energies (keV) of xraylib.EdgeEnergy; "beams": per beam the mean energy (keV), first and
second half-value layers in aluminium (mm; air kerma weighted with NIST's mass energy-absorption
coefficient of dry air as shipped inside spekpy, log-log interpolated), the photon fluence per
mm2 per mAs at 1000 mm, the air kerma (uGy per mAs at 1000 mm) and, per step, the transmission
as the detector weighs it (photons x absorption, times the energy for an energy-integrating
detector).

The spectrum is SpekPy's tungsten-anode spectrum in 0.05 keV bins (DK_KEV), lines included, with
no filtration of SpekPy's own: the filters are applied here with xraylib's attenuation, at each
bin's centre.
"""
import json
import os
import sys

import numpy as np
import spekpy as sp
import xraylib as xr

DK_KEV = 0.05
# SpekPy: photons per keV per cm^2 per mAs at 100 cm; per bin per mm^2: x DK / 100.
PER_CM2_TO_PER_MM2 = 0.01
# Aluminium for the half-value layers: NIST's density (g/cm3), as rsasim's library.
AL_DENSITY = 2.699
# 1 keV = 1.602176634e-16 J, 1 mm^-2 = 1e6 m^-2, 1 cm^2/g = 0.1 m^2/kg; Gy -> uGy.
UGY_PER_WEIGHT = 1.602176634e-16 * 1e6 * 0.1 * 1e6
SHELLS = {"K": xr.K_SHELL, "L1": xr.L1_SHELL, "L2": xr.L2_SHELL, "L3": xr.L3_SHELL}


def mu_rho(composition, energies_kev):
    """Mixture rule over xraylib.CS_Total, cm2/g, at each energy."""
    out = np.zeros(len(energies_kev))
    for symbol, fraction in composition.items():
        z = xr.SymbolToAtomicNumber(symbol)
        out += fraction * np.array([xr.CS_Total(z, float(e)) for e in energies_kev])
    return out


def mu_per_mm(layer, energies_kev):
    return mu_rho(layer["composition"], energies_kev) * layer["density_g_cm3"] / 10.0


def air_muen(energies_kev):
    """NIST mu_en/rho of dry air (spekpy's copy of Hubbell & Seltzer Table 4), log-log."""
    path = os.path.join(os.path.dirname(sp.__file__), "data", "tables", "nist_muen_air.dat")
    with open(path) as f:
        data = json.load(f)
    e = np.array(data["photon energy"]) * 1000.0
    m = np.array(data["muen_over_rho_air"])
    out = np.empty(len(energies_kev))
    for i, x in enumerate(energies_kev):
        j = np.searchsorted(e, x, side="right") - 1
        j = min(max(j, 0), len(e) - 2)
        while e[j + 1] == e[j]:
            j += 1
        t = (np.log(x) - np.log(e[j])) / (np.log(e[j + 1]) - np.log(e[j]))
        out[i] = np.exp(np.log(m[j]) + t * (np.log(m[j + 1]) - np.log(m[j])))
    return out


def kerma_layer(weights, mu_al, fraction):
    """Thickness of aluminium (mm) leaving `fraction` of the air kerma (bisection)."""
    k0 = weights.sum()
    lo, hi = 0.0, 1.0
    while (weights * np.exp(-mu_al * hi)).sum() > fraction * k0:
        hi *= 2.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if (weights * np.exp(-mu_al * mid)).sum() > fraction * k0:
            lo = mid
        else:
            hi = mid
        if hi - lo <= 1e-12 * hi:
            break
    return 0.5 * (lo + hi)


def beam(request):
    s = sp.Spek(kvp=request["kvp"], th=request["anode_angle_deg"], dk=DK_KEV)
    assert s.state.filtration.filters == [], "SpekPy added filtration"
    k, density = s.get_spectrum()
    n = density * DK_KEV * PER_CM2_TO_PER_MM2
    for layer in request["filtration"]:
        n = n * np.exp(-mu_per_mm(layer, k) * layer["thickness_mm"])
    weights = n * k * air_muen(k)
    mu_al = mu_rho({"Al": 1.0}, k) * AL_DENSITY / 10.0
    hvl1 = kerma_layer(weights, mu_al, 0.5)
    hvl2 = kerma_layer(weights, mu_al, 0.25) - hvl1
    scint = request.get("scintillator")
    eta = 1.0 - np.exp(-mu_per_mm(scint, k) * scint["thickness_mm"]) if scint else np.ones(len(k))
    w = n * eta * (k if request["response"] == "energy_integrating" else 1.0)
    steps = [
        float((w * np.exp(-mu_per_mm(step, k) * step["thickness_mm"])).sum() / w.sum())
        for step in request["steps"]
    ]
    return {
        "mean_energy_kev": float((n * k).sum() / n.sum()),
        "hvl1_mm_al": hvl1,
        "hvl2_mm_al": hvl2,
        "fluence_per_mm2_per_mas": float(n.sum()),
        "air_kerma_ugy_per_mas": float(weights.sum() * UGY_PER_WEIGHT),
        "transmissions": steps,
    }


def edges(symbol):
    z = xr.SymbolToAtomicNumber(symbol)
    out = {}
    for name, shell in SHELLS.items():
        try:
            e = xr.EdgeEnergy(z, shell)
        except ValueError:
            continue
        if e > 0:
            out[name] = e
    return out


def main():
    assert sp.__version__ == "2.5.4", f"spekpy {sp.__version__}, the reference pins 2.5.4"
    assert np.__version__ == "2.4.6", f"numpy {np.__version__}, the reference pins 2.4.6"
    assert xr.__version__ == "4.3.0", f"xraylib {xr.__version__}, the reference pins 4.3.0"
    request = json.load(sys.stdin)
    answer = {
        "mu_rho": [
            list(mu_rho(r["composition"], r["energies_kev"])) for r in request.get("mu_rho", [])
        ],
        "edges": {s: edges(s) for s in request.get("edges", [])},
        "beams": [beam(b) for b in request.get("beams", [])],
    }
    json.dump(answer, sys.stdout)


if __name__ == "__main__":
    main()
