"""Headless rendering: build a sky in a fresh scene and render it with Cycles (CPU).

From the repository (``bpy`` module installed)::

    python -m blender_addon.render --location desert --month 1 --sun-elevation 5 \\
        --mode environment --samples 64 --size 256x128 --out desert.png

Inside Blender, with the extension installed (see docs/blender.md)::

    blender -b --python-exit-code 1 --python-expr "import sys; \\
        from bl_ext.user_default.skymodel import render; \\
        sys.exit(render.main(['--location', 'desert', '--sun-elevation', '5', '--out', '/tmp/desert.png']))"

The scene is new (``Skymodel Render``; nothing else in the file is touched): a world,
the sky (Build Sky with the given settings) and an equirectangular panoramic camera
``--camera-height`` metres above the ground whose image centre looks horizontally toward
``--center-azimuth`` (default: the sun's azimuth). The PNG goes through the scene's view
transform (AgX and the add-on's exposure); ``--exr`` also writes the scene-linear image.
A day as a sequence (``--date --from --to --every [--timezone]``, as ``skymodel
timelapse``): the frames are keyframed and baked (:mod:`blender_addon.animation`, one
multiple-scattering solve for the day) and every frame is rendered to
``--out``/frame_NNNN.png, the camera centred on the sun's azimuth at the middle frame::

    python -m blender_addon.render --location zaragoza --date 2026-06-21 --from 19:00 \\
        --to 22:30 --every 10min --timezone Europe/Madrid --out frames/

Exit status 0 on success, 2 for bad input (the message names the option and the value as
typed, checked before Blender does any work: out of range is refused, never clamped; the
documented bounds such as ``--lat 90`` are accepted), 130 when interrupted (Ctrl+C: one line,
no traceback), 1 otherwise.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
import time
from types import SimpleNamespace

import bpy
from skymodel import scene
from skymodel.errors import SkymodelInputError
from skymodel.render.quality import QUALITIES


def _size(text):
    try:
        w, h = (int(v) for v in str(text).lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT, got {text!r}") from None
    hi = scene.parameter("image_width").maximum
    if not (1 <= w <= hi and 1 <= h <= hi):
        raise argparse.ArgumentTypeError(f"size out of range: {text!r} (each side 1..{hi:g})")
    return w, h


def parse_args(argv=None):
    ap = argparse.ArgumentParser(prog="python -m blender_addon.render", description=__doc__.split("\n\n")[0])
    g = ap.add_argument_group("atmosphere")
    g.add_argument("--location", default=None, help="location preset (default rural)")
    g.add_argument("--lat", type=float, default=None, help="latitude, degrees north (custom location)")
    g.add_argument("--lon", type=float, default=None, help="longitude, degrees east (custom location)")
    g.add_argument("--month", type=int, default=scene.default("month"),
                   help=scene.parameter("month").help_text() + "; ignored with --time")
    g.add_argument("--aerosol", default=None, help="aerosol type or 'none' (default: the location's)")
    g.add_argument("--aod550", type=float, default=None)
    g.add_argument("--turbidity", type=float, default=None)
    g.add_argument("--stratospheric", default="background", choices=["background", "volcanic", "none"])
    g.add_argument("--ozone-du", type=float, default=None)
    g.add_argument("--albedo", type=float, default=None)
    g = ap.add_argument_group("sun")
    g.add_argument("--sun-elevation", type=float, default=None, help=scene.parameter("sun_elevation").help_text())
    g.add_argument("--sun-azimuth", type=float, default=None, help="degrees clockwise from north, default 180")
    g.add_argument("--time", default=None, help="date-time YYYY-MM-DDTHH:MM, UTC unless --timezone is given "
                   "(or an offset: +02:00); the sun placed by the core")
    g = ap.add_argument_group("render")
    g.add_argument("--mode", default="environment", choices=["auto", "environment", "volumetric"])
    g.add_argument("--quality", default=scene.default("quality"), choices=list(QUALITIES),
                   help=scene.parameter("quality").help_text().replace("%", "%%"))
    g.add_argument("--image-width", type=int, default=0, help="environment image width (0: by quality)")
    g.add_argument("--layers", type=int, default=8, help="volume layers (volumetric)")
    g.add_argument("--volume-bounces", type=int, default=8)
    g.add_argument("--samples", type=int, default=64)
    g.add_argument("--size", type=_size, default=(256, 128), help="WIDTHxHEIGHT of the render")
    g.add_argument("--camera-height", type=float, default=1.7, help="metres above the ground")
    g.add_argument("--center-azimuth", type=float, default=None, help="image centre azimuth (default: the sun's)")
    g.add_argument("--out", required=True, help="PNG file (.png); with --date a folder for frame_NNNN.png")
    g.add_argument("--exr", default=None, help="also write the scene-linear image (OpenEXR)")
    g = ap.add_argument_group("a day as a sequence (blender_addon.animation: Animate Day, then Bake Time of Day)")
    for name in ("date", "time_from", "time_to", "every", "timezone"):
        p = scene.parameter(name)
        g.add_argument(p.flag, dest=name, default=None, help=p.help_text())
    return ap.parse_args(argv)


#: The headless options checked against the registry (flag -> attribute, registry name);
#: out of range is an error naming the flag and the value as typed, never a clamp.
_REGISTRY_OPTIONS = (
    ("--lat", "lat", "latitude"), ("--lon", "lon", "longitude"), ("--month", "month", "month"),
    ("--aod550", "aod550", "aod550"), ("--turbidity", "turbidity", "turbidity"),
    ("--ozone-du", "ozone_du", "ozone_du"), ("--albedo", "albedo", "albedo"),
    ("--sun-elevation", "sun_elevation", "sun_elevation"), ("--sun-azimuth", "sun_azimuth", "sun_azimuth"),
    ("--quality", "quality", "quality"), ("--image-width", "image_width", "environment_width"),
    ("--layers", "layers", "volume_layers"), ("--camera-height", "camera_height", "observer_altitude"),
    ("--center-azimuth", "center_azimuth", "sun_azimuth"),
)

#: Bounds of options that are the renderer's, not the sky's (Blender's own limits).
VOLUME_BOUNCES = (0, 64)
SAMPLES = (1, 1 << 16)
OUTPUT_EXTENSIONS = {"--out": (".png",), "--exr": (".exr",)}


def check_options(o) -> None:
    """Check every parsed option before Blender does any work: each sky value against
    :mod:`skymodel.scene` (the bounds themselves pass: ``--lat 90`` is allowed), the
    renderer's counts, the date's year, and the output paths (extension, existing and
    writable folder). Raises :class:`SkymodelInputError` naming the flag and the value as
    typed (exit status 2 from :func:`main`); nothing is clamped."""
    for flag, attr, name in _REGISTRY_OPTIONS:
        value = getattr(o, attr)
        if value is None:
            continue
        try:
            scene.check(name, value)
        except SkymodelInputError as e:
            raise SkymodelInputError(flag, value, e.allowed) from None
    if o.aod550 is not None and o.turbidity is not None:
        raise SkymodelInputError("--turbidity", o.turbidity, "either --aod550 or --turbidity, not both")
    for flag, value, (lo, hi) in (("--volume-bounces", o.volume_bounces, VOLUME_BOUNCES),
                                  ("--samples", o.samples, SAMPLES)):
        if not (lo <= value <= hi):
            raise SkymodelInputError(flag, value, f"an integer in {lo}..{hi}")
    if o.time:
        import datetime as dt

        try:
            t = dt.datetime.fromisoformat(o.time.rstrip("Zz"))
        except ValueError:
            raise SkymodelInputError("--time", o.time, "an ISO date-time such as 2026-06-21T19:30") from None
        try:
            scene.check("year", t.year)
        except SkymodelInputError as e:
            raise SkymodelInputError("--time", o.time, f"a date with the year {e.allowed}") from None
        if o.sun_elevation is not None or o.sun_azimuth is not None:
            raise SkymodelInputError("--time", o.time, "either --time or --sun-elevation/--sun-azimuth, not both")
    elif getattr(o, "timezone", None) is not None and getattr(o, "date", None) is None:
        raise SkymodelInputError("--timezone", o.timezone, "a time zone only together with --time or --date")
    from skymodel.render.image_io import check_output_path

    if getattr(o, "date", None) is not None:  # a day: --out is a folder, the frames checked by the core
        _check_sequence(o)
        return
    for flag, path in (("--out", o.out), ("--exr", o.exr)):
        if path is not None:
            check_output_path(flag, path, OUTPUT_EXTENSIONS[flag])


def _check_sequence(o) -> None:
    """A day sequence's options (``--date``; the frames placed by
    :func:`skymodel.render.timeline.day_frames` at the location, every frame's sun checked),
    and ``--out`` a folder that exists or can be made, before any work."""
    from skymodel.optics.atmosphere import Atmosphere
    from skymodel.render import timeline

    if o.time or o.sun_elevation is not None or o.sun_azimuth is not None or o.exr:
        raise SkymodelInputError("--date", o.date, "a day without --time, --sun-elevation/--sun-azimuth or --exr")
    if o.mode != "environment":
        raise SkymodelInputError("--mode", o.mode, "environment for a day sequence")
    custom = o.location is None and o.lat is not None
    atm = Atmosphere(location=None if custom else (o.location or "rural"), latitude=o.lat if custom else None,
                     longitude=o.lon if custom else None, aerosol=o.aerosol)
    # through the night too: frames below -18 render the night's light (as skymodel timelapse's --night auto)
    timeline.day_frames(atm.latitude, atm.longitude, o.date, o.time_from, o.time_to, o.every, o.timezone,
                        allow_night=True)
    folder = os.path.abspath(o.out)
    if os.path.exists(folder) and not os.path.isdir(folder):
        raise SkymodelInputError("--out", o.out, "a folder for the frames (this is a file)")
    if not os.path.isdir(os.path.dirname(folder)):
        raise SkymodelInputError("--out", o.out, "a folder in an existing folder")


def render_day(o, progress=print) -> list:
    """``--date``: a new scene whose frames run through the day (Animate Day), the sky of
    every frame baked with one shared solve (Bake Time of Day, the images in
    ``--out``/bake-<id>/), then every frame rendered to ``--out``/frame_NNNN.png. Returns
    the paths written."""
    _ensure_registered()
    scene = _new_scene(o)
    # the new scene as the context's: Blender writes animated values back to the settings (which
    # the bake reads frame by frame) and evaluates the exposure keys only in the active scene's
    # depsgraph; without this every frame read the last frame's time (one sky for all)
    with bpy.context.temp_override(scene=scene, view_layer=scene.view_layers[0]):
        return _render_day(scene, o, progress)


def _render_day(scene, o, progress) -> list:
    from . import animation

    s = scene.world.skymodel
    _apply_options(s, o)
    frames = animation.animate_day(scene, s, o.date, o.time_from, o.time_to, o.every, o.timezone)
    os.makedirs(o.out, exist_ok=True)
    ctx = SimpleNamespace(scene=scene, window_manager=None)
    animation.bake(ctx, folder=o.out, progress=lambda t: progress(f"[skymodel] {t}") if progress else None)
    az = frames[len(frames) // 2].azimuth_deg if o.center_azimuth is None else o.center_azimuth
    scene.camera.rotation_euler = (math.radians(90.0), 0.0, -math.radians(az))
    scene.render.image_settings.color_depth = "8"
    written = []
    for k in range(scene.frame_start, scene.frame_end + 1):
        scene.frame_set(k)
        path = os.path.join(os.path.abspath(o.out), f"frame_{k:04d}.png")
        _render(scene, path, "PNG")
        written.append(path)
        if progress:
            progress(f"[skymodel] frame {k}/{scene.frame_end}: {frames[k - 1].time_local} -> {path}")
    return written


def _ensure_registered():
    if not hasattr(bpy.types.World, "skymodel"):
        from . import register

        register()


def _apply_options(s, o):
    s.location_source = "CUSTOM" if (o.location is None and o.lat is not None) else "PRESET"
    s.location = o.location or "rural"
    if o.lat is not None:
        s.latitude = math.radians(o.lat)
    if o.lon is not None:
        s.longitude = math.radians(o.lon)
    s.aerosol = o.aerosol or "location"
    s.aerosol_amount = "AOD" if o.aod550 is not None else ("TURBIDITY" if o.turbidity is not None else "DEFAULT")
    if o.aod550 is not None:
        s.aod550 = o.aod550
    if o.turbidity is not None:
        s.turbidity = o.turbidity
    s.stratospheric = o.stratospheric
    s.use_ozone = o.ozone_du is not None
    if o.ozone_du is not None:
        s.ozone_du = o.ozone_du
    s.use_albedo = o.albedo is not None
    if o.albedo is not None:
        s.albedo = o.albedo
    if o.time:
        import datetime as dt

        try:
            t = dt.datetime.fromisoformat(o.time.rstrip("Zz"))
        except ValueError:
            raise SkymodelInputError("time", o.time, "an ISO date-time such as 2026-06-21T19:30") from None
        s.sun_source = "TIME"
        zone = getattr(o, "timezone", None)
        if t.tzinfo is not None:  # an explicit offset: the instant in UTC (checked against --timezone)
            t = scene.resolve_time(o.time, zone).utc.replace(tzinfo=None)
            zone = "UTC"
        s.timezone = zone or "UTC"  # without --timezone the time is UTC, as skymodel render's --time
        s.year, s.month, s.day, s.hour, s.minute = t.year, t.month, t.day, t.hour, t.minute
    else:
        s.sun_source = "ANGLES"
        s.month = o.month
        # checked here: the property would clamp silently
        sun = scene.place_sun(elevation_deg=o.sun_elevation, azimuth_deg=o.sun_azimuth)
        el, az = sun.elevation_deg, sun.azimuth_deg
        s.sun_elevation = math.radians(el)
        s.sun_azimuth = math.radians(az % 360.0)
    s.mode = o.mode.upper()
    s.quality = o.quality
    s.image_width = o.image_width
    s.n_layers = o.layers
    s.volume_bounces = o.volume_bounces


def build_scene(o, progress=print):
    """A new scene with world, camera and the sky; returns it."""
    _ensure_registered()
    from . import ops

    scene = _new_scene(o)
    cam = scene.camera
    _apply_options(scene.world.skymodel, o)
    ctx = SimpleNamespace(scene=scene, window_manager=None)
    result = ops.build(ctx, progress=lambda t: progress(f"[skymodel] {t}") if progress else None)
    az = result.sun_azimuth_deg if o.center_azimuth is None else o.center_azimuth
    # camera: local -Z forward; X 90 deg looks north (+Y), Z rotation -az turns it to azimuth az
    cam.rotation_euler = (math.radians(90.0), 0.0, -math.radians(az))
    return scene


def _new_scene(o):
    """A new scene (``Skymodel Render``) with a world and the panoramic camera."""
    scene = bpy.data.scenes.new("Skymodel Render")
    world = bpy.data.worlds.new("Skymodel World")
    scene.world = world
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = int(o.samples)
    scene.cycles.use_denoising = False
    scene.render.resolution_x, scene.render.resolution_y = o.size
    scene.render.resolution_percentage = 100
    cam_data = bpy.data.cameras.new("Skymodel Camera")
    cam_data.type = "PANO"
    cam_data.panorama_type = "EQUIRECTANGULAR"
    cam_data.clip_start = 0.01
    cam_data.clip_end = 2.0e7
    cam = bpy.data.objects.new("Skymodel Camera", cam_data)
    scene.collection.objects.link(cam)
    scene.camera = cam
    cam.location = (0.0, 0.0, float(o.camera_height))
    return scene


def _render(scene, path, fmt):
    r = scene.render
    old = (r.filepath, r.image_settings.file_format)
    try:
        r.image_settings.file_format = fmt
        r.filepath = path
        bpy.ops.render.render(write_still=True, scene=scene.name)
    finally:
        r.filepath, r.image_settings.file_format = old


def render_linear(scene) -> "np.ndarray":
    """Render and return the scene-linear image (H, W, 3) float32, row 0 at the top."""
    folder = tempfile.mkdtemp(prefix="skymodel-render-")
    path = os.path.join(folder, "render.exr")
    _render(scene, path, "OPEN_EXR")
    try:
        return read_rgb(path)
    finally:
        os.remove(path)
        os.rmdir(folder)


def read_rgb(path) -> "np.ndarray":
    """An image file as Blender reads it: (H, W, 3) float32, row 0 at the top (an 8-bit PNG in
    [0, 1], an EXR scene-linear); the image is not kept in ``bpy.data``."""
    import numpy as np

    img = bpy.data.images.load(path, check_existing=False)
    try:
        w, h = img.size
        px = np.empty(w * h * 4, np.float32)
        img.pixels.foreach_get(px)
    finally:
        bpy.data.images.remove(img)
    return px.reshape(h, w, 4)[::-1, :, :3].copy()


def main(argv=None) -> int:
    try:
        o = parse_args(argv)
    except SystemExit as ex:  # argparse: bad usage
        return int(ex.code or 0)
    t0 = time.perf_counter()
    try:
        check_options(o)
        out = os.path.abspath(o.out)
        if o.date is not None:
            written = render_day(o)
            print(f"[skymodel] wrote {len(written)} frames into {out} in {time.perf_counter() - t0:.1f} s")
            return 0
        scene = build_scene(o)
        if o.exr:
            _render(scene, os.path.abspath(o.exr), "OPEN_EXR")
            print(f"[skymodel] wrote {o.exr}")
        scene.render.image_settings.color_depth = "8"
        _render(scene, out, "PNG")
    except SkymodelInputError as ex:
        print(f"skymodel: error: {ex}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:  # Ctrl+C: one line, no traceback (the build rolled back)
        print("skymodel: interrupted", file=sys.stderr)
        return 130
    except OSError as ex:
        print(f"skymodel: error: {ex}", file=sys.stderr)
        return 1
    print(f"[skymodel] wrote {out} in {time.perf_counter() - t0:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
