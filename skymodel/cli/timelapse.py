"""``skymodel timelapse``: a sequence of skies, one multiple-scattering solve per atmosphere.

Two kinds of sequence (:mod:`skymodel.render.timeline`):

* a day: ``--date 2026-06-21 --from 19:00 --to 22:30 --every 10min --timezone Europe/Madrid``
  (local times; the frames step in real time);
* days at one sun elevation: ``--dates 2026-01-15:2026-12-15 --every 1month --sun-elevation -4``
  (each date at the instant the sun crosses that elevation, at dusk or, ``--crossing dawn``,
  at dawn): the seed paper's experiment on how ozone changes the colour of twilight.

Each frame is ``skymodel render --time <its UTC instant>``: the atmosphere of its UTC date
(ozone interpolated by day of the year), the solar spectrum at its Earth-sun distance, the
sun where it is. Frames whose optical profile is the same share one multiple-scattering
solve (:class:`~skymodel.render.sequence.SolutionCache`; a day has one, a year one per
distinct ozone column), and each frame then only marches its pixels: the frames equal
independent renders of the same instants bit for bit (``tests/test_timelapse.py``).

Output in the ``--out`` folder:

* ``frame_0001.exr`` ...: scene-linear Rec.709, no exposure, each with the frame's
  metadata (UTC instant, local time, sun, ozone) in its ``skymodel`` header attribute,
  written atomically as it is rendered;
* ``frames.json``: the sequence and every finished frame (UTC and local time, zone, sun
  elevation/azimuth, Earth-sun distance, day of the year, ozone column, the zenith's CIE xy
  chromaticity and luminance, whether the solve was reused, the exposure meters and the
  preview's exposure),
  rewritten atomically after each frame;
* once every frame is rendered: ``frame_0001.png`` ... previews at one exposure curve for
  the whole sequence (``--exposure-curve``: ``follow`` gives each frame the exposure of the
  one display rule, :mod:`skymodel.render.exposure`, the Blender add-on's for the same
  instant: continuous in the light, so nothing flickers, dusk darker than noon and the night
  darker still, a moonlit night brighter than a moonless one; ``fixed`` uses one exposure,
  the mean of the frames' exposures, so colours
  and brightness compare from frame to frame), ``contact_sheet.png`` and a video
  (``timelapse.mp4`` through ``imageio-ffmpeg`` when installed, else an animated
  ``timelapse.webp`` or ``timelapse.gif`` through Pillow; none without either).

The night (``--night auto``, the default): each frame also gets the night's light of its
instant (:mod:`skymodel.render.night`: the moon's disc at any sun elevation; the moonlit sky,
the stars and the natural glow while the sun is below the horizon), and frames with the sun
below its lowest elevation (-18 degrees) skip the sunlit sky, so a day sequence may run
through the night (``--from 00:00 --to 23:45``). ``--night off``: the sunlit sky alone, and a
frame below that elevation is refused.

Everything is checked before the first solve (dates, times, step, frame count, with
``--night off`` every frame's sun above its lowest elevation, the output folder). Ctrl-C leaves only finished frames:
each EXR is complete or absent and ``frames.json`` lists exactly those (``"complete":
false``).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

from skymodel import scene
from skymodel.cli.options import (add_atmosphere_arguments, add_option, atmosphere_from_args, profile_for_sun,
                                  size)
from skymodel.errors import SkymodelInputError

FRAME_NAME = "frame_{:04d}"


def add_command(sub) -> None:
    """Register ``skymodel timelapse`` on the CLI's subparsers."""
    p = sub.add_parser("timelapse", help="a sequence of skies: a day (--date --from --to --every) or days at one "
                                         "sun elevation (--dates --every --sun-elevation)")
    add_atmosphere_arguments(p)
    g = p.add_argument_group("sequence")
    add_option(g, "date", default=None)
    add_option(g, "time_from")
    add_option(g, "time_to")
    add_option(g, "every")
    add_option(g, "dates", default=None)
    add_option(g, "sun_elevation", default=None, note="with --dates: the elevation of every frame")
    add_option(g, "dusk_or_dawn")
    add_option(g, "timezone", note="the zone of --date/--from/--to and of the local times reported")
    add_option(g, "observer_altitude")
    add_option(g, "max_frames")
    r = p.add_argument_group("images")
    add_option(r, "camera")
    add_option(r, "image_width", type=size, default=(scene.default("image_width"), None), metavar="WIDTH[xHEIGHT]",
               note="WIDTH or WIDTHxHEIGHT")
    add_option(r, "quality")
    add_option(r, "wavelength_step")
    add_option(r, "exposure_curve")
    add_option(r, "frame_rate")
    r.add_argument("--exposure", type=float, default=None, help="PNG exposure in EV added to the curve")
    r.add_argument("--no-sun", action="store_true", help="leave the solar disc (and the moon's) out of the images")
    add_option(r, "night", note="with auto a day sequence runs through the night (the sun below its lowest "
                                "elevation: stars, moon and glow only)")
    p.add_argument("--out", default="frames", help="output folder (created; default frames)")
    p.add_argument("--overwrite", action="store_true", help="write into a folder that holds a previous sequence")
    p.add_argument("--no-video", action="store_true", help="write no video")
    p.add_argument("--solution-cache", default=None, metavar="FOLDER",
                   help="keep the multiple-scattering solutions in FOLDER for later runs (your own folder only)")
    p.add_argument("--quiet", action="store_true")
    p.add_argument("--json", action="store_true", help="print frames.json's summary as JSON on stdout")
    p.set_defaults(func=cmd_timelapse)


# ----------------------------------------------------------------------------- planning


def plan_frames(args, atm) -> tuple[str, list]:
    """``(kind, frames)``: ``"day"`` or ``"days"`` and the frames' sun placements, all
    checked (:mod:`skymodel.render.timeline`). Raises naming the option at fault."""
    from skymodel.render import timeline

    if getattr(args, "month", None) is not None:
        raise SkymodelInputError("month", args.month, "no --month with timelapse: each frame's month and day of "
                                                      "the year come from its date")
    if (args.date is None) == (args.dates is None):
        raise SkymodelInputError("date", args.date, "either --date (a day: --from, --to, --every) or --dates "
                                                    "(days at one --sun-elevation), not both or neither")
    if args.date is not None:
        if args.sun_elevation is not None:
            raise SkymodelInputError("sun_elevation", args.sun_elevation, "no --sun-elevation with --date (the "
                                                                          "sun follows the clock); use --dates")
        return "day", timeline.day_frames(atm.latitude, atm.longitude, args.date, args.time_from, args.time_to,
                                          args.every, args.timezone, args.max_frames,
                                          allow_night=scene.check("night", args.night) != "off")
    if args.sun_elevation is None:
        raise SkymodelInputError("sun_elevation", None, "a sun elevation with --dates (-4 for the paper's twilight)")
    return "days", timeline.days_frames(atm.latitude, atm.longitude, args.dates, args.every, args.sun_elevation,
                                        args.timezone, args.dusk_or_dawn, args.max_frames)


def _out_folder(path, overwrite: bool) -> Path:
    """The output folder, created (its parent must exist), writable, and free of a
    previous sequence unless ``overwrite``. Raises naming ``out``."""
    from skymodel.render import image_io

    folder = Path(path)
    if folder.exists() and not folder.is_dir():
        raise SkymodelInputError("out", str(path), "a folder (this is a file)")
    if not folder.parent.is_dir():
        raise SkymodelInputError("out", str(path), f"a folder in an existing folder ({folder.parent} does not exist)")
    if (folder / "frames.json").exists() and not overwrite:
        raise SkymodelInputError("out", str(path), "a new or empty folder (it holds a sequence: frames.json); "
                                                   "or --overwrite")
    folder.mkdir(exist_ok=True)
    image_io.check_output_path("out", folder / "frames.json", (".json",))
    return folder


def _remove_previous(folder: Path) -> None:
    """Delete the files a previous sequence's ``frames.json`` lists (frames, previews,
    contact sheet, video) and that file itself; nothing else in the folder."""
    index = folder / "frames.json"
    try:
        old = json.loads(index.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return
    names = [old.get("contact_sheet"), old.get("video")]
    for f in old.get("frames", []) if isinstance(old, dict) else []:
        names += [f.get("exr"), f.get("png")] if isinstance(f, dict) else []
    for name in names:
        if isinstance(name, str) and name and Path(name).name == name:  # plain names inside the folder only
            (folder / name).unlink(missing_ok=True)
    index.unlink(missing_ok=True)


def _write_json_atomic(path: Path, data: dict) -> None:
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        tmp.write_text(json.dumps(data, indent=1, default=_json_default), encoding="utf-8")
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def _json_default(o):
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, (set, tuple)):
        return list(o)
    return str(o)


# ----------------------------------------------------------------------------- exposure


def exposure_curve(exposures_ev, rule: str) -> np.ndarray:
    """The exposure [stops] of each frame's preview from the frames' own exposures (the
    display rule of :mod:`skymodel.render.exposure`): ``follow``: each frame its own (the
    add-on's exposure for that instant; continuous in the light, so no flicker);
    ``fixed``: their mean for every frame."""
    ev = np.asarray(exposures_ev, dtype=float)
    if scene.check("exposure_curve", rule) == "fixed":
        return np.full(ev.size, float(ev.mean()) if ev.size else 0.0)
    return ev.copy()


# ----------------------------------------------------------------------------- output


def zenith_colour(xyz, directions, valid, within_deg: float = 5.0) -> dict:
    """The sky's colour at the zenith: the mean CIE XYZ of the valid pixels within
    ``within_deg`` of it (the one nearest when none is), as ``zenith_xy`` (CIE 1931
    chromaticity) and ``zenith_Y`` (W m^-2 sr^-1, ybar-weighted; 1 = 683 cd m^-2)."""
    z = np.where(valid, directions[..., 2], -np.inf)
    near = z >= math.cos(math.radians(within_deg))
    if not near.any():
        near = z == z.max()
    X, Y, Z = xyz[near].mean(axis=0)
    total = X + Y + Z
    xy = [float(X / total), float(Y / total)] if total > 0 else [None, None]
    return {"zenith_xy": xy, "zenith_Y": float(Y)}



def contact_sheet(images: list, max_tile_width: int = 256) -> np.ndarray:
    """The frames (uint8 (H, W, 3) each) in rows, left to right, in a sheet of about
    16:9, reduced by an integer stride to at most ``max_tile_width`` px wide, a 2-px
    black gap between tiles."""
    step = max(1, math.ceil(images[0].shape[1] / max_tile_width))
    tiles = [im[::step, ::step] for im in images]
    h, w = tiles[0].shape[:2]
    cols = max(1, min(len(tiles), math.ceil(math.sqrt(len(tiles) * 16 / 9 * h / w))))  # about 16:9
    rows = math.ceil(len(tiles) / cols)
    gap = 2
    sheet = np.zeros((rows * (h + gap) - gap, cols * (w + gap) - gap, 3), np.uint8)
    for k, t in enumerate(tiles):
        r, c = divmod(k, cols)
        sheet[r * (h + gap):r * (h + gap) + h, c * (w + gap):c * (w + gap) + w] = t
    return sheet


def write_video(folder: Path, images: list, fps: int):
    """The frames as a video in ``folder``: MP4 (H.264) through imageio-ffmpeg when it is
    installed, else an animated WebP or GIF through Pillow; written to a temporary file and
    renamed. Returns the path, or None when neither library is installed."""
    tmp = None
    try:
        try:
            import imageio_ffmpeg

            path = folder / "timelapse.mp4"
            tmp = folder / f".timelapse.{os.getpid()}.tmp.mp4"
            h, w = images[0].shape[:2]
            h2, w2 = h - h % 2, w - w % 2  # yuv420p needs even sizes
            writer = imageio_ffmpeg.write_frames(str(tmp), (w2, h2), fps=fps, codec="libx264", pix_fmt_out="yuv420p",
                                                 macro_block_size=1, output_params=["-crf", "18"])
            writer.send(None)
            for im in images:
                writer.send(np.ascontiguousarray(im[:h2, :w2]))
            writer.close()
        except ImportError:
            try:
                from PIL import Image, features
            except ImportError:
                return None
            fmt = "webp" if features.check("webp") else "gif"
            path = folder / f"timelapse.{fmt}"
            tmp = folder / f".timelapse.{os.getpid()}.tmp.{fmt}"
            frames = [Image.fromarray(im) for im in images]
            extra = {"lossless": True} if fmt == "webp" else {}
            frames[0].save(tmp, save_all=True, append_images=frames[1:], duration=round(1000 / fps), loop=0, **extra)
        os.replace(tmp, path)
        return path
    finally:
        if tmp is not None and tmp.exists():
            tmp.unlink()


# ----------------------------------------------------------------------------- the command


class _Progress:
    def __init__(self, quiet: bool, total: int):
        self.quiet, self.total, self.t0 = quiet, total, time.perf_counter()

    def line(self, text):
        if not self.quiet:
            print(f"[{time.perf_counter() - self.t0:7.1f}s] {text}", file=sys.stderr, flush=True)

    def frame(self, done: int, text: str):
        elapsed = time.perf_counter() - self.t0
        left = elapsed / done * (self.total - done)
        self.line(f"frame {done}/{self.total} {text}; about {left:.0f} s left")


def cmd_timelapse(args) -> int:
    from skymodel.colorimetry import spectral_to_xyz, xyz_to_rgb
    from skymodel.render import image_io
    from skymodel.render.cameras import make_camera
    from skymodel.render.quality import quality_settings
    from skymodel.render import night as night_module
    from skymodel.render.exposure import display_exposure
    from skymodel.render.sequence import SolutionCache, render_frame
    from skymodel.wavelengths import default_wavelengths

    # --- everything checked before the first solve
    base = atmosphere_from_args(args)
    kind, frames = plan_frames(args, base)
    quality = scene.check("quality", args.quality)
    settings = quality_settings(quality)
    rule = scene.check("exposure_curve", args.exposure_curve)
    fps = scene.check("frame_rate", args.frame_rate)
    if args.exposure is not None:
        image_io.tonemap(np.ones((1, 3)), args.exposure)  # checks the range, naming exposure_ev
    wl = default_wavelengths(args.wavelength_step)
    width, height = args.image_width
    camera = make_camera(args.camera, width, height, n_wavelengths=wl.size)
    observer = scene.check("observer_altitude", args.observer_altitude)
    folder = _out_folder(args.out, args.overwrite)
    cache = SolutionCache(args.solution_cache, keep=2)
    _remove_previous(folder)  # --overwrite: the previous sequence's files, so no stale frame stays
    prog = _Progress(args.quiet, len(frames))
    prog.line(f"{len(frames)} frames ({kind}) at {base.location or 'custom'} ({base.latitude:g}, {base.longitude:g}); "
              f"{camera.name} {camera.width}x{camera.height}, {wl.size} wavelengths, quality {quality}")

    atmospheres = {}  # by UTC date: the ozone of the day

    def atmosphere_of(sun):
        day = sun.time_utc[:10]
        if day not in atmospheres:
            ns = argparse.Namespace(**vars(args))
            ns.time_utc, ns.timezone, ns.month = sun.time_utc, None, None
            with contextlib.redirect_stderr(io.StringIO()):  # the location rules were printed once
                atmospheres.clear()
                atmospheres[day] = atmosphere_from_args(ns)
        return atmospheres[day]

    sequence = {"kind": kind, "location": base.location, "latitude_deg": base.latitude,
                "longitude_deg": base.longitude, "timezone": args.timezone or "UTC", "every": args.every,
                "date": args.date, "dates": args.dates, "sun_elevation_deg": args.sun_elevation,
                "crossing": args.dusk_or_dawn if kind == "days" else None, "camera": camera.describe(),
                "quality": quality, "wavelength_step_nm": float(args.wavelength_step), "include_sun": not args.no_sun,
                "observer_altitude_m": observer, "exposure_curve": rule, "frame_rate": fps,
                "night": scene.check("night", args.night)}
    record = {"sequence": sequence, "frames": [], "complete": False}
    store_path = folder / f".frames-rgb.{os.getpid()}.tmp.npy"
    store = None
    try:
        store = np.lib.format.open_memmap(store_path, mode="w+", dtype=np.float32,
                                          shape=(len(frames), camera.height, camera.width, 3))
        directions, valid = camera.directions()
        meters = []
        for k, sun in enumerate(frames):
            t0 = time.perf_counter()
            atm = atmosphere_of(sun)
            profile = profile_for_sun(atm, wl, sun)
            solves = cache.stats["solves"]
            radiance, sun_irradiance = np.zeros(camera.shape + (wl.size,)), np.zeros(wl.size)
            if night_module.sunlit(sun.elevation_deg):  # below the bound the sunlit sky is zero
                image = render_frame(profile, camera, sun.elevation_deg, sun.azimuth_deg, observer, settings,
                                     include_sun=not args.no_sun, cache=cache)
                radiance, sun_irradiance = image.radiance, image.sun_irradiance
            night_info = None
            if night_module.night_active(args.night, sun.time_utc):
                add, night_info = night_module.night_light(
                    profile, camera, base.latitude, base.longitude, sun.time_utc, None,
                    sun_elevation_deg=sun.elevation_deg, observer_altitude_m=observer, quality=settings,
                    solutions=cache, include_moon_disc=not args.no_sun)
                radiance += add
            xyz = np.where(valid[..., None], spectral_to_xyz(radiance, wl), 0.0)
            rgb = xyz_to_rgb(xyz, "rec709")
            meta = {"frame": k + 1, "frames": len(frames), "time_utc": sun.time_utc, "time_local": sun.time_local,
                    "timezone": sun.timezone, "day_of_year": sun.day_of_year,
                    "sun_elevation_deg": sun.elevation_deg, "sun_azimuth_deg": sun.azimuth_deg,
                    "earth_sun_distance_au": sun.earth_sun_distance_au,
                    "ozone_du": profile.metadata.get("ozone_du"), "solve_reused": cache.stats["solves"] == solves,
                    "render_s": round(time.perf_counter() - t0, 3),
                    **({"night": {k_: v for k_, v in night_info.as_dict().items() if k_ != "timings"}}
                       if night_info is not None else {})}
            name = FRAME_NAME.format(k + 1)
            header = {"camera": camera.describe(), "colour_space": "rec709", "quality": quality,
                      "observer_altitude_m": observer, "atmosphere": profile.metadata, **meta}
            image_io.write_exr(folder / f"{name}.exr", rgb, chromaticities=image_io.CHROMATICITIES["rec709"],
                               attributes={"comments": "skymodel: scene-linear radiometric colour (CIE 1931 "
                                                       "integrals of W m^-2 sr^-1 nm^-1)",
                                           "skymodel": json.dumps(header, default=_json_default)})
            store[k] = rgb
            # the frame's exposure: the one display rule (the add-on's for the same instant); the sun
            # and the moon count as light on the ground whether their discs are drawn or not
            sun_y = float(spectral_to_xyz(sun_irradiance, wl)[1]) if args.no_sun else 0.0
            moon_y = night_info.moon_horizontal_illuminance_y() if (night_info and args.no_sun) else 0.0
            meters.append(display_exposure(xyz[..., 1], camera, sun_y, sun.elevation_deg, moon_y))
            record["frames"].append({"exr": f"{name}.exr", "png": None, **meta, "exposure": meters[-1],
                                     **zenith_colour(xyz, directions, valid)})
            _write_json_atomic(folder / "frames.json", record)
            prog.frame(k + 1, f"{sun.time_local} sun {sun.elevation_deg:.2f} deg "
                              f"({'solve reused' if meta['solve_reused'] else 'solved'}, {meta['render_s']:.1f} s)")
        # --- previews at one exposure curve, the contact sheet and the video
        curve = exposure_curve([m["exposure"] for m in meters], rule) + (args.exposure or 0.0)
        previews = []
        for k, entry in enumerate(record["frames"]):
            rgb8 = image_io.tonemap(np.asarray(store[k], dtype=float), float(curve[k]), valid=valid,
                                    average_luminance=image_io.TONEMAP_KEY)
            png = entry["exr"][:-4] + ".png"
            image_io.write_png(folder / png, rgb8, text={"Software": "skymodel", "Comment": entry["time_utc"]})
            entry["png"] = png
            entry["preview_exposure_ev"] = float(curve[k])
            previews.append(rgb8)
        image_io.write_png(folder / "contact_sheet.png", contact_sheet(previews), text={"Software": "skymodel"})
        record["contact_sheet"] = "contact_sheet.png"
        video = None if args.no_video else write_video(folder, previews, fps)
        record["video"] = None if video is None else video.name
        record["solves"] = cache.stats["solves"]
        record["solve_s"] = round(cache.stats["solve_s"], 3)
        record["wall_s"] = round(time.perf_counter() - prog.t0, 3)
        record["complete"] = True
        _write_json_atomic(folder / "frames.json", record)
    finally:
        del store
        store_path.unlink(missing_ok=True)
    prog.line(f"{len(frames)} frames, {record['solves']} multiple-scattering solve(s) ({record['solve_s']:.1f} s), "
              f"{record['wall_s']:.1f} s in all; wrote {folder}/frames.json, contact_sheet.png"
              + (f", {record['video']}" if record["video"] else
                 "" if args.no_video else " (no video: install imageio-ffmpeg or Pillow)"))
    if args.json:
        print(json.dumps({k: v for k, v in record.items() if k != "frames"} | {"frames": len(record["frames"])},
                         default=_json_default))
    return 0
