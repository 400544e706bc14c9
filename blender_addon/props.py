"""The settings: a PropertyGroup on ``bpy.types.World.skymodel``.

Angles are stored in radians (Blender's convention for ``subtype='ANGLE'``: the UI shows
degrees) and converted to degrees for the core. Ranges match what the core accepts, so the
UI cannot produce a value the core refuses; what it can still refuse (an unknown location
name, a date that does not exist, a night-time date, a custom location without an
aerosol type) is reported by the Build operator naming the parameter.
"""

from __future__ import annotations

import math

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, StringProperty

from .physics import SkyParams

# search suggestions (kept alive: Blender does not copy the strings of callbacks)
_SUGGESTIONS: dict[str, list] = {}


def _location_names() -> list[str]:
    if "location" not in _SUGGESTIONS:
        try:
            from skymodel.optics.atmosphere import locations

            names = sorted(locations())
        except Exception:  # the core's data modules may be missing in a broken install
            from skymodel.data import load_toml

            names = sorted(load_toml("presets/locations.toml").get("locations", {}))
        _SUGGESTIONS["location"] = names
    return _SUGGESTIONS["location"]


def _aerosol_names() -> list[str]:
    if "aerosol" not in _SUGGESTIONS:
        try:
            from skymodel.optics.aerosols import aerosol_types

            names = sorted(aerosol_types())
        except Exception:
            names = []
        _SUGGESTIONS["aerosol"] = ["location", "none"] + names
    return _SUGGESTIONS["aerosol"]


def _search_location(self, context, edit_text):
    return [n for n in _location_names() if edit_text.lower() in n.lower()] or _location_names()


def _search_aerosol(self, context, edit_text):
    return [n for n in _aerosol_names() if edit_text.lower() in n.lower()] or _aerosol_names()


_DEG = math.pi / 180.0

#: Auto mode's per-effect override choices.
_OVERRIDE_ITEMS = [("AUTO", "Auto", "As the effect planner decides"), ("ON", "On", "Always simulate it"),
                   ("OFF", "Off", "Never simulate it")]


class SkymodelSettings(bpy.types.PropertyGroup):
    # ---- where
    location_source: EnumProperty(
        name="Location", description="A named location preset, or a latitude/longitude of your own",
        items=[("PRESET", "Preset", "A named location (sets latitude, longitude, aerosol type and ground)"),
               ("CUSTOM", "Custom", "Your own latitude and longitude (choose an aerosol type too)")],
        default="PRESET")
    location: StringProperty(
        name="Preset", description="Location preset (skymodel/data/presets/locations.toml)", default="rural",
        search=_search_location, search_options={'SORT'})
    latitude: FloatProperty(
        name="Latitude", description="Degrees north (Custom location; the preset's otherwise)",
        subtype='ANGLE', unit='ROTATION', min=-90 * _DEG, max=90 * _DEG, default=45 * _DEG, precision=3)
    longitude: FloatProperty(
        name="Longitude", description="Degrees east (Custom location)",
        subtype='ANGLE', unit='ROTATION', min=-180 * _DEG, max=180 * _DEG, default=0.0, precision=3)
    # ---- when / sun
    sun_source: EnumProperty(
        name="Sun", description="Place the sun directly, or from a date and time at the location",
        items=[("ANGLES", "Elevation / Azimuth", "Give the sun's elevation and azimuth"),
               ("TIME", "Date and Time", "The core places the sun for the date and UTC time at the location")],
        default="ANGLES")
    month: IntProperty(name="Month", description="Month 1..12 (ozone climatology; and the date's month)",
                       min=1, max=12, default=6)
    year: IntProperty(name="Year", min=1900, max=2100, default=2026)
    day: IntProperty(name="Day", description="Day of the month", min=1, max=31, default=21)
    hour: IntProperty(name="Hour (UTC)", description="Hour, UTC", min=0, max=23, default=12)
    minute: IntProperty(name="Minute", min=0, max=59, default=0)
    sun_elevation: FloatProperty(
        name="Sun Elevation", description="Angle of the sun's centre above the horizon (-12° = end of civil dusk)",
        subtype='ANGLE', unit='ROTATION', min=-12 * _DEG, max=90 * _DEG, default=25 * _DEG, precision=2)
    sun_azimuth: FloatProperty(
        name="Sun Azimuth", description="Clockwise from north (+Y): east (+X) = 90°, south = 180°",
        subtype='ANGLE', unit='ROTATION', min=0.0, max=360 * _DEG, default=180 * _DEG, precision=2)
    # ---- air
    aerosol: StringProperty(
        name="Aerosol", description="Tropospheric aerosol type; 'location' = the preset's, 'none' = clean air",
        default="location", search=_search_aerosol, search_options={'SORT'})
    aerosol_amount: EnumProperty(
        name="Amount", description="How much aerosol",
        items=[("DEFAULT", "Type Default", "The number densities of the aerosol type"),
               ("AOD", "AOD 550 nm", "Aerosol optical depth at 550 nm"),
               ("TURBIDITY", "Turbidity", "(tau_Rayleigh + tau_aerosol) / tau_Rayleigh at 550 nm")],
        default="DEFAULT")
    aod550: FloatProperty(name="AOD 550 nm", description="Aerosol optical depth at 550 nm",
                          min=0.0, max=10.0, soft_max=2.0, default=0.2, precision=3)
    turbidity: FloatProperty(name="Turbidity", description="Linke-style turbidity at 550 nm",
                             min=1.0, max=64.0, soft_max=10.0, default=2.5, precision=2)
    stratospheric: EnumProperty(
        name="Stratosphere", description="Stratospheric aerosol",
        items=[("background", "Background", "Background sulfate layer"),
               ("volcanic", "Volcanic", "After a large eruption"),
               ("none", "None", "No stratospheric aerosol")],
        default="background")
    use_ozone: BoolProperty(name="Override Ozone", description="Give the total ozone column yourself",
                            default=False)
    ozone_du: FloatProperty(name="Ozone", description="Total ozone column in Dobson units",
                            min=1.0, max=1000.0, soft_min=100.0, soft_max=500.0, default=300.0, precision=1)
    use_albedo: BoolProperty(name="Override Albedo", description="Give the ground albedo yourself",
                             default=False)
    albedo: FloatProperty(name="Albedo", description="Ground albedo (Lambertian, grey)", subtype='FACTOR',
                          min=0.0, max=1.0, default=0.2)
    observer_altitude: FloatProperty(
        name="Observer Altitude", description="Height of the viewpoint above the ground (Environment mode)",
        subtype='DISTANCE', unit='LENGTH', min=0.0, max=100_000.0, soft_max=20_000.0, default=0.0)
    # ---- how
    mode: EnumProperty(
        name="Mode", description="How the sky enters the scene",
        items=[("AUTO", "Auto", "The effect planner decides from the scene (cameras, farthest object, "
                "resolution) what to simulate: environment or volume shells, ozone, aerosols, orders, resolution"),
               ("ENVIRONMENT", "Environment", "Spectral sky image as the world + sun lamp (any engine)"),
               ("VOLUMETRIC", "Volumetric", "Nested atmosphere volumes around the planet + sun lamp (Cycles)")],
        default="ENVIRONMENT")
    sky_model: EnumProperty(
        name="Sky Model", description="Where the Environment image comes from (the sun lamp follows the model)",
        items=[("ours", "Skymodel", "Spectral marcher: Rayleigh, ozone, Mie aerosols, multiple scattering"),
               ("preetham", "Preetham 1999", "Analytic daylight of Preetham, Shirley & Smits (fast; sun above "
                "the horizon; turbidity from the AOD)"),
               ("openspace_earth", "OpenSpace Earth", "The OpenSpace parameterisation of Costa et al. 2021, "
                "rendered by the spectral marcher"),
               ("blender", "Blender Sky Texture", "Blender's own Sky Texture node (Multiple Scattering) with "
                "matched air, aerosol and ozone densities; lamp and exposure from Skymodel")],
        default="ours")
    quality: EnumProperty(
        name="Quality", description="Accuracy of the spectral render (and image size)",
        items=[("preview", "Preview", "512x256, 10 nm"), ("final", "Final", "1024x512, 5 nm"),
               ("reference", "Reference", "2048x1024, 5 nm, tight tolerances")],
        default="preview")
    image_width: IntProperty(name="Image Width", description="Environment image width in pixels "
                             "(0: by quality; height = width / 2)", min=0, max=8192, soft_max=4096, default=0)
    n_layers: IntProperty(name="Volume Layers", description="Nested atmosphere layers (Volumetric mode)",
                          min=1, max=24, soft_max=16, default=8)
    volume_bounces: IntProperty(name="Volume Bounces", description="Cycles volume bounces (Volumetric mode; "
                                "0 = single scattering)", min=0, max=64, default=8)
    # ---- Auto mode: the effect planner (skymodel.planner) and the user's overrides
    plan_cameras: EnumProperty(
        name="Plan For", description="Which cameras the plan is for",
        items=[("ACTIVE", "Active Camera", "The scene's active camera (all cameras when there is none)"),
               ("ALL", "All Cameras", "Every camera in the scene")], default="ACTIVE")
    plan_tolerance_kind: EnumProperty(
        name="Tolerance", description="How the plan's error is measured",
        items=[("de2000", "Colour (dE2000)", "Mean CIEDE2000 colour difference of the tone-mapped sky"),
               ("radiance_rel", "Radiance (relative)", "Mean relative luminance error")], default="de2000")
    plan_tolerance: FloatProperty(
        name="Tolerance Value", description="Largest error the plan may make (dE2000, or a fraction for radiance)",
        min=0.001, max=100.0, soft_max=10.0, default=1.0, precision=3)
    override_multiple_scattering: EnumProperty(name="Multiple Scattering", items=_OVERRIDE_ITEMS, default="AUTO")
    override_aerosols: EnumProperty(name="Aerosols", items=_OVERRIDE_ITEMS, default="AUTO")
    override_ozone: EnumProperty(name="Ozone", items=_OVERRIDE_ITEMS, default="AUTO")
    override_earth_shadow: EnumProperty(name="Earth's Shadow", items=_OVERRIDE_ITEMS, default="AUTO")
    override_ground_reflection: EnumProperty(name="Ground Reflection", items=_OVERRIDE_ITEMS, default="AUTO")
    override_sun_disc: EnumProperty(name="Sun Disc", items=_OVERRIDE_ITEMS, default="AUTO")
    override_aerial_perspective: EnumProperty(name="Volume Shells", items=_OVERRIDE_ITEMS, default="AUTO")
    override_n_layers: IntProperty(name="Shell Layers", description="Volume layers in Auto mode (0: the planner's)",
                                   min=0, max=24, default=0)
    pack_image: BoolProperty(name="Pack Image", description="Pack the sky image into the .blend file",
                             default=False)
    set_exposure: BoolProperty(name="Set Exposure", description="Set the view transform (AgX) and the "
                               "exposure from the sky's illuminance", default=True)
    # ---- written by the last successful build
    last_build: StringProperty(name="Last Build", default="")
    last_info: StringProperty(name="Info", default="")

    def to_params(self) -> SkyParams:
        """Plain, degree-valued parameters for :mod:`.physics`."""
        preset = self.location_source == "PRESET"
        aer = self.aerosol.strip()
        return SkyParams(
            location=self.location.strip() if preset else None,
            latitude_deg=None if preset else math.degrees(self.latitude),
            longitude_deg=None if preset else math.degrees(self.longitude),
            month=int(self.month),
            time_utc=(self.year, self.month, self.day, self.hour, self.minute) if self.sun_source == "TIME" else None,
            sun_elevation_deg=math.degrees(self.sun_elevation),
            sun_azimuth_deg=math.degrees(self.sun_azimuth),
            aerosol=None if aer.lower() in ("", "location") else aer,
            aod550=float(self.aod550) if self.aerosol_amount == "AOD" else None,
            turbidity=float(self.turbidity) if self.aerosol_amount == "TURBIDITY" else None,
            stratospheric=self.stratospheric,
            ozone_du=float(self.ozone_du) if self.use_ozone else None,
            albedo=float(self.albedo) if self.use_albedo else None,
            observer_altitude_m=float(self.observer_altitude),
            quality=self.quality,
            image_width=int(self.image_width),
            mode=self.mode,
            n_layers=int(self.n_layers),
            sky_model=self.sky_model,
        )


CLASSES = (SkymodelSettings,)


def register():
    for c in CLASSES:
        bpy.utils.register_class(c)
    bpy.types.World.skymodel = bpy.props.PointerProperty(type=SkymodelSettings, name="Skymodel")


def unregister():
    if hasattr(bpy.types.World, "skymodel"):
        del bpy.types.World.skymodel
    for c in reversed(CLASSES):
        bpy.utils.unregister_class(c)
