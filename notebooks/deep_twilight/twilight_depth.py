"""How dark is the sunlit sky at -12, -15 and -18 degrees next to the natural night glow, and
can the Monte Carlo tracer check the marcher there?

    nice -n 10 python notebooks/deep_twilight/twilight_depth.py      # about 2 minutes

Zenith radiance at 545 nm from SkyMarcher (default settings; the renderer's scene bound is
-12, the marcher itself accepts any elevation) for a Rayleigh-only and the rural sky, June,
in V mag/arcsec^2, against the dark-sky zenith of skymodel.astro.night_background (V 21.9,
Benn & Ellison 1998); and the Monte Carlo tracer's estimate with 400000 paths per direction.
"""

import time

import numpy as np

from skymodel import Atmosphere
from skymodel.astro.night_background import dark_sky_zenith_radiance, radiance_to_surface_brightness
from skymodel.render.marcher import SkyMarcher
from skymodel.validation.montecarlo import trace_radiance

WL = np.array([545.0])
ZENITH = np.array([[0.0, 0.0, 1.0]])


def main():
    glow = float(dark_sky_zenith_radiance(WL)[0])
    print("| sky | sun (deg) | marcher zenith V (mag/arcsec^2) | sunlit / natural glow | MC, 400k paths: non-zero estimate? | MC time (s) |")
    print("|---|---|---|---|---|---|")
    for name, kw in (("Rayleigh only", dict(aerosol="none")), ("rural", {})):
        prof = Atmosphere(location="rural", month=6, **kw).optical_profile(WL)
        for el in (-12.0, -15.0, -18.0):
            lz = float(SkyMarcher(prof, el, 180.0).radiance(ZENITH).radiance[0, 0])
            t0 = time.perf_counter()
            mc = trace_radiance(prof, ZENITH, el, 180.0, n_paths=400_000, seed=1)
            dt = time.perf_counter() - t0
            v = float(radiance_to_surface_brightness(lz, "V"))
            hit = "yes" if mc.radiance[0, 0] > 0 else "no (0)"
            print(f"| {name} | {el:g} | {v:.2f} | {lz / glow:.3g} | {hit}, rel. se {mc.stderr[0, 0] / max(mc.radiance[0, 0], 1e-300):.2f} | {dt:.0f} |"
                  if mc.radiance[0, 0] > 0 else f"| {name} | {el:g} | {v:.2f} | {lz / glow:.3g} | {hit} | {dt:.0f} |",
                  flush=True)


if __name__ == "__main__":
    main()
