"""The ``skymodel`` command line: ``profile``, ``sun``, ``presets`` (and more as the
renderer lands). Every command takes ``--json`` for machine-readable output; errors in
the input print one line naming the parameter and exit with status 2."""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np

from skymodel.errors import SkymodelInputError


def _floats(text: str) -> list[float]:
    try:
        return [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated numbers, got {text!r}") from None


def add_atmosphere_arguments(p: argparse.ArgumentParser) -> None:
    """Options shared by every command that builds an atmosphere."""
    g = p.add_argument_group("atmosphere")
    g.add_argument("--location", default=None, help="location preset (see `skymodel presets`); default rural")
    g.add_argument("--lat", type=float, default=None, help="latitude, degrees north (-90..90)")
    g.add_argument("--lon", type=float, default=None, help="longitude, degrees east (-180..180)")
    g.add_argument("--month", type=int, default=None, help="month 1..12 (ozone climatology); default 6, or the month of --time")
    g.add_argument("--aerosol", default=None, help="tropospheric aerosol type or 'none'; default the location's")
    g.add_argument("--aod550", type=float, default=None, help="aerosol optical depth at 550 nm (0..10)")
    g.add_argument("--turbidity", type=float, default=None, help="(tau_R + tau_A) / tau_R at 550 nm (1..64)")
    g.add_argument("--stratospheric", default="background", help="background, volcanic or none")
    g.add_argument("--ozone-du", type=float, default=None, help="total ozone column, Dobson units")
    g.add_argument("--albedo", type=float, default=None, help="ground albedo 0..1; default the location's surface")
    g.add_argument("--altitudes", type=int, default=401, help="points of the altitude grid (default 401)")


def atmosphere_from_args(args):
    from skymodel.optics.atmosphere import Atmosphere

    location = args.location
    if location is None and (args.lat is None or args.lon is None or args.aerosol is None):
        location = "rural"
    month = args.month
    if month is None:
        month = _time_month(getattr(args, "time", None)) or 6
    return Atmosphere(
        location=location, month=month, latitude=args.lat, longitude=args.lon, aerosol=args.aerosol,
        aod550=args.aod550, turbidity=args.turbidity, stratospheric=args.stratospheric,
        ozone_du=args.ozone_du, albedo=args.albedo, n_altitudes=args.altitudes,
    )


def _time_month(text):
    if not text:
        return None
    import numpy as np

    try:
        return int(str(np.datetime64(str(text).rstrip("Zz"), "M")).split("-")[1])
    except ValueError:
        raise SkymodelInputError("time", text, "an ISO 8601 UTC date-time such as 2026-06-21T12:00:00Z") from None


def _size(text: str):
    try:
        parts = [int(v) for v in str(text).lower().split("x")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected WIDTH or WIDTHxHEIGHT, got {text!r}") from None
    if len(parts) not in (1, 2):
        raise argparse.ArgumentTypeError(f"expected WIDTH or WIDTHxHEIGHT, got {text!r}")
    return parts[0], (parts[1] if len(parts) == 2 else None)


def profile_summary(profile, layers: int | None = None) -> dict:
    """Column quantities per wavelength (and the layered atmosphere when ``layers``)."""
    p = profile
    tau_r = p.vertical_optical_depth(p.rayleigh_scattering)
    tau_o = p.vertical_optical_depth(p.ozone_absorption)
    sca = p.vertical_optical_depth(p.aerosol_scattering)
    ext = sca + p.vertical_optical_depth(p.aerosol_absorption)
    with np.errstate(invalid="ignore", divide="ignore"):
        ssa = np.where(ext > 0, sca / np.where(ext > 0, ext, 1.0), 1.0)
        mu = np.cos(np.radians(p.aerosol_phase_angles_deg))
        # asymmetry of the column-mean aerosol phase function (scattering-weighted regimes)
        w = np.stack([p.vertical_optical_depth(a) for a in p.aerosol_scattering_by_regime])  # (R, W)
        phase = (w[:, None, :] * p.aerosol_phase).sum(0) / np.where(w.sum(0) > 0, w.sum(0), 1.0)
        from skymodel.numerics import trapezoid

        g = -2 * np.pi * trapezoid(phase * mu[:, None], mu, axis=0)
    out = {
        "atmosphere": {k: v for k, v in p.metadata.items()},
        "wavelengths_nm": p.wavelengths_nm.tolist(),
        "rayleigh_optical_depth": tau_r.tolist(),
        "ozone_optical_depth": tau_o.tolist(),
        "aerosol_optical_depth": ext.tolist(),
        "aerosol_single_scattering_albedo": ssa.tolist(),
        "aerosol_asymmetry": g.tolist(),
        "ozone_column_du": p.metadata["ozone_du"],
        "angstrom_exponent": p.metadata["angstrom_exponent"],
        "solar_irradiance_W_m2_nm": p.solar_irradiance.tolist(),
    }
    if layers:
        lay = p.layered(n_layers=layers)
        dz = np.diff(lay.edges_m)[:, None]
        a_sca = lay.aerosol_scattering * dz
        a_ext = a_sca + lay.aerosol_absorption * dz
        with np.errstate(invalid="ignore", divide="ignore"):
            lay_ssa = np.where(a_ext > 0, a_sca / np.where(a_ext > 0, a_ext, 1.0), 1.0)
            wr = lay.aerosol_scattering_by_regime  # (R, L, W)
            lay_phase = (wr[:, :, None, :] * lay.aerosol_phase[:, None, :, :]).sum(0) / np.where(
                wr.sum(0) > 0, wr.sum(0), 1.0)[:, None, :]
        out["layers"] = {
            "edges_m": lay.edges_m.tolist(),
            "rayleigh_optical_depth": (lay.rayleigh_scattering * dz).tolist(),
            "ozone_optical_depth": (lay.ozone_absorption * dz).tolist(),
            "aerosol_optical_depth": a_ext.tolist(),
            "aerosol_single_scattering_albedo": lay_ssa.tolist(),
            "aerosol_phase_angles_deg": lay.aerosol_phase_angles_deg.tolist(),
            "aerosol_phase_function_sr-1": lay_phase.tolist(),
            "shape_note": "per-layer arrays are [layer][wavelength]; phase is [layer][angle][wavelength]",
        }
    return out


def _print_profile_table(s: dict) -> None:
    a = s["atmosphere"]
    print(f"location {a['location']}  lat {a['latitude_deg']:.2f}  lon {a['longitude_deg']:.2f}  month {a['month']}")
    print(f"aerosol {a['aerosol']} (stratospheric {a['stratospheric']})  AOD550 {a['aod550']:.4f}  "
          f"Angstrom {a['angstrom_exponent']:.3f}  ozone {a['ozone_du']:.1f} DU  albedo {a['albedo']:.2f}")
    print(f"{'nm':>6} {'tau_R':>9} {'tau_O3':>9} {'tau_aer':>9} {'ssa':>6} {'g':>6}")
    for i, wl in enumerate(s["wavelengths_nm"]):
        print(f"{wl:6.1f} {s['rayleigh_optical_depth'][i]:9.5f} {s['ozone_optical_depth'][i]:9.5f} "
              f"{s['aerosol_optical_depth'][i]:9.5f} {s['aerosol_single_scattering_albedo'][i]:6.3f} "
              f"{s['aerosol_asymmetry'][i]:6.3f}")
    if "layers" in s:
        print("layers (edges in km):", ", ".join(f"{e / 1000:.2f}" for e in s["layers"]["edges_m"]))


def cmd_profile(args) -> int:
    atm = atmosphere_from_args(args)
    prof = atm.optical_profile(args.wavelengths)
    s = profile_summary(prof, args.layers)
    if args.json:
        json.dump(s, sys.stdout, indent=1)
        print()
    else:
        _print_profile_table(s)
    return 0


def cmd_sun(args) -> int:
    from skymodel import sun

    pos = sun.solar_position(args.lat, args.lon, args.time, refraction=args.refraction)
    out = {
        "latitude_deg": args.lat, "longitude_deg": args.lon, "time_utc": args.time,
        "elevation_deg": float(np.asarray(pos.elevation_deg)), "azimuth_deg": float(np.asarray(pos.azimuth_deg)),
        "earth_sun_distance_au": float(np.asarray(pos.earth_sun_distance_au)),
        "refraction": bool(args.refraction),
    }
    if args.json:
        print(json.dumps(out, indent=1))
    else:
        print(f"elevation {out['elevation_deg']:.4f} deg, azimuth {out['azimuth_deg']:.4f} deg (clockwise from north), "
              f"distance {out['earth_sun_distance_au']:.5f} AU")
    return 0


def cmd_presets(args) -> int:
    from skymodel.optics import aerosols, ground
    from skymodel.optics.atmosphere import locations

    out = {
        "locations": {k: {kk: v[kk] for kk in ("latitude", "longitude", "aerosol", "surface", "description") if kk in v}
                      for k, v in locations().items()},
        "aerosol_types": list(aerosols.aerosol_types()),
        "aerosol_components": list(aerosols.components()),
        "surfaces": ground.surfaces(),
    }
    if args.json:
        print(json.dumps(out, indent=1))
    else:
        print("locations:")
        for k, v in out["locations"].items():
            print(f"  {k:18s} {v['latitude']:7.2f} {v['longitude']:8.2f}  {v['aerosol']:18s} {v['surface']:8s} {v.get('description', '')}")
        print("aerosol types:", ", ".join(out["aerosol_types"]))
        print("aerosol components:", ", ".join(out["aerosol_components"]))
        print("surfaces:", ", ".join(f"{k} ({v:.2f})" for k, v in out["surfaces"].items()))
    return 0


def add_sun_arguments(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("sun and observer")
    g.add_argument("--sun-elevation", type=float, default=None, help="degrees above the horizon (-12..90); default 25")
    g.add_argument("--sun-azimuth", type=float, default=None, help="degrees clockwise from north; default 180")
    g.add_argument("--time", default=None, help="UTC date-time: place the sun from --lat/--lon (or the location)")
    g.add_argument("--observer-altitude", type=float, default=0.0, help="metres above the ground (0..120000)")


def sun_from_args(args, atm):
    """(elevation, azimuth, earth-sun distance in AU) from --sun-* or --time."""
    from skymodel.errors import check_range

    if args.time is not None:
        if args.sun_elevation is not None or args.sun_azimuth is not None:
            raise SkymodelInputError("time", args.time, "either --time or --sun-elevation/--sun-azimuth, not both")
        from skymodel import sun

        pos = sun.solar_position(atm.latitude, atm.longitude, args.time)
        elev, az = float(np.asarray(pos.elevation_deg)), float(np.asarray(pos.azimuth_deg))
        dist = float(np.asarray(pos.earth_sun_distance_au))
    else:
        elev = 25.0 if args.sun_elevation is None else args.sun_elevation
        az = 180.0 if args.sun_azimuth is None else args.sun_azimuth
        dist = 1.0
    check_range("sun_elevation", elev, -12.0, 90.0, "degrees (below -12 the sky is night: use -12)")
    check_range("sun_azimuth", az, -360.0, 360.0, "degrees")
    return elev, az % 360.0, dist


class _Progress:
    def __init__(self, quiet: bool):
        self.quiet = quiet
        self.t0 = __import__("time").perf_counter()

    def stage(self, text):
        if not self.quiet:
            print(f"[{__import__('time').perf_counter() - self.t0:6.1f}s] {text}", file=sys.stderr, flush=True)

    def order(self, n, size):
        if not self.quiet:
            bar = "#" * min(n, 30)
            print(f"\r[{__import__('time').perf_counter() - self.t0:6.1f}s] scattering order {n:2d} "
                  f"(adds {size:.2%}) {bar}", end="", file=sys.stderr, flush=True)


def cmd_render(args) -> int:
    from dataclasses import replace as dc_replace

    from skymodel.render import image_io
    from skymodel.render.cameras import make_camera
    from skymodel.render.sky import quality_settings, render_sky
    from skymodel.wavelengths import default_wavelengths

    prog = _Progress(args.quiet)
    atm = atmosphere_from_args(args)
    elev, az, dist = sun_from_args(args, atm)
    settings = quality_settings(args.quality)
    wl = default_wavelengths(args.wavelength_step)
    width, height = args.size
    camera = make_camera(args.camera, width, height, n_wavelengths=wl.size)
    png = None if args.no_png else (args.png or (str(args.out).rsplit(".", 1)[0] + ".png"))
    # validate every output path before the (long) render, so nothing is half-written
    for key, path, ext in (("out", args.out, ".exr"), ("png", png, ".png"), ("spectral", args.spectral, ".npz")):
        if path is not None:
            image_io.check_output_path(key, path, (ext,))
    prog.stage(f"atmosphere: {atm.location or 'custom'}, month {atm.month}, aerosol {atm.aerosol}; "
               f"sun elevation {elev:.2f}, azimuth {az:.2f}; {camera.name} {camera.width}x{camera.height}, "
               f"{wl.size} wavelengths, quality {args.quality}")
    profile = atm.optical_profile(wl)
    if dist != 1.0:
        profile = dc_replace(profile, solar_irradiance=profile.solar_irradiance / dist**2)
    img = render_sky(profile, camera, elev, az, args.observer_altitude, settings, include_sun=not args.no_sun,
                     progress=prog.order)
    if not args.quiet:
        print(file=sys.stderr)
    prog.stage(f"rendered in {img.info['total_s']:.1f}s ({img.info['orders']} scattering orders)")
    written = image_io.save_outputs(out=args.out, png=png, spectral=args.spectral, radiance=img.radiance,
                                    wavelengths=wl, camera=camera, exposure_ev=args.exposure, colour_space="xyz" if args.xyz else "rec709",
                                    metadata={"atmosphere": profile.metadata, "sun_elevation_deg": elev,
                                              "sun_azimuth_deg": az, "observer_altitude_m": args.observer_altitude,
                                              "quality": args.quality})
    for path in written.values():
        prog.stage(f"wrote {path}")
    return 0


def cmd_radiance(args) -> int:
    from dataclasses import replace as dc_replace

    from skymodel.render.marcher import SkyMarcher
    from skymodel.render.rays import direction_from_angles
    from skymodel.render.sky import quality_settings

    atm = atmosphere_from_args(args)
    elev, az, dist = sun_from_args(args, atm)
    profile = atm.optical_profile(args.wavelengths)
    if dist != 1.0:
        profile = dc_replace(profile, solar_irradiance=profile.solar_irradiance / dist**2)
    settings = dc_replace(quality_settings(args.quality), exact=True)
    zen = np.asarray(args.view_zenith, float)
    rel = np.asarray(args.relative_azimuth, float)
    if np.any((zen < 0) | (zen > 180)):
        raise SkymodelInputError("view_zenith", args.view_zenith, "angles in [0, 180] degrees")
    zz, rr = np.meshgrid(zen, rel, indexing="ij")
    d = direction_from_angles(zz.ravel(), (az + rr.ravel()) % 360.0)
    res = SkyMarcher(profile, elev, az, args.observer_altitude, settings).radiance(d)
    out = {
        "units": {"radiance": "W m^-2 sr^-1 nm^-1", "solar_irradiance_toa": "W m^-2 nm^-1", "angles": "degrees"},
        "atmosphere": profile.metadata, "sun_elevation_deg": elev, "sun_azimuth_deg": az,
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


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="skymodel", description="Physically based spectral sky and atmosphere.")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("profile", help="per-wavelength optical depths of an atmosphere")
    add_atmosphere_arguments(p)
    p.add_argument("--wavelengths", type=_floats, default=None, help="comma-separated nm (default 380..780 by 5)")
    p.add_argument("--layers", type=int, default=None, help="also print N piecewise-constant layers")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_profile)

    p = sub.add_parser("sun", help="solar elevation and azimuth for a place and UTC time")
    p.add_argument("--lat", type=float, required=True, help="latitude, degrees north")
    p.add_argument("--lon", type=float, required=True, help="longitude, degrees east")
    p.add_argument("--time", required=True, help="UTC date-time, ISO 8601 (e.g. 2026-06-21T12:00:00Z)")
    p.add_argument("--refraction", action="store_true", help="apparent elevation (with standard refraction)")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_sun)

    p = sub.add_parser("presets", help="list locations, aerosol types, components and surfaces")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_presets)

    p = sub.add_parser("render", help="render a sky image (EXR, PNG preview, spectral NPZ)")
    add_atmosphere_arguments(p)
    add_sun_arguments(p)
    p.add_argument("--camera", default="equirectangular", help="equirectangular, fisheye or dome")
    p.add_argument("--size", type=_size, default=(512, None), help="WIDTH or WIDTHxHEIGHT in pixels (default 512)")
    p.add_argument("--quality", default="preview", help="preview, final or reference (default preview)")
    p.add_argument("--wavelength-step", type=float, default=5.0, help="spectral sampling in nm (default 5)")
    p.add_argument("--out", default="sky.exr", help="scene-linear float EXR (default sky.exr)")
    p.add_argument("--png", default=None, help="tone-mapped PNG preview (default: the EXR name with .png)")
    p.add_argument("--no-png", action="store_true", help="write no PNG")
    p.add_argument("--spectral", default=None, help="also save the spectral cube as .npz")
    p.add_argument("--xyz", action="store_true", help="EXR channels X, Y, Z instead of Rec.709 R, G, B")
    p.add_argument("--exposure", type=float, default=None, help="PNG exposure in EV relative to auto")
    p.add_argument("--no-sun", action="store_true", help="leave the solar disc out of the image")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=cmd_render)

    p = sub.add_parser("radiance", help="spectral radiance for listed view directions (point queries)")
    add_atmosphere_arguments(p)
    add_sun_arguments(p)
    p.add_argument("--view-zenith", type=_floats, default=[0.0, 30.0, 60.0, 80.0], help="degrees, comma-separated")
    p.add_argument("--relative-azimuth", type=_floats, default=[0.0, 90.0, 180.0],
                   help="degrees from the sun's azimuth (0 = toward the sun), comma-separated")
    p.add_argument("--wavelengths", type=_floats, default=None, help="nm, comma-separated (default 380..780 by 5)")
    p.add_argument("--quality", default="final", help="preview, final or reference (default final)")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_radiance)

    from skymodel.cli.compare import add_compare_command  # `skymodel compare` (sky models side by side)

    add_compare_command(sub)

    from skymodel.validation.accuracy import add_bench_command  # `skymodel bench accuracy` (what accuracy costs in time)

    add_bench_command(sub)

    for register in _EXTRA_COMMANDS:
        register(sub)
    return parser


#: Sub-command registrars added by other modules (renderer, benchmarks) — each takes the subparsers object.
_EXTRA_COMMANDS: list = []


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except SkymodelInputError as exc:
        print(f"skymodel {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
