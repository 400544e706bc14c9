"""The spherical correction's probe wavelengths: `final` (probes about 100 nm apart, the factor read
linearly between them) against the correction computed at every solver wavelength
(`spherical_probe_step_nm=10`), on bench_truth's views and the grid of measure.py, render grid 5 nm.

    python notebooks/solver_spectrum/probes.py desert:-4,rural:-4
"""
import sys, time; sys.path[:0] = [str(__import__("pathlib").Path(__file__).resolve().parents[2] / "benchmarks")]
import numpy as np, bench_truth as bt
from dataclasses import replace
from skymodel.render.marcher import SkyMarcher
from skymodel.render.quality import QUALITIES
from skymodel.render.rays import sun_direction
from skymodel.validation.truth import view_directions
from skymodel.wavelengths import default_wavelengths
from skymodel.colorimetry import cmf_weights
wl = default_wavelengths(5.0); cmf = cmf_weights(wl)
for name in sys.argv[1].split(","):
    a, e = name.split(":"); sc = bt.Scene(a, float(e), "/nonexistent"); prof = sc.atm.optical_profile(list(wl))
    Z, A = np.meshgrid(np.r_[np.arange(0, 85, 5.0), 86, 87, 88, 89, 89.5], np.arange(0, 181, 10.0), indexing="ij")
    grid = np.stack([Z.ravel(), A.ravel()], -1); views = np.concatenate([sc.views, grid])
    dirs = np.concatenate([sc.dirs, view_directions(grid, bt.SUN_AZIMUTH)])
    keep = np.degrees(np.arccos(np.clip(dirs @ sun_direction(sc.elev, bt.SUN_AZIMUTH), -1, 1))) > 2.27
    out = {}
    for tag, step in (("probe100", 100.0), ("probe10", 10.0)):
        s = replace(QUALITIES["final"].settings, spherical_probe_step_nm=step)
        t = time.perf_counter(); out[tag] = SkyMarcher(prof, sc.elev, bt.SUN_AZIMUTH, 0.0, s).radiance(dirs).radiance
        print(name, tag, f"{time.perf_counter()-t:.1f} s", flush=True)
    rel = out["probe100"][keep] / out["probe10"][keep] - 1
    i, j = np.unravel_index(np.abs(rel).argmax(), rel.shape)
    relY = (out["probe100"] @ cmf)[keep] / (out["probe10"] @ cmf)[keep] - 1
    print(f"  {name}: probes 100 nm vs every solver wavelength: spectral median {np.median(np.abs(rel))*100:.3f} %, worst {rel[i,j]*100:+.2f} % ({wl[j]:.0f} nm, {views[keep][i]}); XYZ max {np.abs(relY).max(0)*100}", flush=True)
