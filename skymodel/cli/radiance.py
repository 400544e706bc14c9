"""``skymodel radiance``: spectral radiance for listed view directions (point queries)."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np

from skymodel import scene
from skymodel.cli.options import (add_atmosphere_arguments, add_option, add_sun_arguments, atmosphere_from_args,
                                  floats, profile_for_sun, sun_from_args)


def add_command(sub) -> None:
    """Register ``skymodel radiance`` on the CLI's subparsers."""
    p = sub.add_parser("radiance", help="spectral radiance for listed view directions (point queries)")
    add_atmosphere_arguments(p)
    add_sun_arguments(p)
    add_option(p, "view_zenith", type=floats, default=[0.0, 30.0, 60.0, 80.0], note="comma-separated")
    p.add_argument("--relative-azimuth", type=floats, default=[0.0, 90.0, 180.0],
                   help="degrees from the sun's azimuth (0 = toward the sun), comma-separated")
    p.add_argument("--wavelengths", type=floats, default=None, help="nm, comma-separated (default 380..780 by 5)")
    add_option(p, "quality", note="every direction is evaluated exactly (no direction grid)")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_radiance)


def cmd_radiance(args) -> int:
    from skymodel.render.marcher import SkyMarcher
    from skymodel.render.quality import quality_settings
    from skymodel.render.rays import direction_from_angles

    atm = atmosphere_from_args(args)
    sun = sun_from_args(args, atm)
    settings = replace(quality_settings(scene.check("quality", args.quality)), exact=True)
    zen = np.asarray(args.view_zenith, float)
    rel = np.asarray(args.relative_azimuth, float)
    view = scene.parameter("view_zenith")
    if np.any(~((zen >= view.minimum) & (zen <= view.maximum))):
        from skymodel.errors import SkymodelInputError

        raise SkymodelInputError("view_zenith", args.view_zenith, "angles in " + view.range_text())
    profile = profile_for_sun(atm, args.wavelengths, sun)
    zz, rr = np.meshgrid(zen, rel, indexing="ij")
    d = direction_from_angles(zz.ravel(), (sun.azimuth_deg + rr.ravel()) % 360.0)
    res = SkyMarcher(profile, sun.elevation_deg, sun.azimuth_deg, args.observer_altitude, settings).radiance(d)
    out = {
        "units": {"radiance": "W m^-2 sr^-1 nm^-1", "solar_irradiance_toa": "W m^-2 nm^-1", "angles": "degrees"},
        "atmosphere": profile.metadata, "sun_elevation_deg": sun.elevation_deg, "sun_azimuth_deg": sun.azimuth_deg,
        "observer_altitude_m": args.observer_altitude, "wavelengths_nm": profile.wavelengths_nm.tolist(),
        "solar_irradiance_toa": profile.solar_irradiance.tolist(),
        "direct_solar_irradiance_at_observer": res.sun_irradiance.tolist(),
        "directions": [{"view_zenith_deg": float(z), "relative_azimuth_deg": float(r), "radiance": res.radiance[i].tolist()}
                       for i, (z, r) in enumerate(zip(zz.ravel(), rr.ravel()))],
    }
    if args.json:
        print(json.dumps(out, indent=1))
    else:
        wl = profile.wavelengths_nm
        print("view_zen rel_az " + " ".join(f"{w:9.1f}" for w in wl))
        for item in out["directions"]:
            print(f"{item['view_zenith_deg']:8.2f} {item['relative_azimuth_deg']:6.1f} "
                  + " ".join(f"{v:9.3e}" for v in item["radiance"]))
        print("E_toa          " + " ".join(f"{v:9.4f}" for v in profile.solar_irradiance))
    return 0
