"""Single-setting variants of a quality preset against the cached accuracy reference, at
512x256 (the table in README.md beside it). Needs the reference of the
scene in the cache (run `skymodel bench accuracy` first).

    nice -n 10 python notebooks/preset_tuning/accuracy_variants.py twilight

prints, for each variant, wall and CPU seconds, the mean and max relative radiance error
and the mean CIEDE2000, exactly as `skymodel bench accuracy` computes them.
"""

from __future__ import annotations

import sys
from dataclasses import replace

import numpy as np

from skymodel.validation import accuracy as a
from skymodel.render.image_io import auto_exposure_luminance
from skymodel.render.sky import QUALITY


def variants():
    p, f = QUALITY["preview"], QUALITY["final"]
    return {
        "preview": p,
        "preview table_mus 48": replace(p, table_mus=48),
        "preview table_altitudes 16": replace(p, table_altitudes=16),
        "preview view_steps 64": replace(p, view_steps=64),
        "preview table_mu 24, table_phi 12": replace(p, table_mu=24, table_phi=12),
        "final": f,
        "final table_altitudes 24, table_steps 48": replace(f, table_altitudes=24, table_steps=48),
        "final table_mu 48, table_phi 16": replace(f, table_mu=48, table_phi=16),
        "final ms_wavelength_step_nm 20": replace(f, ms_wavelength_step_nm=20.0),
        "final view_steps 128": replace(f, view_steps=128),
    }


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    scene = argv[0] if argv else "twilight"
    cfg = a.full_config()
    elev = a.SCENES[scene]
    _, ref = a.preset_run(cfg, scene, "__reference__", True)
    cam = a.camera(cfg.preset_width, cfg.preset_height)
    dirs, _ = cam.directions()
    mask = a.sky_mask(cam, elev)
    w = np.where(mask, cam.pixel_solid_angles(), 0.0)
    R, wl = ref["cam0"], ref["wavelengths_nm"]
    avg = auto_exposure_luminance(a.rgb_of(R, wl), mask)
    prof = a.base_profile()
    print(f"| variant ({scene}, {cfg.preset_width}x{cfg.preset_height}) | mean rel. error | max | ΔE00 mean | wall (s) | CPU (s) |")
    print("|---|---|---|---|---|---|")
    for name, s in variants().items():
        rad, dt, info = a.render_directions(prof, s, elev, dirs.reshape(-1, 3))
        e = a.errors(rad.reshape(dirs.shape[:-1] + (-1,)), wl, R, wl, w, avg)
        print(f"| {name} | {100 * e['radiance_rel_mean']:.2f} % | {100 * e['radiance_rel_max']:.0f} % | "
              f"{e['de2000_mean']:.2f} | {dt:.1f} | {info['cpu_s']:.1f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
