"""How the paper desert's phase function depends on the radius above which particles are held at
one sphere's optics (``mie_lookup.PAPER_R_MAX_UM``, 50 um in the shipped table).

usage: phase_tail.py [WAVELENGTH_NM] [R_MAX_UM,...]   (default 450 and 50,100,200,500,1000)

Prints, per r_max: the build time of the one entry at that wavelength, p(0), g, and the zigzag
between neighbouring table angles (largest |p / exp(five-angle running mean of log p) - 1| in
1-3, 3-6, 6-12, 12-30 degrees); then the nine-angle smoothed phase function at a few angles and
its ratio to the first r_max's; and the area share of the desert distribution above each r_max.
"""
import sys
import time

import numpy as np

from skymodel.optics import mie_lookup as ml

wl = np.array([float(sys.argv[1]) if len(sys.argv) > 1 else 450.0])
radii = [float(r) for r in (sys.argv[2] if len(sys.argv) > 2 else "50,100,200,500,1000").split(",")]
entry = ml.paper_entries()["desert:mineral"]
m = ml.refractive_index_file(entry["index"] + ".csv", wl)
ang = ml.default_angles_deg()
total_area = sum(n * ml.lognormal_area_tail(r, s, 1e-9) for n, r, s in entry["modes"])
phases = {}
for r_max in radii:
    t = time.perf_counter()
    res = ml.integrate_modes(m, wl, entry["modes"], ang, r_max_um=r_max)
    p = res["phase"][:, 0] / ml.phase_integral(res["phase"], ang, axis=0)[0]
    phases[r_max] = p
    lp = np.log(p)
    zig = np.abs(np.exp(lp - np.convolve(lp, np.ones(5) / 5, mode="same")) - 1.0)
    bands = "/".join(f"{100 * zig[(ang > lo) & (ang < hi)].max():.1f}" for lo, hi in ((1, 3), (3, 6), (6, 12), (12, 30)))
    above = sum(n * ml.lognormal_area_tail(r, s, r_max) for n, r, s in entry["modes"]) / total_area
    print(f"r_max {r_max:6g} um: {time.perf_counter() - t:5.1f} s, p(0) {p[0]:.4g} sr^-1, g {res['g'][0]:.4f}, "
          f"ext {res['ext'][0]:.5g} m^2, zigzag 1-3/3-6/6-12/12-30 deg {bands} %, area above r_max {100 * above:.1f} %")


def smooth(p):
    return np.exp(np.convolve(np.log(p), np.ones(9) / 9, mode="same"))


first = radii[0]
print("angle (deg) | " + " | ".join(f"p({r:g} um)" for r in radii) + " | " + " | ".join(f"{first:g}/{r:g}" for r in radii[1:]))
for a in (0.1, 0.5, 1, 2, 3, 5, 8, 12, 20, 40, 90, 150):
    i = int(np.argmin(np.abs(ang - a)))
    sm = [smooth(phases[r])[i] for r in radii]
    print(f"{a:6.1f} | " + " | ".join(f"{v:.4g}" for v in sm) + " | " + " | ".join(f"{sm[0] / v:.3f}" for v in sm[1:]))
