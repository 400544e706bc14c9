"""Panels: World properties and the 3D view sidebar ("Sky" tab) show the same settings."""

from __future__ import annotations

import bpy
from skymodel.errors import SkymodelInputError


def draw_settings(layout, context):
    world = context.scene.world if context.scene else None
    if world is None:
        layout.label(text="The scene has no world", icon="ERROR")
        layout.template_ID(context.scene, "world", new="world.new")
        return
    s = world.skymodel
    layout.use_property_split = True
    layout.use_property_decorate = False

    col = layout.column(align=True)
    col.prop(s, "location_source", expand=True)
    if s.location_source == "PRESET":
        col.prop(s, "location")
    else:
        col.prop(s, "latitude")
        col.prop(s, "longitude")
        col.prop(s, "site_altitude")

    col = layout.column(align=True)
    col.prop(s, "sun_source", expand=True)
    if s.sun_source == "TIME":
        col.prop(s, "year")
        col.prop(s, "month")
        col.prop(s, "day")
        col.prop(s, "hour")
        col.prop(s, "minute")
        col.prop(s, "timezone")
        col.prop(s, "moon_lamp")
    else:
        col.prop(s, "month")
        col.prop(s, "sun_elevation")
        col.prop(s, "sun_azimuth")
    from . import sunpath

    sunpath.draw_panel(col, s, context.scene)

    col = layout.column(align=True)
    col.prop(s, "aerosol_model")
    col.prop(s, "aerosol")
    col.prop(s, "aerosol_amount")
    if s.aerosol_amount == "AOD":
        col.prop(s, "aod550")
    elif s.aerosol_amount == "TURBIDITY":
        col.prop(s, "turbidity")
    col.prop(s, "stratospheric")
    row = col.row(heading="Ozone")
    row.prop(s, "use_ozone", text="")
    sub = row.row()
    sub.active = s.use_ozone
    sub.prop(s, "ozone_du", text="")
    row = col.row(heading="Albedo")
    row.prop(s, "use_albedo", text="")
    sub = row.row()
    sub.active = s.use_albedo
    sub.prop(s, "albedo", text="")

    col = layout.column(align=True)
    col.prop(s, "mode")
    col.prop(s, "quality")
    if s.mode != "VOLUMETRIC":
        col.prop(s, "sky_model")
        col.prop(s, "image_width")
        col.prop(s, "observer_altitude")
        col.prop(s, "image_storage")
    if s.mode != "ENVIRONMENT":
        if s.mode == "VOLUMETRIC":
            col.prop(s, "n_layers")
            if s.sun_source == "ANGLES":
                from . import props, volumetric

                warn = volumetric.twilight_warning(props.angle_degrees(s.sun_elevation, "sun_elevation"), s.n_layers)
                if warn:
                    col.label(text=warn, icon="ERROR")
        col.prop(s, "volume_bounces")
    col.prop(s, "set_exposure")
    if s.set_exposure:
        col.prop(s, "exposure_rule")
        col.prop(s, "exposure_offset")
    if s.mode == "AUTO":
        draw_plan(layout, context, s)

    from . import ops

    job = ops.JOB
    if job is not None and job.running:
        box = layout.box()
        box.label(text="Cancelling the build..." if job.cancelled.is_set() else f"Building: {job.status}",
                  icon="TIME")
        if not job.cancelled.is_set():
            box.label(text="Esc cancels (the scene stays as it was)")
    from . import live

    live.draw_panel(layout, s)
    row = layout.row(align=True)
    row.scale_y = 1.4
    row.operator("skymodel.build_sky", icon="WORLD")
    row.operator("skymodel.remove_sky", text="", icon="TRASH")
    row.operator("skymodel.clear_cache", text="", icon="FILE_CACHE")

    box = layout.box()
    if s.last_build:
        box.label(text=f"Last build: {s.last_build}", icon="INFO")
        for part in s.last_info.split(" | "):
            box.label(text=part)
    else:
        box.label(text="Not built yet", icon="INFO")

    from . import animation

    animation.draw_panel(layout, context)  # Time of Day: Animate Day, Bake Time of Day


def draw_plan(layout, context, s):
    """Auto mode: the effect planner's decisions and reasons, and the overrides."""
    from . import scene_description

    col = layout.column(align=True)
    col.prop(s, "plan_cameras")
    col.prop(s, "plan_tolerance_kind")
    col.prop(s, "plan_tolerance")
    col.prop(s, "plan_time_budget")
    box = layout.box()
    try:
        plan = scene_description.make_plan(context.scene, s)
    except SkymodelInputError as ex:
        box.label(text=f"No plan: {ex}", icon="ERROR")
        return
    except Exception as ex:  # a missing effect table, a broken scene: say so, keep the panel usable
        box.label(text=f"No plan: {type(ex).__name__}: {ex}", icon="ERROR")
        return
    lines = scene_description.plan_lines(plan)
    box.label(text=lines[0], icon="INFO")
    if plan.mode == "volumetric" and (night := scene_description.night_message(s.to_params())):
        box.label(text=night[0].upper() + night[1:], icon="INFO")  # Build Sky builds Environment (ops.prepare)
    for w in plan.warnings():
        box.label(text=w, icon="ERROR")
    for d in plan:
        row = box.row()
        state = "on" if d.on else "off"
        value = scene_description.short_value(d)
        row.label(text=f"{d.name.replace('_', ' ').capitalize()}: {state}" + (f" ({value})" if value else ""))
        prop = scene_description.OVERRIDE_PROPS.get(d.name)
        if prop:
            row.prop(s, prop, text="")
        sub = box.column()
        sub.scale_y = 0.7
        sub.label(text=d.reason)
    box.prop(s, "override_n_layers")


class WORLD_PT_skymodel(bpy.types.Panel):
    bl_label = "Skymodel"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "world"

    @classmethod
    def poll(cls, context):
        return context.world is not None

    def draw(self, context):
        draw_settings(self.layout, context)


class VIEW3D_PT_skymodel(bpy.types.Panel):
    bl_label = "Skymodel"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Sky"

    def draw(self, context):
        draw_settings(self.layout, context)


CLASSES = (WORLD_PT_skymodel, VIEW3D_PT_skymodel)


register, unregister = bpy.utils.register_classes_factory(CLASSES)
