"""The marcher of today at the zenith at sun -12, -15, -18 deg against the stored Monte Carlo values.

    nice -n 5 python notebooks/deep_twilight/remeasure_zenith.py [--presets preview,final]   # ~1-2 min

The MC radiances are the README's table (``mc_vs_marcher.py mc --minutes 31``, tracer of commit
79cae72, 40,000 paths per direction and band, rural June, view 0/0); the marcher is run now with
the same medium, bands and geometry as ``mc_vs_marcher.py marcher``, so a change of the marcher
since that run shows here. Prints marcher / MC - 1 (%) with the MC's standard error.
"""

from __future__ import annotations

import argparse
import os
import sys

import numpy as np

_HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:0] = [os.path.join(_HERE, "..", "..")]

from skymodel import Atmosphere  # noqa: E402

BANDS = np.array([450.0, 550.0, 650.0])
#: notebooks/deep_twilight/README.md, view 0/0: MC radiance (W m-2 sr-1 nm-1) and se (%) at 450/550/650 nm.
MC = {-12.0: ((4.51e-08, 1.06e-08, 1.14e-08), (13.5, 3.2, 5.2)),
      -15.0: ((2.35e-09, 6.02e-10, 5.78e-10), (7.6, 6.0, 9.5)),
      -18.0: ((6.33e-11, 1.75e-11, 2.53e-11), (6.1, 7.7, 12.7))}


def main():
    from skymodel.render.marcher import SkyMarcher
    from skymodel.render.quality import quality_settings

    ap = argparse.ArgumentParser()
    ap.add_argument("--presets", default="preview,final")
    args = ap.parse_args()
    prof = Atmosphere(location="rural", month=6).optical_profile(BANDS)
    zen = np.array([[0.0, 0.0, 1.0]])
    print("| sun (deg) | preset | marcher / MC - 1 at 450/550/650 nm (%) | MC se (%) |")
    print("|---|---|---|---|")
    for preset in args.presets.split(","):
        s = quality_settings(preset)
        for el, (mc, se) in MC.items():
            m = SkyMarcher(prof, el, 180.0, 0.0, s).radiance(zen).radiance[0]
            d = "/".join(f"{100 * (a / b - 1):+.0f}" for a, b in zip(m, mc))
            print(f"| {el:g} | {preset} | {d} | {'/'.join(f'{x:g}' for x in se)} |", flush=True)


if __name__ == "__main__":
    main()
