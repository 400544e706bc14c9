"""The solver's wavelengths carried to the render's: linear against the ozone-aware log map
(skymodel.render.solver_spectrum), each against a solve at every 5-nm render wavelength.

    python notebooks/solver_spectrum/measure.py [scenes] [steps]      # e.g. rural:20,rural:-4 10,40

For each scene (bench_truth's atmospheres; `final` settings otherwise) the field is solved once
at all 81 wavelengths (380-780 nm); the solver wavelengths of a step are every k-th of them
(exactly what `solver_wavelengths` picks), and the sky is marched on the truth's views plus a
grid (zenith 0-89.5, azimuth from the sun 0-180 every 10 degrees) with each map. Prints
|rel| over the views more than 2.27 degrees from the sun: spectral median and max (where),
CIE XYZ median and max; and once, at the end, `final` as the package builds it (its own 10-nm
solve) against the same map on the 81-wavelength solve (what the subsampling leaves out)."""
import sys
import time
from pathlib import Path

import numpy as np

sys.path[:0] = [str(Path(__file__).resolve().parents[2] / "benchmarks")]
import bench_truth as bt  # noqa: E402
from _setup import LinearMap, every_wavelength_scene, sub_solution  # noqa: E402
from skymodel.colorimetry import cmf_weights  # noqa: E402
from skymodel.render.marcher import SkyMarcher, solve_sky  # noqa: E402
from skymodel.render.quality import QUALITIES  # noqa: E402
from skymodel.render.solver_spectrum import SolverSpectrumMap  # noqa: E402
from skymodel.wavelengths import default_wavelengths  # noqa: E402

scenes = (sys.argv[1] if len(sys.argv) > 1 else "rural:60,rural:20,rural:5,rural:-4,desert:60,desert:0,desert:-4")
steps = [int(v) for v in (sys.argv[2] if len(sys.argv) > 2 else "10,20,40").split(",")]
wl = default_wavelengths(5.0)
cmf = cmf_weights(wl)


def stats(r, full, keep, views):
    rel = r[keep] / full[keep] - 1
    rel_xyz = (r @ cmf)[keep] / (full @ cmf)[keep] - 1
    i, j = np.unravel_index(np.abs(rel).argmax(), rel.shape)
    z, a = views[keep][i]
    return (f"{np.median(np.abs(rel)) * 100:.3f} | {rel[i, j] * 100:+.2f} ({wl[j]:.0f} nm, {z:g}/{a:g}) | "
            + "/".join(f"{v:.3f}" for v in np.median(np.abs(rel_xyz), 0) * 100) + " | "
            + "/".join(f"{v:.3f}" for v in np.abs(rel_xyz).max(0) * 100))


print("| scene | step | map | spectral median | spectral worst (where) | XYZ median | XYZ max |")
print("|---|---|---|---|---|---|---|")
last = None
for name in scenes.split(","):
    sc, prof, views, dirs, keep, s = every_wavelength_scene(name, wl)
    t = time.perf_counter()
    sol = solve_sky(prof, s)
    solve_s = time.perf_counter() - t

    def render(solution, settings=s):
        return SkyMarcher(prof, sc.elev, bt.SUN_AZIMUTH, 0.0, settings, solution=solution).radiance(dirs).radiance

    full = render(sol)
    for step in steps:
        idx = np.arange(0, wl.size, step // 5)
        m = SolverSpectrumMap.for_profile(wl[idx], prof)
        for label, to_full in (("linear", LinearMap(m.linear)), ("log, ozone", m)):
            r = render(sub_solution(sol, prof, idx, to_full))
            print(f"| {name} | {step} nm | {label} | {stats(r, full, keep, views)} |", flush=True)
    print(f"(solve at 81 wavelengths {solve_s:.0f} s)", file=sys.stderr, flush=True)
    last = (name, prof, render, full, keep, views, sol)

# the package's own `final` (its 10-nm solve) against the 81-wavelength solve with the same map
name, prof, render, full, keep, views, sol = last
own = render(None, QUALITIES["final"].settings)
idx = np.arange(0, wl.size, 2)
sub = render(sub_solution(sol, prof, idx, SolverSpectrumMap.for_profile(wl[idx], prof)))
print(f"\n{name}: `final` as built against the subsampled 81-wavelength solve: "
      f"max |rel| {np.abs(own[keep] / sub[keep] - 1).max() * 100:.3f} %; against the 81-wavelength solve: "
      + stats(own, full, keep, views))
