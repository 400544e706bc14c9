"""Operators: Build Sky, Remove Sky."""

from __future__ import annotations

import os
import time
import traceback
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


def build(context, settings=None, progress=None):
    """Build the sky of ``context.scene.world`` (used by the operator and by
    ``render.py``); raises on bad input or failure, leaving the scene untouched."""
    scene = context.scene
    world = scene.world
    settings = settings or world.skymodel
    t0 = time.perf_counter()
    params = settings.to_params()
    auto_info = None
    if params.mode == "AUTO":  # the effect planner decides (skymodel.planner)
        from . import scene_description

        auto_plan = scene_description.make_plan(scene, settings)
        params = scene_description.params_from_plan(params, auto_plan)
        auto_info = scene_description.plan_info(auto_plan)
        if progress:
            for line in scene_description.plan_lines(auto_plan):
                progress(f"plan: {line}")
    if progress:
        progress(f"mode {params.mode.lower()}, quality {params.quality}")
    sky = physics.resolve(params)
    if progress:
        progress(f"sun elevation {sky.sun_elevation_deg:.2f}°, azimuth {sky.sun_azimuth_deg:.2f}°"
                 + (f" ({sky.time_iso})" if sky.time_iso else ""))
    if params.mode == "ENVIRONMENT":
        _, result = physics.render_environment(sky, cache_dir(), progress)
    else:
        from . import volumetric

        result = volumetric.compute(sky, cache_dir(), progress)
    result.info = dict(result.info)  # not the cached entry's dict
    if auto_info:
        result.info["auto"] = auto_info["auto"]
        result.info["warnings"] = list(result.info.get("warnings", ())) + auto_info["warnings"]
    result.info["total_s"] = time.perf_counter() - t0
    if params.mode == "ENVIRONMENT":
        builder.apply_environment(scene, world, settings, result, progress)
    else:
        volumetric.apply(scene, world, settings, result, progress)
    result.info["total_s"] = time.perf_counter() - t0
    return result


class SKYMODEL_OT_build_sky(bpy.types.Operator):
    """Compute the sky with the spectral core and put it into the scene (world, sun lamp, volumes)"""

    bl_idname = "skymodel.build_sky"
    bl_label = "Build Sky"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return context.scene is not None and context.scene.world is not None

    def execute(self, context):
        progress = Progress(context)
        try:
            result = build(context, progress=progress)
        except SkymodelInputError as ex:
            self.report({"ERROR"}, f"Skymodel: {ex}")
            return {"CANCELLED"}
        except Exception as ex:  # the scene was rolled back; say what happened
            traceback.print_exc()
            self.report({"ERROR"}, f"Skymodel: build failed, scene unchanged: {type(ex).__name__}: {ex}")
            return {"CANCELLED"}
        finally:
            progress.end()
        self.report({"INFO"}, f"Skymodel: {result.mode.lower()} sky built in {result.info['total_s']:.1f} s"
                    + (" (cached image)" if result.cache_hit else ""))
        for warning in result.info.get("warnings", ()):
            self.report({"WARNING"}, f"Skymodel: {warning}")
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
    """Empty the add-on's cache folder (:func:`cache_dir`). An open image still read from
    the cache (a .blend built before images were packed by default) is packed first, so
    the scene keeps its sky. Returns ``{"files", "bytes", "packed", "folder"}``."""
    from skymodel.render.environment import clear_cache as clear_folder

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
    """Delete the rendered skies the add-on keeps in its cache folder (scenes keep their packed or saved images)"""

    bl_idname = "skymodel.clear_cache"
    bl_label = "Clear Sky Cache"
    bl_options = {"REGISTER"}

    def execute(self, context):
        r = clear_cache()
        text = f"Skymodel: cache cleared, {r['files']} files, {r['bytes'] / 1e6:.1f} MB freed ({r['folder']})"
        if r["packed"]:
            text += f"; {r['packed']} image(s) still read from the cache were packed into the .blend first"
        self.report({"INFO"}, text)
        return {"FINISHED"}


CLASSES = (SKYMODEL_OT_build_sky, SKYMODEL_OT_remove_sky, SKYMODEL_OT_clear_cache)


register, unregister = bpy.utils.register_classes_factory(CLASSES)
