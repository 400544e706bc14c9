"""The spherical correction's probe wavelengths: `final` (probes about 100 nm apart, the factor carried
between them by the solver's map; read linearly before 4b13185) against the correction computed at
every solver wavelength (`spherical_probe_step_nm=10`), on bench_truth's views and a grid
(`_setup.scene_views`), render grid 5 nm.

    python notebooks/solver_spectrum/probes.py desert:-4,rural:-4
"""
import sys, time; sys.path[:0] = [str(__import__("pathlib").Path(__file__).resolve().parents[2] / "benchmarks")]
import numpy as np, bench_truth as bt
from _setup import scene_views
from dataclasses import replace
from skymodel.render.marcher import SkyMarcher
from skymodel.render.quality import QUALITIES
from skymodel.wavelengths import default_wavelengths
from skymodel.colorimetry import cmf_weights
wl = default_wavelengths(5.0); cmf = cmf_weights(wl)
for name in sys.argv[1].split(","):
    a, e = name.split(":"); sc = bt.Scene(a, float(e), "/nonexistent"); prof = sc.atm.optical_profile(list(wl))
    views, dirs, keep = scene_views(sc, bt.SUN_AZIMUTH)
    out = {}
    for tag, step in (("probe100", 100.0), ("probe10", 10.0)):
        s = replace(QUALITIES["final"].settings, spherical_probe_step_nm=step)
        t = time.perf_counter(); out[tag] = SkyMarcher(prof, sc.elev, bt.SUN_AZIMUTH, 0.0, s).radiance(dirs).radiance
        print(name, tag, f"{time.perf_counter()-t:.1f} s", flush=True)
    rel = out["probe100"][keep] / out["probe10"][keep] - 1
    i, j = np.unravel_index(np.abs(rel).argmax(), rel.shape)
    relY = (out["probe100"] @ cmf)[keep] / (out["probe10"] @ cmf)[keep] - 1
    print(f"  {name}: probes 100 nm vs every solver wavelength: spectral median {np.median(np.abs(rel))*100:.3f} %, worst {rel[i,j]*100:+.2f} % ({wl[j]:.0f} nm, {views[keep][i]}); XYZ max {np.abs(relY).max(0)*100}", flush=True)
