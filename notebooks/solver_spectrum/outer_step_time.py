"""Solve time of `final` (rural, June, 380-780 nm every 5 nm) with its solver every 10 nm (41
wavelengths) and with 20 nm outside 440-660 nm (32), alternated, 3 of each; medians and the
median of the paired ratios.

    python notebooks/solver_spectrum/outer_step_time.py"""
import time
from dataclasses import replace

import numpy as np

from skymodel import Atmosphere
from skymodel.render.marcher import solve_sky
from skymodel.render.quality import QUALITIES
from skymodel.wavelengths import default_wavelengths

prof = Atmosphere(location="rural", month=6).optical_profile(default_wavelengths(5.0))
final = QUALITIES["final"].settings
variants = {"41 (10 nm)": replace(final, ms_wavelength_outer_step_nm=0.0), "32 (20 nm outside)": final}
times = {k: [] for k in variants}
for _ in range(3):
    for k, s in variants.items():
        t = time.perf_counter()
        solve_sky(prof, s)
        times[k].append(time.perf_counter() - t)
        print(f"{k}: {times[k][-1]:.1f} s", flush=True)
a, b = (np.array(v) for v in times.values())
print("medians " + ", ".join(f"{k} {np.median(v):.1f} s" for k, v in times.items())
      + f"; paired ratio {np.median(b / a):.2f}")
