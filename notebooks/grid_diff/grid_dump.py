"""Dump the final direction grid's total radiance (sky and ground rings) for scenes, to compare code revisions.
usage (from the repository root, once per revision on PYTHONPATH): python notebooks/grid_diff/grid_dump.py OUTDIR tag rural:25,5,-4 desert:60,20,5,0"""
import sys, os, time
import numpy as np
sys.path[:0] = ["benchmarks"]
import bench_truth as bt
from skymodel.render.marcher import SkyMarcher, solve_sky
from skymodel.render.quality import QUALITIES, quality_settings
from skymodel.wavelengths import default_wavelengths
out, tag = sys.argv[1], sys.argv[2]
os.makedirs(out, exist_ok=True)
s = quality_settings("final")
wl = default_wavelengths(QUALITIES["final"].wavelength_step_nm)
for item in sys.argv[3:]:
    loc, suns = item.split(":")
    suns = [float(x) for x in suns.split(",")]
    atm = bt.Scene(loc, suns[0], "/tmp").atm
    prof = atm.optical_profile(wl)
    sol = solve_sky(prof, s)
    for sun in suns:
        t = time.perf_counter()
        m = SkyMarcher(prof, sun, 180.0, settings=s, solution=sol)
        dt = time.perf_counter() - t
        sky, ground = [sum(imgs) for imgs in m._grid[3]]
        np.savez(f"{out}/{loc}_{sun:g}_{tag}.npz", sky=sky, ground=ground, zen_sky=m._grid[0], az=m._grid[2],
                 secs=dt, e_sun=prof.solar_irradiance)
        print(f"{loc} {sun:g} {tag}: grid {dt:.2f} s", flush=True)
