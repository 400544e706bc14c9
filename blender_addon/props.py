"""The settings: a PropertyGroup on ``bpy.types.World.skymodel``.

Angles are stored in radians (Blender's convention for ``subtype='ANGLE'``: the UI shows
degrees) and converted to degrees for the core. The properties of user parameters are made
by :func:`registry_property` from the parameter registry (:mod:`skymodel.scene`: default,
bounds, description) and the quality registry (:mod:`skymodel.render.quality`), so the UI
cannot produce a value the core refuses; what it can still refuse (an unknown location
name, a date that does not exist, a night-time date (sun below -18) in Volumetric mode or with
another sky model than ours, a custom location without an aerosol type) is reported by the Build
operator naming the parameter.
"""

from __future__ import annotations

import math

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, StringProperty

from skymodel import scene

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

#: Labels of the stratospheric choices (the names are the registry's).
_STRATOSPHERIC_LABELS = {"background": ("Background", "Background sulfate layer"),
                         "volcanic": ("Volcanic", "After a large eruption"),
                         "none": ("None", "No stratospheric aerosol")}


def _quality_items() -> list[tuple]:
    """The Quality enum from the quality registry (:mod:`skymodel.render.quality`)."""
    from skymodel.render.quality import QUALITIES

    return [(name, name.title(), f"{q.environment_width_px}x{q.environment_width_px // 2}, "
             f"{q.wavelength_step_nm:g} nm: {q.purpose}") for name, q in QUALITIES.items()]


def _aerosol_model_items() -> list[tuple]:
    """The aerosol models (the registry's choices); each tooltip lists every type's components
    with their fractions (:func:`skymodel.optics.aerosols.type_composition`)."""
    from skymodel.optics.aerosols import type_composition

    labels = {"guimera2018": "Paper (Guimera 2018)", "opac": "OPAC"}
    items = []
    for name in scene.parameter("aerosol_model").choices:
        comp = type_composition(name)
        parts = []
        for t, c in comp.items():
            fr = ", ".join(f"{k} {v.get('table1_fraction', v.get('number_fraction', 0.0)):.3g}"
                           for k, v in c["components"].items())
            parts.append(f"{t}: {fr}")
        text = ("Table 1 proportions by number, Jaenicke sizes, Eq. 12 profile. " if name == "guimera2018"
                else "OPAC mixtures (Hess et al. 1998), number fractions. ")
        items.append((name, labels.get(name, name), text + "; ".join(parts)))
    return items


def _stratospheric_items() -> list[tuple]:
    return [(c, *_STRATOSPHERIC_LABELS.get(c, (c.title(), c))) for c in scene.parameter("stratospheric").choices]


#: Properties made from the parameter registry: property name -> (registry name, Blender label,
#: Blender-only keywords). Defaults, bounds and descriptions come from :mod:`skymodel.scene`.
REGISTRY_PROPERTIES = {
    "location": ("location", "Preset", {"search": _search_location, "search_options": {'SORT'}}),
    "latitude": ("latitude", "Latitude", {"subtype": 'ANGLE', "unit": 'ROTATION', "precision": 3}),
    "longitude": ("longitude", "Longitude", {"subtype": 'ANGLE', "unit": 'ROTATION', "precision": 3}),
    "month": ("month", "Month", {}),
    "year": ("year", "Year", {}),
    "day": ("day", "Day", {}),
    "hour": ("hour", "Hour", {}),
    "minute": ("minute", "Minute", {}),
    "sun_elevation": ("sun_elevation", "Sun Elevation", {"subtype": 'ANGLE', "unit": 'ROTATION', "precision": 2}),
    "sun_azimuth": ("sun_azimuth", "Sun Azimuth", {"subtype": 'ANGLE', "unit": 'ROTATION', "precision": 2}),
    "aod550": ("aod550", "AOD 550 nm", {"precision": 3}),
    "turbidity": ("turbidity", "Turbidity", {"precision": 2}),
    "stratospheric": ("stratospheric", "Stratosphere", {"items": _stratospheric_items}),
    "aerosol_model": ("aerosol_model", "Aerosol Model", {"items": _aerosol_model_items}),
    "site_altitude": ("site_altitude", "Site Altitude", {"subtype": 'DISTANCE', "unit": 'LENGTH'}),
    "ozone_du": ("ozone_du", "Ozone", {"precision": 1}),
    "albedo": ("albedo", "Albedo", {"subtype": 'FACTOR'}),
    "observer_altitude": ("observer_altitude", "Observer Altitude", {"subtype": 'DISTANCE', "unit": 'LENGTH'}),
    "quality": ("quality", "Quality", {"items": _quality_items}),
    "image_width": ("environment_width", "Image Width", {}),
    "n_layers": ("volume_layers", "Volume Layers", {}),
}


def angle_degrees(radians: float, name: str) -> float:
    """Degrees of an angle property (stored as float32 radians) for the core: a value
    within float32 rounding of the registry's bound of ``name`` is that bound, so the
    documented bounds (latitude 90, sun elevation -18) pass the core's check instead of
    arriving as 90.0000025 and being refused."""
    deg = math.degrees(radians)
    p = scene.parameter(name)
    for bound in (p.minimum, p.maximum):
        if bound is not None and abs(deg - bound) <= 1e-6 * max(1.0, abs(bound)):
            return float(bound)
    return deg


def _sky_changed(self, context):
    """Update callback of every setting the sky depends on: the live update
    (:mod:`.live`) queues a rebuild when the World's *Live Update* is on (it never raises)."""
    from . import live, sunpath

    live.on_change(self, context)
    sunpath.refresh(self, context)


def _live_toggled(self, context):
    from . import live

    live.on_toggle(self, context)


def _sun_path_changed(self, context):
    from . import sunpath

    sunpath.on_change(self, context)


def registry_property(prop_name: str):
    """The bpy property of ``prop_name`` (a key of :data:`REGISTRY_PROPERTIES`), built now
    from the registry entry: default (or the entry's ``suggested`` value for a field that
    is switched off by default), hard and soft bounds, description with the range. Angles
    (``subtype='ANGLE'``) are converted to radians; an azimuth is offered over one turn;
    an exclusive minimum becomes the minimum plus one unit (Blender fields cannot exclude
    a bound)."""
    name, label, ui = REGISTRY_PROPERTIES[prop_name]
    p = scene.parameter(name)
    ui = dict(ui, update=_sky_changed)
    text = p.help[:1].upper() + p.help[1:] + f" ({p.range_text()})"
    if "items" in ui:
        items = ui.pop("items")()
        return EnumProperty(name=label, description=text, items=items, default=p.default, **ui)
    if not p.is_number:
        return StringProperty(name=label, description=text, default=p.default or "", **ui)
    value = p.default if p.default is not None else p.suggested
    lo, hi = p.minimum, p.maximum
    if p.exclusive_minimum:
        lo = lo + 1
    if p.integer:
        kw = {"min": int(lo), "max": int(hi), "default": int(value)}
        if p.soft_maximum is not None:
            kw["soft_max"] = int(p.soft_maximum)
        return IntProperty(name=label, description=text, **kw, **ui)
    scale = _DEG if ui.get("subtype") == 'ANGLE' else 1.0
    if name == "sun_azimuth":  # one turn in the UI; the core takes any azimuth modulo 360
        lo, hi = max(lo, 0.0), min(hi, 360.0)
    kw = {"min": lo * scale, "max": hi * scale, "default": float(value or 0.0) * scale}
    if p.soft_minimum is not None:
        kw["soft_min"] = p.soft_minimum * scale
    if p.soft_maximum is not None:
        kw["soft_max"] = p.soft_maximum * scale
    return FloatProperty(name=label, description=text, **kw, **ui)

#: Auto mode's per-effect override choices.
_OVERRIDE_ITEMS = [("AUTO", "Auto", "As the effect planner decides"), ("ON", "On", "Always simulate it"),
                   ("OFF", "Off", "Never simulate it")]


class SkymodelSettings(bpy.types.PropertyGroup):
    # ---- where
    location_source: EnumProperty(update=_sky_changed,
        name="Location", description="A named location preset, or a latitude/longitude of your own",
        items=[("PRESET", "Preset", "A named location (sets latitude, longitude, aerosol type and ground)"),
               ("CUSTOM", "Custom", "Your own latitude and longitude: with Aerosol 'location' the aerosol type and the ground come from the "
                "location rule (polar bands, land/sea mask, deserts; the console prints the rule)")],
        default="PRESET")
    location: registry_property("location")
    latitude: registry_property("latitude")
    longitude: registry_property("longitude")
    # ---- when / sun
    sun_source: EnumProperty(update=_sky_changed,
        name="Sun", description="Place the sun directly, or from a date and time at the location",
        items=[("ANGLES", "Elevation / Azimuth", "Give the sun's elevation and azimuth"),
               ("TIME", "Date and Time", "The core places the sun for the date and time (in the Time Zone) at the location")],
        default="ANGLES")
    month: registry_property("month")
    timezone: StringProperty(
        update=_sky_changed, name="Time Zone", default="UTC",
        description="The zone the date and time are read in: an IANA name (Europe/Madrid, daylight saving "
        "applied), UTC, an offset such as +02:00, or auto (the zone at the place, found offline; needs the "
        "optional timezonefinder package). A local time skipped or repeated at a daylight-saving change is "
        "refused, naming it (the core's --timezone)")
    year: registry_property("year")
    day: registry_property("day")
    hour: registry_property("hour")
    minute: registry_property("minute")
    sun_elevation: registry_property("sun_elevation")
    sun_azimuth: registry_property("sun_azimuth")
    # ---- air
    aerosol: StringProperty(update=_sky_changed,
        name="Aerosol", description="Tropospheric aerosol type; 'location' = the preset's, 'none' = clean air",
        default="location", search=_search_aerosol, search_options={'SORT'})
    aerosol_amount: EnumProperty(update=_sky_changed,
        name="Amount", description="How much aerosol",
        items=[("DEFAULT", "Type Default", "The number densities of the aerosol type"),
               ("AOD", "AOD 550 nm", "Aerosol optical depth at 550 nm"),
               ("TURBIDITY", "Turbidity", "(tau_Rayleigh + tau_aerosol) / tau_Rayleigh at 550 nm")],
        default="DEFAULT")
    aod550: registry_property("aod550")
    turbidity: registry_property("turbidity")
    stratospheric: registry_property("stratospheric")
    aerosol_model: registry_property("aerosol_model")
    site_altitude: registry_property("site_altitude")
    use_ozone: BoolProperty(update=_sky_changed, name="Override Ozone", description="Give the total ozone column yourself",
                            default=False)
    ozone_du: registry_property("ozone_du")
    use_albedo: BoolProperty(update=_sky_changed, name="Override Albedo", description="Give the ground albedo yourself",
                             default=False)
    albedo: registry_property("albedo")
    observer_altitude: registry_property("observer_altitude")
    # ---- how
    mode: EnumProperty(update=_sky_changed,
        name="Mode", description="How the sky enters the scene",
        items=[("AUTO", "Auto", "The effect planner decides from the scene (cameras, farthest object, "
                "resolution) what to simulate: environment or volume shells, ozone, aerosols, orders, resolution"),
               ("ENVIRONMENT", "Environment", "Spectral sky image as the world + sun lamp (any engine)"),
               ("VOLUMETRIC", "Volumetric", "Nested atmosphere volumes around the planet + sun lamp (Cycles)")],
        default="ENVIRONMENT")
    sky_model: EnumProperty(update=_sky_changed,
        name="Sky Model", description="Where the Environment image comes from (the sun lamp follows the model)",
        items=[("ours", "Skymodel", "Spectral marcher: Rayleigh, ozone, Mie aerosols, multiple scattering"),
               ("preetham", "Preetham 1999", "Analytic daylight of Preetham, Shirley & Smits (fast; sun above "
                "the horizon; turbidity from the AOD)"),
               ("openspace_earth", "OpenSpace Earth", "The OpenSpace parameterisation of Costa et al. 2021, "
                "rendered by the spectral marcher"),
               ("blender", "Blender Sky Texture", "Blender's own Sky Texture node (Multiple Scattering) with "
                "matched air, aerosol and ozone densities; lamp and exposure from Skymodel")],
        default="ours")
    quality: registry_property("quality")
    image_width: registry_property("image_width")
    n_layers: registry_property("n_layers")
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
    plan_time_budget: FloatProperty(
        name="Time Budget", description="Most seconds the sky may cost in Auto mode: the environment's build, or "
        "the volume shells' Cycles render of one frame (a choice predicted to take longer is not made)",
        min=1.0, max=1e6, soft_max=3600.0, default=60.0, precision=0, unit='TIME_ABSOLUTE')
    override_multiple_scattering: EnumProperty(name="Multiple Scattering", items=_OVERRIDE_ITEMS, default="AUTO")
    override_aerosols: EnumProperty(name="Aerosols", items=_OVERRIDE_ITEMS, default="AUTO")
    override_ozone: EnumProperty(name="Ozone", items=_OVERRIDE_ITEMS, default="AUTO")
    override_earth_shadow: EnumProperty(name="Earth's Shadow", items=_OVERRIDE_ITEMS, default="AUTO")
    override_ground_reflection: EnumProperty(name="Ground Reflection", items=_OVERRIDE_ITEMS, default="AUTO")
    override_sun_disc: EnumProperty(name="Sun Disc", items=_OVERRIDE_ITEMS, default="AUTO")
    override_aerial_perspective: EnumProperty(name="Volume Shells", items=_OVERRIDE_ITEMS, default="AUTO")
    override_n_layers: IntProperty(name="Shell Layers", description="Volume layers in Auto mode (0: the planner's)",
                                   min=0, max=scene.parameter("volume_layers").maximum, default=0)
    image_storage: EnumProperty(
        name="Sky Image", description="Where the Environment image is kept, so the .blend opens with its sky "
        "wherever it goes (the add-on's cache can be cleared at any time)",
        items=[("PACK", "Pack into .blend", "Pack the image into the .blend file (self-contained)"),
               ("BESIDE", "Save beside .blend", "Copy the image into a 'skymodel_sky' folder next to the saved "
                ".blend and link it by a relative path (an unsaved file packs it instead)")],
        default="PACK")
    set_exposure: BoolProperty(update=_sky_changed, name="Set Exposure", description="Set the view transform (AgX) and the "
                               "exposure from the sky's illuminance", default=True)
    exposure_rule: EnumProperty(update=_sky_changed,
        name="Exposure Rule", description="How Build Sky sets the film exposure",
        items=[("SKY", "Keep Sky Colours", "The incident-light rule in daylight; at a low sun and in twilight "
                "the sky meter (a key that falls with the light, Krawczyk et al. 2005) keeps the sky's colours "
                "instead of washing them to white (docs/blender.md)"),
               ("INCIDENT", "White Plate at 1", "Incident-light rule only: a white plate lit by sun and sky "
                "displays at 1, at noon and at dusk alike (dusk skies wash out)")],
        default="SKY")
    exposure_offset: FloatProperty(update=_sky_changed,
        name="Exposure Offset", description="Stops added to the exposure Build Sky sets (your own look on top)",
        min=-16.0, max=16.0, soft_min=-5.0, soft_max=5.0, default=0.0, precision=2, unit='NONE')
    # ---- live update, sun path, moon
    live_update: BoolProperty(
        update=_live_toggled, name="Live Update", default=False,
        description="Rebuild the sky in the background while you change its settings (Environment mode): a "
        "preview-quality sky shortly after each change, then the chosen quality once the settings have been still "
        "for a moment; the sun lamp and the exposure follow. The interface never waits for it")
    show_sun_path: BoolProperty(
        update=_sun_path_changed, name="Sun Path", default=False,
        description="Show the sun's path over the chosen day (Date and Time) in the viewport as a curve, with "
        "a marker at every hour (local time in the Time Zone); removed when switched off")
    sun_path_radius: FloatProperty(
        update=_sun_path_changed, name="Path Radius", description="Radius of the sun path's sphere",
        min=0.01, max=1e6, soft_max=1000.0, default=10.0, subtype='DISTANCE', unit='LENGTH')
    moon_lamp: BoolProperty(
        update=_sky_changed, name="Moon Lamp", default=True,
        description="With a date and time: a second sun lamp for the moon when it is above the horizon "
        "(direction, lunar irradiance at the observer, colour and disc size from the core's astro module)")
    # ---- written by the last successful build
    last_build: StringProperty(name="Last Build", default="")
    last_info: StringProperty(name="Info", default="")

    def to_params(self) -> SkyParams:
        """Plain, degree-valued parameters for :mod:`.physics`."""
        preset = self.location_source == "PRESET"
        aer = self.aerosol.strip()
        return SkyParams(
            location=self.location.strip() if preset else None,
            latitude_deg=None if preset else angle_degrees(self.latitude, "latitude"),
            longitude_deg=None if preset else angle_degrees(self.longitude, "longitude"),
            month=int(self.month),
            time_utc=(self.year, self.month, self.day, self.hour, self.minute) if self.sun_source == "TIME" else None,
            timezone=(self.timezone.strip() or None) if self.sun_source == "TIME" else None,
            moon_lamp=bool(self.moon_lamp) and self.sun_source == "TIME",
            sun_elevation_deg=angle_degrees(self.sun_elevation, "sun_elevation"),
            sun_azimuth_deg=angle_degrees(self.sun_azimuth, "sun_azimuth"),
            aerosol=None if aer.lower() in ("", "location") else aer,
            aod550=float(self.aod550) if self.aerosol_amount == "AOD" else None,
            turbidity=float(self.turbidity) if self.aerosol_amount == "TURBIDITY" else None,
            stratospheric=self.stratospheric,
            ozone_du=float(self.ozone_du) if self.use_ozone else None,
            albedo=float(self.albedo) if self.use_albedo else None,
            observer_altitude_m=float(self.observer_altitude),
            aerosol_model=self.aerosol_model,
            site_altitude_m=None if preset else float(self.site_altitude),
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
