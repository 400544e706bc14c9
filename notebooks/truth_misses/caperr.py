"""bench_skyview.py error, at final, for sun_exact_deg 8 and 12 (one solve per aerosol)."""
import sys, time
from dataclasses import replace
import numpy as np
from skymodel import Atmosphere
from skymodel.render.cameras import make_camera
from skymodel.render.marcher import solve_sky, optics_key
from dataclasses import replace as dreplace
from skymodel.render.quality import quality_settings
from skymodel.render.rays import sun_direction
from skymodel.render.sky import render_sky_reduced
from skymodel.render.skyview import xyz_reduction
from skymodel.wavelengths import default_wavelengths
size = int(sys.argv[1]) if len(sys.argv) > 1 else 512
exacts = [float(x) for x in (sys.argv[2] if len(sys.argv) > 2 else "8,12").split(",")]
SCENES = (("rural", 30.0), ("rural", -4.0), ("desert", 60.0), ("desert", 20.0), ("desert", 5.0), ("desert", 0.0))
wl = default_wavelengths(10.0)
s0 = quality_settings("final")
cam = make_camera("equirectangular", size, n_wavelengths=3)
dirs, valid = cam.directions()
red = xyz_reduction(wl)
sols = {}
print("| scene | sun_exact | pixels in cap | marched exactly | mean all (%) | max all (%) | mean cap (%) | max cap (%) | table s | direct s |")
for aerosol, sun in SCENES:
    prof = Atmosphere(location=aerosol, month=6).optical_profile(wl)
    if aerosol not in sols:
        sols[aerosol] = solve_sky(prof, s0)
    for ex in exacts:
        s = replace(s0, sun_exact_deg=ex)
        sol = sols[aerosol]
        sol = dreplace(sol, settings=s, key=optics_key(prof, s))
        out, secs, info = {}, {}, {}
        for m in ("table", "direct"):
            t = time.perf_counter()
            out[m], _, info[m] = render_sky_reduced(prof, cam, sun, red, 3, 180.0, 0.0, s, solution=sol, method=m, band_pixels=1 << 20)
            secs[m] = time.perf_counter() - t
        gam = np.degrees(np.arccos(np.clip(dirs @ sun_direction(sun, 180.0), -1, 1)))
        keep = valid & (gam > 0.3) & np.all(out["direct"] > 0, axis=-1)
        rel = np.abs(out["table"][keep] / out["direct"][keep] - 1.0)
        cap = (gam < ex)[keep]
        print(f"| {aerosol} sun {sun:g} | {ex:g} | {int(cap.sum())} | {info['table'].get('table_exact_pixels')} "
              f"| {100 * rel.mean():.5f} | {100 * rel.max():.3f} | {100 * rel[cap].mean():.4f} "
              f"| {100 * rel[cap].max():.3f} | {secs['table']:.1f} | {secs['direct']:.1f} |", flush=True)
