"""The solver's wavelengths thinned outside the eye's band: 10 nm inside [lo, hi], 20 nm outside,
against a solve at every 5-nm wavelength (`final` settings otherwise), through the log-ozone map.

    python notebooks/solver_spectrum/outer_step.py rural:-4,desert:0,rural:20,desert:-4

Grids (indices into the 81 render wavelengths, 380-780 nm): u10 = every 10 nm (41, `final` before
2026-11-29), n440-660 = 10 nm over 440-660 and 20 nm beyond (32, `final` since), n420-680 (34),
n400-700 (36), u20 = every 20 nm (21). Prints, over the truth's views and a grid more than 2.27
degrees from the sun: spectral median |rel| and worst (wavelength), CIE XYZ median and max |rel|, %."""
import sys
from pathlib import Path

import numpy as np

sys.path[:0] = [str(Path(__file__).resolve().parents[2] / "benchmarks"), str(Path(__file__).resolve().parent)]
import bench_truth as bt  # noqa: E402
from _setup import every_wavelength_scene, sub_solution  # noqa: E402
from skymodel.colorimetry import cmf_weights  # noqa: E402
from skymodel.render.marcher import SkyMarcher, solve_sky  # noqa: E402
from skymodel.render.solver_spectrum import SolverSpectrumMap  # noqa: E402
from skymodel.wavelengths import default_wavelengths  # noqa: E402

scenes = sys.argv[1] if len(sys.argv) > 1 else "rural:-4,desert:0,rural:20,desert:-4"
wl = default_wavelengths(5.0)
cmf = cmf_weights(wl)


def grid(lo, hi, outer):
    keep = set(np.arange(380, 781, outer)) | set(np.arange(lo, hi + 1, 10)) | {380, 780}
    return np.array([int(np.argmin(abs(wl - x))) for x in sorted(keep)])


grids = {"u10": np.arange(0, 81, 2), "n440-660": grid(440, 660, 20), "n420-680": grid(420, 680, 20),
         "n400-700": grid(400, 700, 20), "u20": np.arange(0, 81, 4)}


def stats(r, full, keep):
    rel = r[keep] / full[keep] - 1
    rx = (r @ cmf)[keep] / (full @ cmf)[keep] - 1
    i, j = np.unravel_index(np.abs(rel).argmax(), rel.shape)
    return (f"{np.median(np.abs(rel)) * 100:.3f} | {rel[i, j] * 100:+.2f} ({wl[j]:.0f}) | "
            + "/".join(f"{v:.3f}" for v in np.median(np.abs(rx), 0) * 100) + " | "
            + "/".join(f"{v:.3f}" for v in np.abs(rx).max(0) * 100))


print("| scene | grid (solver wavelengths) | spectral median | spectral worst (nm) | XYZ median | XYZ max |")
print("|---|---|---|---|---|---|")
for name in scenes.split(","):
    sc, prof, views, dirs, keep, s = every_wavelength_scene(name, wl)
    sol = solve_sky(prof, s)

    def render(solution):
        return SkyMarcher(prof, sc.elev, bt.SUN_AZIMUTH, 0.0, s, solution=solution).radiance(dirs).radiance

    full = render(sol)
    for g, idx in grids.items():
        r = render(sub_solution(sol, prof, idx, SolverSpectrumMap.for_profile(wl[idx], prof)))
        print(f"| {name} | {g} ({idx.size}) | {stats(r, full, keep)} |", flush=True)
