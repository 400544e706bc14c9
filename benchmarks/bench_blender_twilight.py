"""Volumetric twilight (issue 21): the layered profile the volumes hold, rendered by the core's
marcher, against the smooth atmosphere, for layer edges at equal shares of
``extinction(550 nm) ** a`` (a = 1: equal optical depth, the old edges; 0.3: the add-on's
``volumetric.EDGE_EXPONENT``). No bpy: the error measured is the layering's alone.

    .venv/bin/python benchmarks/bench_blender_twilight.py --elevations -4 0 10 --layers 8 16 24 \\
        --exponents 1 0.3 --width 64

One JSON line per case: sky above the horizon, relative luminance (rms, worst pixel, zenith).
About 6 s per render at 64x32 on the shared 2-core machine.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--elevations", type=float, nargs="+", default=[-4.0, 0.0, 10.0])
    ap.add_argument("--layers", type=int, nargs="+", default=[8, 16, 24])
    ap.add_argument("--exponents", type=float, nargs="+", default=[1.0, 0.3])
    ap.add_argument("--width", type=int, default=64)
    ap.add_argument("--location", default="rural")
    ap.add_argument("--month", type=int, default=6)
    a = ap.parse_args(argv)
    from bench_blender import _stats

    from blender_addon import physics, volumetric
    from skymodel.render.cameras import make_camera
    from skymodel.render.sky import render_sky
    from skymodel.wavelengths import default_wavelengths

    cam = make_camera("equirectangular", a.width, center_azimuth_deg=90.0)
    wl = default_wavelengths(volumetric.WAVELENGTH_STEP_NM)
    for el in a.elevations:
        sky = physics.resolve(physics.SkyParams(location=a.location, month=a.month, sun_elevation_deg=el,
                                                sun_azimuth_deg=180.0, mode="VOLUMETRIC"))
        prof = sky.profile(wl)
        smooth = render_sky(prof, cam, el, 180.0, 0.0, "preview", include_sun=False)
        smooth = physics.spectrum_rgb(smooth.radiance, wl)
        for n in a.layers:
            for x in a.exponents:
                lay = prof.layered(edges_m=volumetric.layer_edges(prof, n, exponent=x))
                rgb = physics.spectrum_rgb(render_sky(lay, cam, el, 180.0, 0.0, "preview", include_sun=False).radiance, wl)
                st = _stats(rgb, smooth, cam)
                print(json.dumps({"sun_elevation_deg": el, "layers": n, "exponent": x,
                                  "top_edges_km": [round(float(e) / 1000, 1) for e in lay.edges_m[-3:]],
                                  **{k: round(v, 4) for k, v in st.items() if isinstance(v, float)}}), flush=True)


if __name__ == "__main__":
    main()
