"""``skymodel render``: a sky image (scene-linear EXR, PNG preview, spectral NPZ)."""

from __future__ import annotations

import sys
import time

import numpy as np

from skymodel import scene
from skymodel.cli.options import (add_atmosphere_arguments, add_option, add_sun_arguments, atmosphere_from_args,
                                  profile_for_sun, size, sun_from_args)
from skymodel.errors import SkymodelInputError


#: Pixels whose spectra the colour render holds at once (render_sky_reduced's band).
REDUCED_BAND_PIXELS = 1 << 20
#: ... and the dtype of the colour image it keeps (each band computed in float64; the EXR is float32).
REDUCED_DTYPE = "float32"


def add_command(sub) -> None:
    """Register ``skymodel render`` on the CLI's subparsers."""
    p = sub.add_parser("render", help="render a sky image (EXR, PNG preview, spectral NPZ)")
    add_atmosphere_arguments(p)
    add_sun_arguments(p)
    add_option(p, "camera")
    add_option(p, "image_width", type=size, default=(scene.default("image_width"), None), metavar="WIDTH[xHEIGHT]",
               note="WIDTH or WIDTHxHEIGHT")
    add_option(p, "quality")
    add_option(p, "wavelength_step")
    p.add_argument("--out", default="sky.exr", help="scene-linear float EXR (default sky.exr)")
    p.add_argument("--png", default=None, help="tone-mapped PNG preview (default: the EXR name with .png)")
    p.add_argument("--no-png", action="store_true", help="write no PNG")
    p.add_argument("--spectral", default=None, help="also save the spectral cube as .npz")
    p.add_argument("--xyz", action="store_true", help="EXR channels X, Y, Z instead of Rec.709 R, G, B")
    add_option(p, "exposure_ev", dest="exposure", default=None)
    add_option(p, "max_memory")
    p.add_argument("--no-sun", action="store_true", help="leave the solar disc (and the moon's) out of the image")
    add_option(p, "night", note="stars, moon and glow need --time; below the sun's lowest elevation only they remain")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=cmd_render)


class Progress:
    """Stage lines and the scattering-order bar on stderr (nothing with ``quiet``)."""

    def __init__(self, quiet: bool):
        self.quiet = quiet
        self.t0 = time.perf_counter()

    def stage(self, text):
        if not self.quiet:
            print(f"[{time.perf_counter() - self.t0:6.1f}s] {text}", file=sys.stderr, flush=True)

    def order(self, n, size):
        if not self.quiet:
            bar = "#" * min(n, 30)
            print(f"\r[{time.perf_counter() - self.t0:6.1f}s] scattering order {n:2d} "
                  f"(adds {size:.2%}) {bar}", end="", file=sys.stderr, flush=True)


def cmd_render(args) -> int:
    from skymodel.render import image_io
    from skymodel.render.cameras import make_camera
    from skymodel.render.memory import check_render_memory
    from skymodel.render import night as night_module
    from skymodel.render.quality import quality_settings
    from skymodel.render.sky import render_sky, render_sky_reduced
    from skymodel.render.skyview import xyz_reduction
    from skymodel.wavelengths import default_wavelengths

    prog = Progress(args.quiet)
    atm = atmosphere_from_args(args)
    mode = scene.check("night", args.night)
    sun = sun_from_args(args, atm, allow_night=mode != "off")
    night = night_module.night_active(mode, sun.time_utc)
    sunlit = night_module.sunlit(sun.elevation_deg)
    if not (sunlit or night):
        raise SkymodelInputError("time_utc", sun.time_utc,
                                 f"a time when the sun is above {night_module.lowest_elevation_deg():g} degrees, "
                                 f"or --night auto (the night's light)")
    quality = scene.check("quality", args.quality)
    settings = quality_settings(quality)
    wl = default_wavelengths(scene.check("wavelength_step", args.wavelength_step))
    width, height = args.image_width
    scene.check("observer_altitude", args.observer_altitude)
    exposure = None if args.exposure is None else scene.check("exposure_ev", args.exposure)
    limit_gib = scene.check("max_memory", args.max_memory)
    # the spectral cube is kept only when --spectral asks for it; otherwise 3 values a pixel
    kept = wl.size if args.spectral else 3
    camera = make_camera(args.camera, width, height, n_wavelengths=kept, max_memory_bytes=limit_gib * 1024**3)
    check_render_memory(camera.width, camera.height, wl.size, settings, limit_gib, wavelengths_nm=wl,
                        image_channels=kept, band_pixels=None if args.spectral else REDUCED_BAND_PIXELS,
                        image_value_bytes=8 if args.spectral else np.dtype(REDUCED_DTYPE).itemsize,
                        sun_elevation_deg=sun.elevation_deg, camera=camera)
    png = None if args.no_png else (args.png or (str(args.out).rsplit(".", 1)[0] + ".png"))
    # validate every output path before the (long) render, so nothing is half-written
    for key, path, ext in (("out", args.out, ".exr"), ("png", png, ".png"), ("spectral", args.spectral, ".npz")):
        if path is not None:
            image_io.check_output_path(key, path, (ext,))
    prog.stage(f"atmosphere: {atm.location or 'custom'}, month {atm.month}, aerosol {atm.aerosol}; "
               f"sun elevation {sun.elevation_deg:.2f}, azimuth {sun.azimuth_deg:.2f}; {camera.name} "
               f"{camera.width}x{camera.height}, {wl.size} wavelengths, quality {quality}")
    profile = profile_for_sun(atm, wl, sun)
    # the sunlit sky (skipped below the sun's lowest elevation), then the night's light added
    # before any finish (night: the same solve serves the moonlit sky, from the process's cache)
    info = {}
    if args.spectral:
        radiance, xyz = np.zeros(camera.shape + (wl.size,)), None
        sun_irradiance = np.zeros(wl.size)
        if sunlit:
            img = render_sky(profile, camera, sun.elevation_deg, sun.azimuth_deg, args.observer_altitude, settings,
                             include_sun=not args.no_sun, progress=prog.order, max_memory_gib=limit_gib)
            radiance, info, sun_irradiance = img.radiance, img.info, img.sun_irradiance
    else:  # straight to CIE XYZ (the sky-view table for large images): no spectral cube
        # float32 (each band computed in float64): the EXR is float32, and the image half the memory
        xyz, radiance = np.zeros(camera.shape + (3,), dtype=REDUCED_DTYPE), None
        sun_irradiance = np.zeros(wl.size)
        if sunlit:
            xyz, sun_irradiance, info = render_sky_reduced(
                profile, camera, sun.elevation_deg, xyz_reduction(wl), 3, sun.azimuth_deg, args.observer_altitude,
                settings, band_pixels=REDUCED_BAND_PIXELS, progress=prog.order, include_sun=not args.no_sun,
                solutions=None if night else False, max_memory_gib=limit_gib, dtype=REDUCED_DTYPE)
    if not args.quiet:
        print(file=sys.stderr)
    if sunlit:
        prog.stage(f"rendered in {info['total_s']:.1f}s ({info['orders']} scattering orders, "
                   f"{info.get('method', 'direct')} method)")
    else:
        prog.stage(f"no sunlit sky: the sun at {sun.elevation_deg:.1f} deg is below "
                   f"{night_module.lowest_elevation_deg():g}")
    night_meta, moon_h = None, 0.0
    if night:
        add, ninfo = night_module.night_light(profile, camera, atm.latitude, atm.longitude, sun.time_utc,
                                              None if args.spectral else xyz_reduction(wl).matrix,
                                              sun_elevation_deg=sun.elevation_deg,
                                              observer_altitude_m=args.observer_altitude, quality=settings,
                                              include_moon_disc=not args.no_sun, band_pixels=REDUCED_BAND_PIXELS)
        if args.spectral:
            radiance += add  # in place: no third copy of a spectral cube
        else:
            xyz += add
        night_meta = ninfo.as_dict()
        moon_h = ninfo.moon_horizontal_illuminance_y() if args.no_sun else 0.0
        prog.stage(f"night: moon at {ninfo.moon_elevation_deg:.1f} deg (phase angle {ninfo.moon_phase_angle_deg:.0f}, "
                   f"{ninfo.moon_illuminance_lux:.3g} lux facing it), moonlit sky "
                   f"{'marched' if ninfo.moonlit_sky else 'not marched'}, {ninfo.stars_drawn} stars, "
                   f"{ninfo.timings['total_s']:.1f}s")
    # the PNG's exposure: the one display rule (skymodel.render.exposure), as the add-on's and the
    # time-lapse's; the sun and the moon are counted as light on the ground whether drawn or not
    meter = None
    if not args.no_png:
        from skymodel.colorimetry import spectral_to_xyz
        from skymodel.render.exposure import display_exposure

        y = (spectral_to_xyz(radiance, wl) if args.spectral else xyz)[..., 1]
        sun_y = float(spectral_to_xyz(sun_irradiance, wl)[1]) if args.no_sun else 0.0
        meter = display_exposure(y, camera, sun_y, sun.elevation_deg, moon_h)
        exposure = meter["exposure"] + (exposure or 0.0)
        prog.stage(f"exposure {meter['exposure']:+.2f} EV (incident {meter['exposure_incident']:+.2f}, "
                   f"sky {meter['exposure_sky']:+.2f})"
                   + (f", plus --exposure {args.exposure:+.2f}" if args.exposure else ""))
    written = image_io.save_outputs(out=args.out, png=png, spectral=args.spectral, radiance=radiance, xyz=xyz,
                                    wavelengths=wl, camera=camera, exposure_ev=exposure,
                                    average_luminance=None if meter is None else image_io.TONEMAP_KEY,
                                    colour_space="xyz" if args.xyz else "rec709",
                                    metadata={"atmosphere": profile.metadata, "sun_elevation_deg": sun.elevation_deg,
                                              "sun_azimuth_deg": sun.azimuth_deg, "time_utc": sun.time_utc,
                                              "time_local": sun.time_local, "timezone": sun.timezone,
                                              "observer_altitude_m": args.observer_altitude, "quality": quality,
                                              **({"night": night_meta} if night_meta else {}),
                                              **({"exposure": meter} if meter else {})})
    for path in written.values():
        prog.stage(f"wrote {path}")
    return 0
