"""``skymodel sun``: solar elevation and azimuth for a place and UTC time."""

from __future__ import annotations

import json

import numpy as np

from skymodel.cli.options import add_option


def add_command(sub) -> None:
    """Register ``skymodel sun`` on the CLI's subparsers."""
    p = sub.add_parser("sun", help="solar elevation and azimuth for a place and UTC time")
    add_option(p, "latitude", required=True)
    add_option(p, "longitude", required=True)
    add_option(p, "time_utc", required=True)
    add_option(p, "timezone")
    p.add_argument("--refraction", action="store_true", help="apparent elevation (with standard refraction)")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_sun)


def cmd_sun(args) -> int:
    from skymodel import scene, sun

    instant = scene.resolve_time(args.time_utc, args.timezone, args.latitude, args.longitude)
    pos = sun.solar_position(args.latitude, args.longitude, instant.utc_iso, refraction=args.refraction)
    out = {
        "latitude_deg": args.latitude, "longitude_deg": args.longitude, "time_utc": instant.utc_iso,
        "time_local": instant.local_iso, "timezone": instant.timezone,
        "elevation_deg": float(np.asarray(pos.elevation_deg)), "azimuth_deg": float(np.asarray(pos.azimuth_deg)),
        "earth_sun_distance_au": float(np.asarray(pos.earth_sun_distance_au)),
        "refraction": bool(args.refraction),
    }
    if args.json:
        print(json.dumps(out, indent=1))
    else:
        print(f"{instant.utc_iso} ({instant.local_iso} {instant.timezone}): "
              f"elevation {out['elevation_deg']:.4f} deg, azimuth {out['azimuth_deg']:.4f} deg (clockwise from north), "
              f"distance {out['earth_sun_distance_au']:.5f} AU")
    return 0
