"""Operators: Build Sky, Remove Sky."""

from __future__ import annotations

import dataclasses
import os
import threading
import time
import traceback
from dataclasses import dataclass
from pathlib import Path

import bpy
from skymodel.errors import SkymodelInputError

from . import builder, physics

class Progress:
    """Progress of a build: the cursor progress in the UI (``wm.progress_*``, which does
    nothing in background mode) and a printed, time-stamped line per stage."""

    def __init__(self, context):
        self.wm = context.window_manager if context is not None else None
        self.t0 = time.perf_counter()
        self.n = 0
        self.lines: list[str] = []
        if self.wm is not None:
            self.wm.progress_begin(0, 100)

    def __call__(self, text: str):
        self.n += 1
        line = f"[skymodel {time.perf_counter() - self.t0:6.1f}s] {text}"
        self.lines.append(line)
        print(line, flush=True)
        if self.wm is not None:
            self.wm.progress_update(min(99, 5 * self.n))

    def end(self):
        if self.wm is not None:
            self.wm.progress_end()


def cache_dir() -> Path:
    """Where rendered skies are cached: ``$SKYMODEL_CACHE_DIR``; else, installed as an
    extension, its user folder (``bpy.utils.extension_path_user(__package__, path="cache")``:
    ``.../extensions/.user/<repo>/skymodel/cache``, which survives updating or reinstalling
    the extension, unlike the extension's own folder); else (an add-on run from a checkout)
    Blender's user data folder (``bpy.utils.user_resource("DATAFILES", path="skymodel/cache")``).
    Nothing a .blend needs lives only here: the sky image is packed into the .blend or
    copied beside it (``image_storage``), so the cache can be cleared at any time."""
    env = os.environ.get("SKYMODEL_CACHE_DIR")
    if env:
        return Path(env)
    pkg = __package__ or ""
    if pkg.startswith("bl_ext."):
        try:
            return Path(bpy.utils.extension_path_user(pkg, path="cache", create=True))
        except (ValueError, RuntimeError, OSError):
            pass
    try:
        return Path(bpy.utils.user_resource("DATAFILES", path="skymodel/cache", create=True))
    except (ValueError, RuntimeError, OSError):
        return physics.default_cache_dir()


class BuildCancelled(Exception):
    """Raised inside a build's computation when the user cancelled it (Esc)."""


@dataclass
class Prepared:
    """What the main thread hands the computation: validated, bpy-free (see :func:`prepare`)."""

    sky: object
    mode: str
    cache: Path
    auto_info: dict | None
    t0: float
    live_stage: str | None = None  #: "preview" / "final" for a live update's build (:mod:`.live`)


def prepare(context, settings=None, progress=None, params=None, live_stage=None) -> Prepared:
    """Main thread: read the panel (and, in Auto mode, the scene for the planner), validate
    through the core, place the sun. Raises ``SkymodelInputError`` naming the parameter.
    ``params``: build these instead of the panel's (the live update's preview stage)."""
    scene = context.scene
    settings = settings or scene.world.skymodel
    t0 = time.perf_counter()
    params = settings.to_params() if params is None else params
    auto_info = None
    if params.mode == "AUTO":  # the effect planner decides (skymodel.planner)
        from . import scene_description

        auto_plan = scene_description.make_plan(scene, settings)
        params = scene_description.params_from_plan(params, auto_plan)
        auto_info = scene_description.plan_info(auto_plan)
        if params.mode == "VOLUMETRIC" and (night := scene_description.night_message(params)):
            params = dataclasses.replace(params, mode="ENVIRONMENT")  # the volumes show no stars or glow
            auto_info["warnings"].append(f"Auto plan: {night}")
        if progress:
            for line in scene_description.plan_lines(auto_plan):
                progress(f"plan: {line}")
    if progress:
        progress(f"mode {params.mode.lower()}, quality {params.quality}")
    sky = physics.resolve(params)
    if progress:
        progress(f"sun elevation {sky.sun_elevation_deg:.2f}°, azimuth {sky.sun_azimuth_deg:.2f}°"
                 + (f" ({sky.time_iso})" if sky.time_iso else "")
                 + (f", local {sky.time_local} {sky.timezone}" if sky.time_local else ""))
    return Prepared(sky, params.mode, cache_dir(), auto_info, t0, live_stage)


def compute(prep: Prepared, progress=None):
    """The physics (no bpy: safe in a background thread): the sky image or the volume layers."""
    if prep.mode == "ENVIRONMENT":
        _, result = physics.render_environment(prep.sky, prep.cache, progress)
    else:
        from . import volumetric

        result = volumetric.compute(prep.sky, prep.cache, progress)
    result.info = dict(result.info)  # not the cached entry's dict
    if prep.sky.params.moon_lamp:  # the moon as a second lamp, when it is up (physics.moon_lamp)
        volumetric = prep.mode == "VOLUMETRIC"
        result.moon = (None if volumetric else physics.moon_from_info(result.info)) or physics.moon_lamp(
            prep.sky, above_atmosphere=volumetric)
    if prep.live_stage:
        result.info["live"] = prep.live_stage
    if prep.sky.time_local and prep.sky.timezone not in (None, "UTC"):
        result.info["time_local"] = f"{prep.sky.time_local} {prep.sky.timezone}"
    if prep.auto_info:
        result.info["auto"] = prep.auto_info["auto"]
        result.info["warnings"] = list(result.info.get("warnings", ())) + prep.auto_info["warnings"]
    result.info["total_s"] = time.perf_counter() - prep.t0
    return result


def apply(context, prep: Prepared, result, settings=None, progress=None):
    """Main thread: put the computed sky into the scene (one transaction: all or nothing)."""
    scene = context.scene
    world = scene.world
    settings = settings or world.skymodel
    if prep.mode == "ENVIRONMENT":
        builder.apply_environment(scene, world, settings, result, progress)
    else:
        from . import volumetric

        volumetric.apply(scene, world, settings, result, progress)
    result.info["total_s"] = time.perf_counter() - prep.t0
    return result


def build(context, settings=None, progress=None):
    """Build the sky of ``context.scene.world`` in one go (the operator's ``execute``, used
    from scripts, and ``render.py``); raises on bad input or failure, leaving the scene untouched.
    A live update's build (:mod:`.live`) is cancelled first and waited for."""
    if JOB is not None and JOB.running:
        raise RuntimeError("a sky build is already running (Esc cancels it)")
    from . import live

    live.stop(wait=600.0)
    prep = prepare(context, settings, progress)
    return apply(context, prep, compute(prep, progress), settings, progress)


class BuildJob:
    """One build whose physics runs in a background thread (:func:`compute`), started and
    finished on the main thread (:func:`prepare`, :func:`apply`). ``cancel()`` makes the
    computation stop at its next progress step; nothing touches the scene before
    :meth:`finish`, so a cancelled or failed job leaves it exactly as it was."""

    def __init__(self, context, settings=None, params=None, live_stage=None):
        self.lines: list[str] = []
        self.status = "starting"
        self.cancelled = threading.Event()
        self.result = None
        self.error: BaseException | None = None
        self.t0 = time.perf_counter()
        self.prep = prepare(context, settings, self._progress, params=params, live_stage=live_stage)
        self.thread = threading.Thread(target=self._run, name="skymodel-build", daemon=True)
        #: prepared, waiting for a live update's thread to end before starting (Build Sky's modal)
        self.deferred = False

    def _progress(self, text: str):
        if self.cancelled.is_set():
            raise BuildCancelled("cancelled")
        line = f"[skymodel {time.perf_counter() - self.t0:6.1f}s] {text}"
        self.lines.append(line)
        self.status = text
        print(line, flush=True)

    def _run(self):
        try:
            self.result = compute(self.prep, self._progress)
            if self.cancelled.is_set():
                raise BuildCancelled("cancelled")
        except BaseException as ex:  # reported on the main thread by finish()
            self.error = ex

    def start(self):
        self.deferred = False
        self.thread.start()
        return self

    @property
    def running(self) -> bool:
        return self.deferred or self.thread.is_alive()

    def cancel(self):
        self.cancelled.set()
        self.deferred = False  # never started: nothing to stop
        self.status = "cancelling"

    def wait(self, timeout=None) -> bool:
        if self.thread.ident is not None:
            self.thread.join(timeout)
        return not self.running

    def finish(self, context, settings=None):
        """Main thread, once the thread is done: apply the result (or re-raise its error;
        :class:`BuildCancelled` when cancelled, the scene untouched)."""
        if self.running:
            raise RuntimeError("the build is still running")
        if self.cancelled.is_set():
            raise BuildCancelled("cancelled")
        if self.error is not None:
            raise self.error
        return apply(context, self.prep, self.result, settings, self._progress)


#: The build in flight (one at a time), or None.
JOB: BuildJob | None = None


def _report_failure(op, ex) -> None:
    if isinstance(ex, BuildCancelled) or isinstance(ex, KeyboardInterrupt):
        op.report({"WARNING"}, "Skymodel: build cancelled, scene unchanged")
    elif isinstance(ex, SkymodelInputError):
        op.report({"ERROR"}, f"Skymodel: {ex}")
    else:  # the scene was rolled back; say what happened
        traceback.print_exception(type(ex), ex, ex.__traceback__)
        op.report({"ERROR"}, f"Skymodel: build failed, scene unchanged: {type(ex).__name__}: {ex}")


def _report_success(op, result) -> None:
    op.report({"INFO"}, f"Skymodel: {result.mode.lower()} sky built in {result.info['total_s']:.1f} s"
              + (" (cached image)" if result.cache_hit else ""))
    for warning in result.info.get("warnings", ()):
        op.report({"WARNING"}, f"Skymodel: {warning}")


class SKYMODEL_OT_build_sky(bpy.types.Operator):
    """Compute the sky with the spectral core and put it into the scene (world, sun lamp, volumes); Esc cancels"""

    bl_idname = "skymodel.build_sky"
    bl_label = "Build Sky"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return context.scene is not None and context.scene.world is not None

    def execute(self, context):  # scripts and headless: in one go
        if JOB is not None and JOB.running:
            self.report({"ERROR"}, "Skymodel: a sky build is already running (Esc cancels it)")
            return {"CANCELLED"}
        progress = Progress(context)
        try:
            result = build(context, progress=progress)
        except BaseException as ex:
            _report_failure(self, ex)
            return {"CANCELLED"}
        finally:
            progress.end()
        _report_success(self, result)
        return {"FINISHED"}

    def invoke(self, context, event):  # the UI: a modal build that never freezes the interface
        global JOB
        if JOB is not None and JOB.running:
            self.report({"ERROR"}, "Skymodel: a sky build is already running" + (
                " (cancelled, stopping at its next step)" if JOB.cancelled.is_set() else " (Esc cancels it)"))
            return {"CANCELLED"}
        if context.window is None or context.window_manager is None:
            return self.execute(context)
        from . import live

        live.stop()  # a live update's build: cancelled; ours starts when its thread has ended
        try:
            JOB = BuildJob(context)
            if live.running():
                JOB.deferred = True
            else:
                JOB.start()
        except BaseException as ex:
            _report_failure(self, ex)
            return {"CANCELLED"}
        wm = context.window_manager
        self._timer = wm.event_timer_add(0.2, window=context.window)
        wm.progress_begin(0, 100)
        wm.modal_handler_add(self)
        self._status(context, "Skymodel: building the sky (Esc cancels)")
        return {"RUNNING_MODAL"}

    def _status(self, context, text):
        try:
            context.workspace.status_text_set(text)
        except (AttributeError, RuntimeError):
            pass
        for area in getattr(context.screen, "areas", ()):
            if area.type in ("PROPERTIES", "VIEW_3D", "STATUSBAR"):
                area.tag_redraw()

    def _end(self, context):
        wm = context.window_manager
        wm.event_timer_remove(self._timer)
        wm.progress_end()
        self._status(context, None)

    def modal(self, context, event):
        global JOB
        job = JOB
        if job is None:
            return {"CANCELLED"}
        if event.type == "ESC" and event.value == "PRESS":
            # the scene has not been touched: end now; the thread stops at its next step
            # (JOB stays set until it has, so a new build waits for the CPU to be free)
            job.cancel()
            self._end(context)
            self.report({"WARNING"}, "Skymodel: build cancelled, scene unchanged")
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        if job.deferred:
            from . import live

            if not live.running():
                job.start()
            return {"RUNNING_MODAL"}
        if job.running:
            context.window_manager.progress_update(min(99, len(job.lines) * 5))
            self._status(context, f"Skymodel: {job.status} (Esc cancels)")
            return {"RUNNING_MODAL"}
        self._end(context)
        JOB = None
        try:
            result = job.finish(context)
        except BaseException as ex:
            _report_failure(self, ex)
            return {"CANCELLED"}
        _report_success(self, result)
        return {"FINISHED"}


class SKYMODEL_OT_remove_sky(bpy.types.Operator):
    """Remove the sky nodes, lamp, volumes and images the add-on created (your own data stays)"""

    bl_idname = "skymodel.remove_sky"
    bl_label = "Remove Sky"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return context.scene is not None

    def execute(self, context):
        from . import live

        live.stop()  # a live build in flight must not put the sky back
        builder.remove_all(context.scene, context.scene.world)
        if context.scene.world is not None:
            context.scene.world.skymodel.last_build = ""
            context.scene.world.skymodel.last_info = ""
        return {"FINISHED"}


def _in_folder(path: str, folder: Path) -> bool:
    try:
        return Path(bpy.path.abspath(path)).resolve().parent == folder.resolve()
    except (OSError, ValueError):
        return False


def clear_cache() -> dict:
    """Empty the add-on's cache folder (:func:`cache_dir`): the sky images, their records and
    the multiple-scattering solutions in its ``solutions/`` (only the files the cache wrote;
    :func:`skymodel.render.environment.clear_cache`). An open image still read from the
    cache (a .blend built before images were packed by default) is packed first, so the
    scene keeps its sky. Refused while a build runs (it writes into the folder). Returns
    ``{"files", "bytes", "packed", "folder"}``."""
    from skymodel.render.environment import clear_cache as clear_folder

    from . import live

    if (JOB is not None and JOB.running) or live.running():
        raise RuntimeError("a sky build is running; clear the cache when it has finished (Esc cancels it)")
    folder = cache_dir()
    packed = 0
    for img in bpy.data.images:
        if img.packed_file is None and img.source == "FILE" and _in_folder(img.filepath, folder):
            try:
                img.pack()
                packed += 1
            except RuntimeError as ex:
                print(f"[skymodel] could not pack {img.name}: {ex}")
    n, size = clear_folder(folder) if folder.is_dir() else (0, 0)
    return {"files": n, "bytes": size, "packed": packed, "folder": str(folder)}


class SKYMODEL_OT_clear_cache(bpy.types.Operator):
    """Delete the rendered skies and multiple-scattering solutions the add-on keeps in its cache folder (scenes keep their packed or saved images)"""

    bl_idname = "skymodel.clear_cache"
    bl_label = "Clear Sky Cache"
    bl_options = {"REGISTER"}

    def execute(self, context):
        try:
            r = clear_cache()
        except RuntimeError as ex:
            self.report({"ERROR"}, f"Skymodel: {ex}")
            return {"CANCELLED"}
        text = f"Skymodel: cache cleared, {r['files']} files, {r['bytes'] / 1e6:.1f} MB freed ({r['folder']})"
        if r["packed"]:
            text += f"; {r['packed']} image(s) still read from the cache were packed into the .blend first"
        self.report({"INFO"}, text)
        return {"FINISHED"}


CLASSES = (SKYMODEL_OT_build_sky, SKYMODEL_OT_remove_sky, SKYMODEL_OT_clear_cache)


register, unregister = bpy.utils.register_classes_factory(CLASSES)
