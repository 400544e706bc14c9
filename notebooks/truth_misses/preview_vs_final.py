"""`preview` as it was before 2026-11-30 (12-degree cone, no peak spread, 16 x 8 solver nodes) and as it
is now, each against `final` over the sky: median and max |preview / final - 1| (%) at 450/550/650 nm,
directions within the truth's EXCLUDE_DEG of the sun left out.

usage: preview_vs_final.py locations suns   e.g. continental,urban,maritime,arctic,desert,rural 60,20,5,0,-4"""
import sys, time
from dataclasses import replace
import numpy as np
from skymodel import Atmosphere
from skymodel.render.marcher import SkyMarcher
from skymodel.render.quality import QUALITIES
from skymodel.render.rays import direction_from_angles
from skymodel.validation.truth import EXCLUDE_DEG, angle_to_sun_deg

wl = list(np.arange(440.0, 661.0, 10.0))


def preview_before(now):
    """``preview``'s settings as they were before d40ed5f, from ``now`` (its settings since)."""
    return replace(now, delta_m_cutoff_deg=12.0, delta_m_mild_cutoff_deg=0.0, peak_spread=False, table_phi=8,
                   table_mu=16)


var = QUALITIES["preview"].settings  # the preset as it is now
pv = preview_before(var)  # as it was


def main():
    fin = QUALITIES["final"].settings
    zen = np.concatenate([np.arange(0, 80, 10.0), [80, 84, 86, 88, 89, 89.5]])
    az = np.concatenate([[0, 2.5, 4, 6, 8, 10, 15], np.arange(20, 181, 20.0)])
    zz, aa = np.meshgrid(zen, az, indexing="ij")
    dirs = direction_from_angles(zz.ravel(), (180.0 + aa.ravel()) % 360.0)
    j = [wl.index(450.0), wl.index(550.0), wl.index(650.0)]
    for loc in sys.argv[1].split(","):
        for sun in [float(x) for x in sys.argv[2].split(",")]:
            atm = Atmosphere(location=loc, month=6)
            prof = atm.optical_profile(wl)
            # leave out the sun's disc and the aureole's first 2 degrees, as the truth does
            sd = direction_from_angles(np.array([90.0 - sun]), np.array([180.0]))[0]
            keep = angle_to_sun_deg(dirs, sd) > EXCLUDE_DEG
            out = {}
            for tag, s in (("final", fin), ("preview", pv), ("variant", var)):
                t = time.perf_counter()
                r = SkyMarcher(prof, sun, 180.0, 0.0, s).radiance(dirs[keep]).radiance[:, j]
                out[tag] = (r, time.perf_counter() - t)
            ref = out["final"][0]
            line = f"{loc:12s} {sun:5.1f}"
            for tag in ("preview", "variant"):  # as it was, as it is
                rel = np.abs(out[tag][0] / ref - 1) * 100
                line += f" | {tag}: med " + "/".join(f"{np.median(rel[:, k]):.2f}" for k in range(3)) + " max " + "/".join(f"{rel[:, k].max():.1f}" for k in range(3))
            print(line, flush=True)


if __name__ == "__main__":
    main()
