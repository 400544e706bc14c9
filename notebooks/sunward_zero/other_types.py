"""Does the per-sky cone help aerosol types without a Monte Carlo truth? `final` with the 12-degree
cone and with today's per-sky cone against the cone resolved in the field (3 degrees, 64 x 48
nodes: for rural haze within 1.8 % of the truth at sun 0 degrees), on the truth's views.

usage: other_types.py aerosol[,aerosol...] sun_elevation_deg [aod550]
(e.g. urban,maritime_clean 0 0.2; the June rural site, every direction exact)"""
import sys
from dataclasses import replace

import numpy as np

from skymodel import Atmosphere
from skymodel.render.marcher import SkyMarcher
from skymodel.render.quality import QUALITIES
from skymodel.validation.truth import angle_to_sun_deg, view_directions, view_set
from skymodel.render.rays import sun_direction

WL = [450.0, 550.0, 650.0]
types, elev = sys.argv[1].split(","), float(sys.argv[2])
aod = float(sys.argv[3]) if len(sys.argv) > 3 else 0.2
views = view_set(elev)
dirs = view_directions(views, 180.0)
angle = angle_to_sun_deg(dirs, sun_direction(elev, 180.0))
keep = angle > 2.27  # outside the disc and the aureole's first 2 degrees, as the truth table
fin = replace(QUALITIES["final"].settings, exact=True)
variants = {"12deg": replace(fin, delta_m_mild_cutoff_deg=0.0), "per-sky": fin,
            "resolved": replace(fin, delta_m_cutoff_deg=3.0, table_mu=64, table_phi=48)}
for t in types:
    prof = Atmosphere(location="rural", month=6, aerosol=t, aod550=aod).optical_profile(WL)
    out = {}
    for name, s in variants.items():
        m = SkyMarcher(prof, elev, 180.0, 0.0, s)
        out[name] = m.radiance(dirs).radiance
        print(f"{t} {name}: cone {m.medium.cutoff_deg:g} deg", flush=True)
    ref = out["resolved"]
    for name in ("12deg", "per-sky"):
        rel = out[name][keep] / ref[keep] - 1
        worst = rel[np.argmax(np.abs(rel), axis=0), np.arange(3)]
        print(f"{t} AOD {aod:g} sun {elev:g}: {name} against the resolved cone: median |rel| "
              + "/".join(f"{100 * x:.2f}" for x in np.median(np.abs(rel), axis=0)) + " %, worst "
              + "/".join(f"{100 * x:+.2f}" for x in worst) + " % at "
              + ", ".join(sorted({f"{views[keep][i][0]:g}/{views[keep][i][1]:g}"
                                  for i in np.argmax(np.abs(rel), axis=0)})), flush=True)
