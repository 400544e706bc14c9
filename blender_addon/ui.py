"""Panels: World properties and the 3D view sidebar ("Sky" tab) show the same settings."""

from __future__ import annotations

import bpy


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

    col = layout.column(align=True)
    col.prop(s, "sun_source", expand=True)
    if s.sun_source == "TIME":
        col.prop(s, "year")
        col.prop(s, "month")
        col.prop(s, "day")
        col.prop(s, "hour")
        col.prop(s, "minute")
    else:
        col.prop(s, "month")
        col.prop(s, "sun_elevation")
        col.prop(s, "sun_azimuth")

    col = layout.column(align=True)
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
        col.prop(s, "image_width")
        col.prop(s, "observer_altitude")
        col.prop(s, "pack_image")
    if s.mode != "ENVIRONMENT":
        col.prop(s, "n_layers")
        col.prop(s, "volume_bounces")
    col.prop(s, "set_exposure")

    row = layout.row(align=True)
    row.scale_y = 1.4
    row.operator("skymodel.build_sky", icon="WORLD")
    row.operator("skymodel.remove_sky", text="", icon="TRASH")

    box = layout.box()
    if s.last_build:
        box.label(text=f"Last build: {s.last_build}", icon="INFO")
        for part in s.last_info.split(" | "):
            box.label(text=part)
    else:
        box.label(text="Not built yet", icon="INFO")


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


def register():
    for c in CLASSES:
        bpy.utils.register_class(c)


def unregister():
    for c in reversed(CLASSES):
        bpy.utils.unregister_class(c)
