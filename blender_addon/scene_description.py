"""Auto mode: describe the Blender scene for the core's effect planner, plan, and turn the
plan into the build's parameters.

* cameras: the active camera, or every camera object (``plan_cameras``); altitude = the
  camera's world z (times the scene's unit scale), view direction = its -Z axis in world
  space (Blender: +X east, +Y north, +Z up, the core's frame), field of view = the lens
  angle of the sensor's larger side (``Camera.angle``); a panoramic camera sees 360
  degrees. No camera: one at the origin that may look anywhere.
* farthest visible object: the largest distance from any camera to any world-space corner
  of the bounding box of a rendered object (the add-on's own objects, cameras, lights and
  empties excluded).
* image size: the render resolution times its percentage; the sky is seen directly
  unless the film is transparent.
* sun elevation: the panel's sun (angles, or date and time at the location, via
  :func:`.physics.resolve`); the tolerance and the time budget from the panel; the Cycles
  samples of the scene (the cost of volume shells).

The plan's environment width is what gets built (a width of the user's own wins); the
planner keeps it within the time budget and says so.

The user's per-effect overrides (Auto / On / Off, and the layer count) are passed to the
planner, which honours them and fits the other decisions into the rest of the tolerance.
"""

from __future__ import annotations

import dataclasses
import math

from skymodel import planner

from . import physics

#: Effect name -> the settings property holding its Auto / On / Off override.
OVERRIDE_PROPS = {
    "multiple_scattering": "override_multiple_scattering",
    "aerosols": "override_aerosols",
    "ozone": "override_ozone",
    "earth_shadow": "override_earth_shadow",
    "ground_reflection": "override_ground_reflection",
    "sun_disc": "override_sun_disc",
    "aerial_perspective": "override_aerial_perspective",
}


def _bound_objects(scene):
    from . import builder

    for obj in scene.objects:
        if obj.type in ("CAMERA", "LIGHT", "EMPTY", "LIGHT_PROBE", "SPEAKER", "ARMATURE"):
            continue
        if builder.is_ours(obj) or obj.hide_render:
            continue
        yield obj


def cameras_of(scene, which: str = "ACTIVE"):
    """The camera objects the plan is for: the active one (or all when there is none)."""
    if which == "ACTIVE" and scene.camera is not None and scene.camera.type == "CAMERA":
        return [scene.camera]
    return [o for o in scene.objects if o.type == "CAMERA" and not o.hide_render]


def camera_view(obj, scale: float = 1.0):
    """The core's ``CameraView`` of a Blender camera object."""
    from mathutils import Vector

    mw = obj.matrix_world
    altitude = max(0.0, float(mw.translation.z) * scale)
    data = obj.data
    if getattr(data, "type", "PERSP") == "PANO":
        return planner.CameraView(altitude_m=min(altitude, planner.TOP_ALTITUDE_M), fov_deg=360.0)
    axis = (mw.to_3x3() @ Vector((0.0, 0.0, -1.0))).normalized()
    fov = math.degrees(float(data.angle)) if getattr(data, "type", "PERSP") == "PERSP" else 1.0
    fov = min(max(fov, 0.1), 360.0)
    return planner.CameraView(altitude_m=min(altitude, planner.TOP_ALTITUDE_M),
                              view_directions=[tuple(axis)], fov_deg=fov)


def farthest_object_m(scene, cameras, scale: float = 1.0) -> float:
    """Largest distance (m) from a camera to a world-space bounding-box corner of a rendered object."""
    from mathutils import Vector

    if not cameras:
        origins = [Vector((0.0, 0.0, 0.0))]
    else:
        origins = [c.matrix_world.translation.copy() for c in cameras]
    far = 0.0
    for obj in _bound_objects(scene):
        mw = obj.matrix_world
        for corner in obj.bound_box:
            w = mw @ Vector(corner)
            for o in origins:
                far = max(far, (w - o).length)
    return far * scale


def describe(scene, settings) -> object:
    """The core's ``SceneDescription`` of ``scene`` with the panel's sun, tolerance and quality
    (the build's time is predicted at the quality it is built at)."""
    scale = scene.unit_settings.scale_length or 1.0
    cams = cameras_of(scene, settings.plan_cameras)
    views = [camera_view(c, scale) for c in cams] or [planner.CameraView()]
    params = dataclasses.replace(settings.to_params(), mode="ENVIRONMENT")
    # at night (a date with the sun below -18) the planner's sun is its lowest, -18: its tables end
    # there, and Auto builds the night in Environment mode (ops.prepare)
    sun_el = max(physics.resolve(params).sun_elevation_deg, physics.MIN_SUN_ELEVATION_DEG)
    r = scene.render
    pct = r.resolution_percentage / 100.0
    return planner.SceneDescription(
        cameras=views, sun_elevation_deg=sun_el, farthest_object_m=min(farthest_object_m(scene, cams, scale), 1e6),
        sky_visible=not r.film_transparent, image_width=max(1, int(r.resolution_x * pct)),
        image_height=max(1, int(r.resolution_y * pct)), tolerance_kind=settings.plan_tolerance_kind,
        tolerance=float(settings.plan_tolerance), time_budget_s=float(settings.plan_time_budget),
        samples=max(1, int(getattr(getattr(scene, "cycles", None), "samples", 64) or 64)), quality=params.quality)


def overrides(settings) -> dict:
    """The user's overrides from the panel, in the planner's form."""
    out = {}
    for effect, prop in OVERRIDE_PROPS.items():
        v = getattr(settings, prop)
        if v != "AUTO":
            out[effect] = v == "ON"
    if int(settings.override_n_layers) > 0:
        out["n_layers"] = int(settings.override_n_layers)
    return out


def night_message(params) -> str | None:
    """Why Auto builds in Environment mode whatever the plan says, for a date/time whose sun is
    below -18 (the volumes show no stars, glow or moon disc; :func:`physics.resolve` refuses
    Volumetric mode there); None in daytime and twilight. Raises on bad input as ``resolve``."""
    el = physics.resolve(dataclasses.replace(params, mode="ENVIRONMENT")).sun_elevation_deg
    if not physics.is_night(el):
        return None
    return (f"night (sun at {el:.1f}°, below {physics.MIN_SUN_ELEVATION_DEG:g}°): Environment mode, since the "
            "volumes show no stars, glow or moon disc")


def make_plan(scene, settings):
    """The plan for ``scene`` (raises the core's ``SkymodelInputError`` on bad input)."""
    return planner.plan(describe(scene, settings), overrides=overrides(settings))


def params_from_plan(params, plan):
    """The build parameters (``physics.SkyParams``) that carry out ``plan``: the effects it
    leaves out as the planner says (:func:`skymodel.planner.apply.atmosphere_changes`, whose
    keywords ``SkyParams`` shares with ``Atmosphere``; the benchmark that proves the plans
    builds the same way), its numerical choices in the add-on's terms (orders 0 = until
    converged)."""
    changes = {"mode": "VOLUMETRIC" if plan.mode == "volumetric" else "ENVIRONMENT",
               "wavelength_step_nm": plan.wavelength_step_nm,
               "orders": plan.orders if plan.orders is not None else 0,
               "earth_shadow": bool(plan["earth_shadow"].on)}
    if plan.n_layers:
        changes["n_layers"] = int(plan.n_layers)
    changes.update(plan.atmosphere_changes())
    if not int(params.image_width):
        changes["image_width"] = environment_width(plan, params.quality)
    return dataclasses.replace(params, **changes)


def environment_width(plan, quality: str = "") -> int:
    """The plan's environment width, as the planner chose it within the time budget (what
    gets built; the quality does not cap it)."""
    return int(plan.environment_width)


def short_value(decision) -> str:
    """A decision's value in a few characters for the panel ("" when it has none)."""
    v = decision.value
    if v is None or isinstance(v, bool):
        return "until converged" if decision.name == "multiple_scattering" and decision.on else ""
    if decision.name == "aerial_perspective":
        lo, hi = v.get("altitude_range_m", (0.0, 0.0))
        return f"{v['n_layers']} layers, {lo / 1000:g}-{hi / 1000:g} km"
    if decision.name == "multiple_scattering":
        return f"{v} order" + ("s" if v != 1 else "")
    if decision.name == "spectral_resolution":
        return f"{v:g} nm"
    if decision.name == "angular_resolution":
        return f"{v}x{v // 2} px"
    return str(v)


def plan_lines(plan) -> list[str]:
    """Short lines for the panel: a header (mode, predicted error against the tolerance,
    predicted time), the plan's warnings, then one per decision."""
    head = (f"{plan.mode.capitalize()}: predicted error {plan.predicted_error:.2g} of "
            f"{plan.scene.tolerance:g} {plan.scene.tolerance_kind}, about {plan.predicted_build_s:.0f} s"
            + (" a frame in Cycles" if plan.mode == "volumetric" else " to build"))
    return [head] + [f"Warning: {w}" for w in plan.warnings()] + plan.summary()


def plan_info(plan) -> dict:
    """What the build's info box shows of the plan: ``auto`` (the header) and ``warnings``."""
    return {"auto": plan_lines(plan)[0], "warnings": [f"Auto plan: {w}" for w in plan.warnings()]}
