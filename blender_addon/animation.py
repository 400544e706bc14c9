"""Time of day, animated: **Bake Time of Day** and **Animate Day**.

What is built and why
    A sky that follows the frame must render right in the viewport, in F12 and animation
    renders (``blender -b file.blend -a``) and on a machine without the add-on. Only data
    saved in the .blend does all of that, so the sky is *baked*: :func:`bake` resolves the
    add-on's settings at every frame of the scene's range (any keyframed setting: the date
    and UTC time, the sun angles, the place), renders one environment image per frame with
    the core, all frames of one atmosphere sharing one multiple-scattering solve
    (:class:`skymodel.render.sequence.SolutionCache`), and writes them as an EXR sequence
    (``sky_0001.exr`` ... numbered by scene frame) that the world's Environment Texture
    reads as an image *sequence*; the sun lamp's rotation, strength and colour and the
    film exposure get one keyframe per frame, and so does the moon lamp's (with *Moon Lamp*
    on, when the moon is up in any frame; strength 0 in the frames where it is down). Nothing is computed at render time, so a
    keyframed time never renders a sky of another frame. No frame-change handler
    re-renders while scrubbing: a preview image per frame costs about a second, too slow
    for scrubbing, and a handler would not run where the add-on is not installed anyway.
    What changes after a bake is found by :func:`stale_frames` (every frame, exact) and,
    cheaply enough for the panel, by :func:`bake_warning` (the keyframes against those
    baked, the frame range, and the current frame's sun and date); an F12 or animation
    render prints a one-line warning (:func:`render_frame_warning`, a ``render_pre``
    handler) for a frame whose settings differ from what was baked, or an animated sky
    never baked. It warns rather than refuses: an exception in a render handler does not
    stop Blender's render.

    **Animate Day** keyframes a day in *local* time: the frames from ``time_from`` to
    ``time_to`` every ``every`` on ``date`` in ``timezone`` (IANA name, DST applied; the
    core's :func:`skymodel.render.timeline.day_frames`), as the UTC date and time the
    settings hold (constant interpolation, one key per frame; the panel's *Time Zone* is
    set to UTC, so the keyed fields read as UTC, and an hour repeated at a daylight-saving
    change stays two distinct keys), and sets the scene's frame range. Then Bake Time of Day.

    **Through the night** (issue 24): a frame whose sun is below -18 is baked as the core's
    night (``render_environment(..., time_iso=, night="auto")``: moonlit sky, stars, glow; no
    sunlit sky), its sun lamp at strength 0 and the moon lamp from the core's ``info["moon"]``,
    so a 24-hour Animate Day bakes without refusal. The exposure keyed at every frame is the
    core's environment exposure of that frame (what Build Sky sets for that instant: the darker
    of the incident-light meter, the moon lamp counted, and the sky meter), a continuous and
    monotonic function of the light, so a night frame is shown darker than the day without
    flicker (docs/blender.md "The night"). Night frames need Environment mode and our model
    (:func:`physics.resolve` refuses others naming the frame).

Where the images go
    ``folder`` when given; else ``//skymodel_sky/bake-<id>/`` beside the saved .blend
    (a relative path: the folder travels with the .blend); else, for an unsaved file, the
    add-on's cache folder. Each bake writes a new folder (rendered into a temporary one and
    renamed only when every frame is done); the previous bake's folder is deleted once the
    new bake is in the scene.

All or nothing
    The scene is changed only after every frame is rendered, in one
    :class:`~blender_addon.builder.Transaction` (:func:`builder.build`): an error or a
    cancel (Esc in the UI's progress, Ctrl-C in a console) during the frames removes the
    temporary folder and leaves the scene exactly as it was.
"""

from __future__ import annotations

import json
import shutil
import uuid
from pathlib import Path

import bpy
from skymodel.errors import SkymodelInputError

from . import builder, physics

#: Scene custom property: JSON of the current bake (build id, folder, frames and their times).
BAKE_KEY = "skymodel_bake"
FRAME_FILE = "sky_{:04d}.exr"
SEQUENCE_NAME = "Skymodel Sky Sequence"


class BakeCancelled(Exception):
    """The bake was cancelled before the scene was changed."""


#: Test hook: raise :class:`BakeCancelled` before rendering this frame (index into the range).
CANCEL_AT: int | None = None


# --------------------------------------------------------------------------- frames


def frame_range(scene) -> list[int]:
    return list(range(scene.frame_start, scene.frame_end + 1))


def frame_skies(scene, settings, frames) -> list:
    """``[(frame, ResolvedSky)]``: the settings as they evaluate at each frame (keyframes
    applied), validated by :func:`physics.resolve`; the current frame is put back. A bad
    frame raises naming the parameter and the frame."""
    current = scene.frame_current
    out = []
    try:
        for f in frames:
            scene.frame_set(f)
            try:
                out.append((f, physics.resolve(settings.to_params())))
            except SkymodelInputError as ex:
                raise SkymodelInputError(ex.parameter, ex.value, f"{ex.allowed} (at frame {f})") from None
    finally:
        scene.frame_set(current)
    return out


def sky_signature(sky) -> list:
    """What a frame's image depends on beyond the atmosphere: the sun and the date."""
    return [round(sky.sun_elevation_deg, 6), round(sky.sun_azimuth_deg, 6), sky.time_iso]


def stale_frames(scene, settings=None) -> list[int]:
    """The frames whose settings now resolve to another sun or date than the bake holds
    (keyframes changed after baking); ``[]`` when nothing is baked or all match."""
    data = bake_record(scene)
    if not data:
        return []
    settings = settings or scene.world.skymodel
    frames = [int(f) for f in data["frames"]]
    now = frame_skies(scene, settings, frames)
    return [f for f, sky in now if sky_signature(sky) != data["frames"][str(f)]["signature"]]


def keys_fingerprint(world) -> list:
    """The world's keyframes of the add-on's settings (``skymodel.*`` f-curves), as
    ``[[data_path, index, [[frame, value, interpolation], ...]], ...]`` sorted: what a bake
    followed. ``[]`` when no setting is animated."""
    if world is None:
        return []
    out = [[fc.data_path, int(fc.array_index),
            [[round(float(kp.co[0]), 4), round(float(kp.co[1]), 6), kp.interpolation] for kp in fc.keyframe_points]]
           for fc in _fcurves(world) if fc.data_path.startswith("skymodel.")]
    return sorted(out, key=lambda c: (c[0], c[1]))


def _frame_signature(scene, settings=None):
    """The current frame's sky signature (settings as evaluated now); None when they do not resolve."""
    settings = settings or scene.world.skymodel
    try:
        return sky_signature(physics.resolve(settings.to_params()))
    except SkymodelInputError:
        return None


def render_frame_warning(scene) -> str | None:
    """One line when the frame about to render would show a sky that is not its own: the
    frame's settings (as evaluated now) differ from what was baked for it, the frame is
    outside the bake, or the sky's settings are keyframed and nothing is baked. None when
    the frame matches (or nothing is animated nor baked)."""
    world = scene.world
    if world is None or not hasattr(world, "skymodel"):
        return None
    data = bake_record(scene)
    f = scene.frame_current
    if not data:
        if keys_fingerprint(world):
            return (f"skymodel: WARNING frame {f}: the sky's settings are keyframed but Bake Time of Day was not run; "
                    "this frame renders the last built sky, not its own")
        return None
    baked = data["frames"].get(str(f))
    if baked is None:
        return (f"skymodel: WARNING frame {f} is outside the baked frames "
                f"{min(map(int, data['frames']))}..{max(map(int, data['frames']))}; it renders another frame's sky")
    now = _frame_signature(scene)
    if now != baked["signature"]:
        return (f"skymodel: WARNING frame {f} renders the sky baked for {baked['signature']} but its settings now give "
                f"{now} (sun elevation, azimuth [deg], UTC); run Bake Time of Day again")
    return None


_PANEL_MEMO: dict = {}


def bake_warning(scene) -> str | None:
    """The panel's warning (cheap: no frame is changed): keyframes changed since the bake,
    frames outside it, the current frame's sun/date differing from its baked image, or
    keyframed settings never baked. None when none applies."""
    world = scene.world
    if world is None or not hasattr(world, "skymodel"):
        return None
    data = bake_record(scene)
    keys = keys_fingerprint(world)
    if not data:
        return "Animated but not baked: renders show one sky" if keys else None
    if "keys" in data and json.loads(json.dumps(keys)) != data["keys"]:
        return "Bake is stale: keyframes changed; bake again"
    baked = [int(f) for f in data["frames"]]
    if scene.frame_start < min(baked) or scene.frame_end > max(baked):
        return f"Frames outside the bake ({min(baked)}..{max(baked)}); bake again"
    memo_key = (scene.name, scene.frame_current, repr(world.skymodel.to_params()), data.get("build"))
    if memo_key not in _PANEL_MEMO:
        _PANEL_MEMO.clear()
        _PANEL_MEMO[memo_key] = render_frame_warning(scene)
    if _PANEL_MEMO[memo_key]:
        return f"Frame {scene.frame_current} differs from its bake; bake again"
    return None


def bake_record(scene) -> dict | None:
    try:
        return json.loads(scene[BAKE_KEY]) if BAKE_KEY in scene.keys() else None
    except (TypeError, ValueError):
        return None


# --------------------------------------------------------------------------- rendering


def _bake_folder(folder, bake_id: str) -> Path:
    if folder:
        return Path(bpy.path.abspath(folder)) / f"bake-{bake_id}"
    if bpy.data.filepath:
        return Path(bpy.path.abspath("//" + builder.BESIDE_FOLDER)) / f"bake-{bake_id}"
    from .ops import cache_dir

    return cache_dir() / f"bake-{bake_id}"


def render_frames(skies, folder: Path, progress=None) -> list:
    """Render every frame's environment image into ``folder`` (created; must not exist)
    as ``sky_<frame>.exr``; returns ``[(frame, SkyResult)]``. The frames of one optical
    profile share one multiple-scattering solve."""
    from skymodel.render import environment
    from skymodel.render.sequence import SolutionCache

    from .ops import cache_dir

    solutions = SolutionCache(keep=2)
    folder.mkdir(parents=True)
    out = []
    for k, (f, sky) in enumerate(skies):
        if CANCEL_AT is not None and k == CANCEL_AT:
            raise BakeCancelled(f"cancelled at frame {f}")
        p = sky.params
        if p.sky_model == "ours":
            _, env = environment.render_environment(
                sky.atmosphere, sky.sun_elevation_deg, sky.sun_azimuth_deg,
                earth_sun_distance_au=sky.earth_sun_distance_au, observer_altitude_m=p.observer_altitude_m,
                quality=p.quality, width=p.image_width, wavelength_step_nm=p.wavelength_step_nm, orders=p.orders,
                earth_shadow=p.earth_shadow, time_iso=sky.time_iso, cache_dir=cache_dir(), solutions=solutions)
            res = physics.SkyResult(mode="ENVIRONMENT", image_path=env.image_path, cache_hit=env.cache_hit,
                                    **env.lamp())
            res.info = dict(env.info)
        else:
            _, res = physics.render_environment(sky, cache_dir())
        if p.moon_lamp:  # the moon lamp of this frame (None while the moon is down)
            res.moon = physics.moon_from_info(res.info) or physics.moon_lamp(sky)
        shutil.copyfile(res.image_path, folder / FRAME_FILE.format(f))
        out.append((f, res))
        if progress:
            progress(f"frame {f} ({k + 1}/{len(skies)}): sun {sky.sun_elevation_deg:.2f}°"
                     + (f" {sky.time_iso}" if sky.time_iso else "")
                     + (" (cached image)" if res.cache_hit else ""))
    return out


# --------------------------------------------------------------------------- the scene


def _keyframe(owner, path: str, frame: int, fcurves: list):
    owner.keyframe_insert(path, frame=frame)
    fcurves.append((owner, path))


def _fcurves(id_block) -> list:
    """Every f-curve of ``id_block``'s action (Blender 4.4+ slotted actions and older ones)."""
    ad = id_block.animation_data
    if ad is None or ad.action is None:
        return []
    try:
        return list(ad.action.fcurves)
    except AttributeError:
        return [fc for layer in ad.action.layers for strip in layer.strips for bag in strip.channelbags
                for fc in bag.fcurves]


def _keys(id_block, data_path: str) -> list:
    """The keyframes of ``data_path`` as ``(frame, value, interpolation)``."""
    return [(kp.co[0], kp.co[1], kp.interpolation) for fc in _fcurves(id_block) if fc.data_path == data_path
            for kp in fc.keyframe_points]


def _restore_keys(owner, id_block, data_path: str, attr: str, keys: list):
    """Put the f-curve of ``data_path`` back to exactly ``keys`` (none: no f-curve)."""
    _remove_fcurves(id_block, data_path)
    for frame, value, interpolation in keys:
        setattr(owner, attr, value)
        owner.keyframe_insert(attr, frame=frame)
    for fc in _fcurves(id_block):
        if fc.data_path == data_path:
            for kp, (_, _, interpolation) in zip(fc.keyframe_points, keys):
                kp.interpolation = interpolation


def _remove_fcurves(id_block, data_path: str):
    """Remove the f-curves of ``data_path`` from ``id_block``'s action (Blender 4.4+ slotted
    actions and older ones alike)."""
    ad = id_block.animation_data
    if ad is None or ad.action is None:
        return
    try:
        ad.action.fcurves  # noqa: B018  (legacy API)
        curves = ad.action.fcurves
        for fc in [fc for fc in curves if fc.data_path == data_path]:
            curves.remove(fc)
        return
    except AttributeError:
        pass
    for layer in ad.action.layers:
        for strip in layer.strips:
            for bag in strip.channelbags:
                for fc in [fc for fc in bag.fcurves if fc.data_path == data_path]:
                    bag.fcurves.remove(fc)


def remove_bake(scene, keep_build: str | None = None):
    """Undo what a bake added outside its own datablocks: the exposure f-curve and the
    record (unless the current build is ``keep_build``); the images' folder is deleted."""
    data = bake_record(scene)
    if not data or data.get("build") == keep_build:
        return
    _remove_fcurves(scene, "view_settings.exposure")
    first = data["frames"].get(str(min(int(f) for f in data["frames"]))) if data.get("frames") else None
    if first is not None:  # the value the build recorded, so Remove Sky can put the user's back
        scene.view_settings.exposure = float(first["exposure"])
    del scene[BAKE_KEY]
    folder = Path(data.get("folder", ""))
    if folder.name.startswith("bake-") and folder.is_dir():
        shutil.rmtree(folder, ignore_errors=True)


def _load_sequence(tx, first_file: Path):
    img = bpy.data.images.load(str(first_file), check_existing=False)
    tx.adopt("images", img)
    img.name = SEQUENCE_NAME
    tx.names.append((img, SEQUENCE_NAME))
    img.source = "SEQUENCE"
    try:
        img.colorspace_settings.name = "Linear Rec.709"
    except TypeError:
        img.colorspace_settings.name = "scene_linear"
    if bpy.data.filepath:
        try:
            img.filepath = bpy.path.relpath(str(first_file))
        except ValueError:  # another drive (Windows)
            pass
    img["skymodel_storage"] = "sequence"
    return img


def apply_bake(scene, world, settings, frames: list, folder: Path, skies: list) -> str:
    """Put a baked sequence into the scene (one transaction): the world reads the EXR
    sequence by frame, the sun lamp and the exposure are keyframed at every frame. Returns
    the build id."""
    first = frames[0][1]
    record = {"folder": str(folder), "frames": {}}
    moons = [res.moon for _, res in frames]
    if first.moon is None:  # a moon lamp when the moon is up in any frame (dark in the others)
        first.moon = next((m for m in moons if m), None)

    def content(tx, coll):
        img = _load_sequence(tx, folder / FRAME_FILE.format(frames[0][0]))
        builder._environment_nodes(tx, world, img)
        env = next(n for n in world.node_tree.nodes
                   if builder.is_ours(n) and n[builder.TAG] == tx.build_id and n.bl_idname == "ShaderNodeTexEnvironment")
        user = env.image_user
        user.frame_start = 1  # file number = scene frame (frames before the range: the first image)
        user.frame_offset = 0
        user.frame_duration = frames[-1][0]
        user.use_auto_refresh = True
        user.use_cyclic = False
        ours = [o for o in coll.objects if builder.is_ours(o) and o[builder.TAG] == tx.build_id and o.type == "LIGHT"]
        sun = next(o for o in ours if "skymodel_sun_elevation_deg" in o.keys())
        moon = next((o for o in ours if "skymodel_moon_elevation_deg" in o.keys()), None)
        light = sun.data
        fcurves: list = []
        old_keys = _keys(scene, "view_settings.exposure")  # a previous bake's: put back on failure
        old_exposure = scene.view_settings.exposure
        tx.undo.append(lambda: (_restore_keys(scene.view_settings, scene, "view_settings.exposure", "exposure",
                                              old_keys), setattr(scene.view_settings, "exposure", old_exposure)))
        _remove_fcurves(scene, "view_settings.exposure")
        for (f, res), (_, sky) in zip(frames, skies):
            sun.rotation_euler = builder.sun_rotation(res.sun_elevation_deg, res.sun_azimuth_deg)
            light.energy = float(res.sun_strength)
            light.color = tuple(float(c) for c in res.sun_colour)
            _keyframe(sun, "rotation_euler", f, fcurves)
            _keyframe(light, "energy", f, fcurves)
            _keyframe(light, "color", f, fcurves)
            if moon is not None:  # below the horizon: dark, kept where it set
                m = res.moon
                if m:
                    moon.rotation_euler = builder.sun_rotation(m["elevation_deg"], m["azimuth_deg"])
                    moon.data.color = tuple(float(c) for c in m["colour"])
                moon.data.energy = float(m["strength"]) if m else 0.0
                _keyframe(moon, "rotation_euler", f, fcurves)
                _keyframe(moon.data, "energy", f, fcurves)
                _keyframe(moon.data, "color", f, fcurves)
            if settings.set_exposure:
                scene.view_settings.exposure = builder.film_exposure(settings, res)
                _keyframe(scene.view_settings, "exposure", f, fcurves)
            record["frames"][str(f)] = {"signature": sky_signature(sky), "file": FRAME_FILE.format(f),
                                        "exposure": builder.film_exposure(settings, res),
                                        "sun_strength": float(res.sun_strength),
                                        "moon_strength": float(res.moon["strength"]) if res.moon else 0.0}
        scene.view_settings.exposure = old_exposure  # what the build records as the value before it
        record["build"] = tx.build_id
        record["keys"] = keys_fingerprint(world)  # what bake_warning compares
        tx.set_key(scene, BAKE_KEY, json.dumps(record))
        first.info["image_storage"] = "sequence"

    return builder.build(scene, world, settings, first, content)


def bake(context, settings=None, folder=None, progress=None) -> dict:
    """Bake the scene's frame range (see the module doc). Returns ``{"frames", "folder",
    "solves", "build"}``. Raises ``SkymodelInputError`` (naming the parameter and frame)
    before any rendering, or :class:`BakeCancelled`; the scene is then unchanged."""
    scene = context.scene
    world = scene.world
    settings = settings or world.skymodel
    params = settings.to_params()
    if params.mode != "ENVIRONMENT":
        raise SkymodelInputError("mode", params.mode, "Environment to bake a time of day (Volumetric: build "
                                                      "each frame)")
    if params.sky_model == "blender":
        raise SkymodelInputError("sky_model", params.sky_model, "a model that makes images (ours, preetham, "
                                                                "openspace_earth); Blender's Sky Texture animates "
                                                                "by itself")
    from . import live

    live.stop()  # a live build in flight is not applied over the bake
    frames = frame_range(scene)
    if scene.frame_start < 1:
        raise SkymodelInputError("frame_start", scene.frame_start, "a scene range starting at frame 1 or later "
                                                                   "(the images are numbered by frame)")
    skies = frame_skies(scene, settings, frames)
    bake_id = uuid.uuid4().hex[:8]
    final = _bake_folder(folder, bake_id)
    tmp = final.with_name(f".{final.name}.partial")
    try:
        done = render_frames(skies, tmp, progress)
        tmp.rename(final)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    try:
        previous = bake_record(scene)
        build_id = apply_bake(scene, world, settings, done, final, skies)
    except BaseException:
        shutil.rmtree(final, ignore_errors=True)
        raise
    if previous and previous.get("folder") != str(final):
        old = Path(previous["folder"])
        if old.name.startswith("bake-") and old.is_dir():
            shutil.rmtree(old, ignore_errors=True)
    return {"frames": len(done), "folder": str(final), "build": build_id}


def animate_day(scene, settings, date, time_from, time_to, every, timezone=None) -> list:
    """Keyframe the settings' UTC date and time so that frame 1, 2, ... are the local times
    ``time_from`` .. ``time_to`` every ``every`` on ``date`` in ``timezone`` (the core's
    :func:`~skymodel.render.timeline.day_frames`; everything checked before any change),
    with constant interpolation; sets the sun from the date and the scene's frame range.
    Returns the frames' :class:`~skymodel.scene.SunPlacement`."""
    from skymodel.render import timeline

    sky = physics.resolve(settings.to_params())
    frames = timeline.day_frames(sky.atmosphere.latitude, sky.atmosphere.longitude, date, time_from, time_to, every,
                                 timezone, allow_night=True)  # a day runs through the night (Environment mode)
    if any(f.time_utc[17:19] != "00" for f in frames):
        raise SkymodelInputError("every", every, "a step of whole minutes (the settings hold minutes)")
    settings.sun_source = "TIME"
    settings.timezone = "UTC"  # the keys hold UTC (every instant exists once in UTC, across DST changes too)
    for k, f in enumerate(frames, start=1):
        t = f.time_utc
        settings.year, settings.month, settings.day = int(t[:4]), int(t[5:7]), int(t[8:10])
        settings.hour, settings.minute = int(t[11:13]), int(t[14:16])
        for prop in ("year", "month", "day", "hour", "minute"):
            settings.keyframe_insert(prop, frame=k)
    _constant_interpolation(scene.world)
    scene.frame_start, scene.frame_end = 1, len(frames)
    return frames


def _constant_interpolation(id_block):
    for fc in _fcurves(id_block):
        if fc.data_path.startswith("skymodel."):
            for kp in fc.keyframe_points:
                kp.interpolation = "CONSTANT"


# --------------------------------------------------------------------------- operators


class SKYMODEL_OT_bake_time(bpy.types.Operator):
    """Render the sky of every frame of the scene's range (keyframed date, time or sun) as an image sequence and keyframe the sun lamp and exposure; works without the add-on once baked"""

    bl_idname = "skymodel.bake_time"
    bl_label = "Bake Time of Day"
    bl_options = {"REGISTER", "UNDO"}

    folder: bpy.props.StringProperty(name="Folder", subtype="DIR_PATH", default="",
                                     description="Where the image sequence goes (empty: beside the saved .blend, "
                                                 "in skymodel_sky/)")

    @classmethod
    def poll(cls, context):
        return context.scene is not None and context.scene.world is not None

    def execute(self, context):
        from .ops import Progress

        progress = Progress(context)
        try:
            r = bake(context, folder=self.folder or None, progress=progress)
        except (SkymodelInputError, BakeCancelled) as ex:
            self.report({"ERROR"}, f"Skymodel: {ex}; scene unchanged")
            return {"CANCELLED"}
        except KeyboardInterrupt:
            self.report({"ERROR"}, "Skymodel: bake cancelled; scene unchanged")
            return {"CANCELLED"}
        except Exception as ex:
            import traceback

            traceback.print_exc()
            self.report({"ERROR"}, f"Skymodel: bake failed, scene unchanged: {type(ex).__name__}: {ex}")
            return {"CANCELLED"}
        finally:
            progress.end()
        self.report({"INFO"}, f"Skymodel: {r['frames']} frames baked into {r['folder']}")
        return {"FINISHED"}


class SKYMODEL_OT_animate_day(bpy.types.Operator):
    """Keyframe the date and time so that the scene's frames run through a day in local time"""

    bl_idname = "skymodel.animate_day"
    bl_label = "Animate Day"
    bl_options = {"REGISTER", "UNDO"}

    date: bpy.props.StringProperty(name="Date", default="2026-06-21", description="Local date, 2026-06-21")
    time_from: bpy.props.StringProperty(name="From", default="19:00", description="Local time of frame 1")
    time_to: bpy.props.StringProperty(name="To", default="22:00", description="Local time of the last frame")
    every: bpy.props.StringProperty(name="Every", default="10min", description="Step: 10min, 1h")
    timezone: bpy.props.StringProperty(name="Time Zone", default="UTC",
                                       description="IANA name (Europe/Madrid), UTC or +02:00")

    @classmethod
    def poll(cls, context):
        return context.scene is not None and context.scene.world is not None

    def invoke(self, context, event):
        zone = context.scene.world.skymodel.timezone.strip()
        if zone:
            self.timezone = zone
        return context.window_manager.invoke_props_dialog(self)

    def execute(self, context):
        try:
            frames = animate_day(context.scene, context.scene.world.skymodel, self.date, self.time_from,
                                 self.time_to, self.every, self.timezone)
        except SkymodelInputError as ex:
            self.report({"ERROR"}, f"Skymodel: {ex}")
            return {"CANCELLED"}
        self.report({"INFO"}, f"Skymodel: {len(frames)} frames keyframed, {frames[0].time_local} to "
                              f"{frames[-1].time_local}; now Bake Time of Day")
        return {"FINISHED"}


def draw_panel(layout, context):
    """The Time of Day box of the add-on's panel."""
    col = layout.column(align=True)
    col.label(text="Time of Day")
    col.operator(SKYMODEL_OT_animate_day.bl_idname, icon="TIME")
    col.operator(SKYMODEL_OT_bake_time.bl_idname, icon="RENDER_ANIMATION")
    data = bake_record(context.scene) if context.scene else None
    warning = bake_warning(context.scene) if context.scene else None
    if warning:
        col.label(text=warning, icon="ERROR")
    elif data:
        col.label(text=f"Baked: {len(data['frames'])} frames", icon="CHECKMARK")


CLASSES = (SKYMODEL_OT_bake_time, SKYMODEL_OT_animate_day)


@bpy.app.handlers.persistent
def _render_pre(scene, *_args):
    """F12 / ``-a``: one line on stderr when the frame's sky is not its own (never raises)."""
    import sys

    try:
        line = render_frame_warning(scene)
    except Exception as ex:  # a render must not fail because of this check
        line = f"skymodel: WARNING frame {scene.frame_current}: could not check the baked sky ({ex})"
    if line:
        print(line, file=sys.stderr)


def register():
    for c in CLASSES:
        bpy.utils.register_class(c)
    if _render_pre not in bpy.app.handlers.render_pre:
        bpy.app.handlers.render_pre.append(_render_pre)


def unregister():
    while _render_pre in bpy.app.handlers.render_pre:
        bpy.app.handlers.render_pre.remove(_render_pre)
    for c in reversed(CLASSES):
        bpy.utils.unregister_class(c)


__all__ = ["bake", "animate_day", "stale_frames", "bake_warning", "render_frame_warning", "keys_fingerprint",
           "remove_bake", "frame_skies", "BakeCancelled"]
