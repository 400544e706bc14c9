"""``skymodel radiance``: spectral radiance for listed view directions (point queries)."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np

from skymodel import scene
from skymodel.cli.options import (add_atmosphere_arguments, add_option, add_sun_arguments, add_wavelengths_argument,
                                  atmosphere_from_args, number_list, profile_for_sun, sun_from_args,
                                  wavelengths_from_args)


def add_command(sub) -> None:
    """Register ``skymodel radiance`` on the CLI's subparsers."""
    p = sub.add_parser("radiance", help="spectral radiance for listed view directions (point queries)")
    add_atmosphere_arguments(p)
    add_sun_arguments(p)
    add_option(p, "view_zenith", type=str, default="0,30,60,80", note="comma-separated")
    p.add_argument("--relative-azimuth", default="0,90,180",
                   help="degrees from the sun's azimuth (0 = toward the sun), comma-separated "
                        f"({scene.parameter('sun_azimuth').range_text()})")
    add_wavelengths_argument(p)
    add_option(p, "quality", note="every direction is evaluated exactly (no direction grid)")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_radiance)


def cmd_radiance(args) -> int:
    from skymodel.render.marcher import SkyMarcher
    from skymodel.render.quality import quality_settings
    from skymodel.render.rays import direction_from_angles

    # every input checked before the atmosphere or the marcher is built
    zen = np.asarray(number_list("view_zenith", args.view_zenith, check="view_zenith"))
    rel = np.asarray(number_list("relative_azimuth", args.relative_azimuth, check="sun_azimuth"))
    wl, back = wavelengths_from_args(args)  # the core works on an ascending grid; answered in the user's order
    settings = replace(quality_settings(scene.check("quality", args.quality)), exact=True)
    atm = atmosphere_from_args(args)
    sun = sun_from_args(args, atm)
    profile = profile_for_sun(atm, wl, sun)
    zz, rr = np.meshgrid(zen, rel, indexing="ij")
    d = direction_from_angles(zz.ravel(), (sun.azimuth_deg + rr.ravel()) % 360.0)
    res = SkyMarcher(profile, sun.elevation_deg, sun.azimuth_deg, args.observer_altitude, settings).radiance(d)
    out = {
        "units": {"radiance": "W m^-2 sr^-1 nm^-1", "solar_irradiance_toa": "W m^-2 nm^-1", "angles": "degrees"},
        "atmosphere": profile.metadata, "sun_elevation_deg": sun.elevation_deg, "sun_azimuth_deg": sun.azimuth_deg,
        "observer_altitude_m": args.observer_altitude, "wavelengths_nm": profile.wavelengths_nm[back].tolist(),
        "solar_irradiance_toa": profile.solar_irradiance[back].tolist(),
        "direct_solar_irradiance_at_observer": np.asarray(res.sun_irradiance)[..., back].tolist(),
        "directions": [{"view_zenith_deg": float(z), "relative_azimuth_deg": float(r),
                        "radiance": res.radiance[i][back].tolist()}
                       for i, (z, r) in enumerate(zip(zz.ravel(), rr.ravel()))],
    }
    if args.json:
        print(json.dumps(out, indent=1))
    else:
        wl = profile.wavelengths_nm[back]
        print("view_zen rel_az " + " ".join(f"{w:9.1f}" for w in wl))
        for item in out["directions"]:
            print(f"{item['view_zenith_deg']:8.2f} {item['relative_azimuth_deg']:6.1f} "
                  + " ".join(f"{v:9.3e}" for v in item["radiance"]))
        print("E_toa          " + " ".join(f"{v:9.4f}" for v in profile.solar_irradiance[back]))
    return 0
