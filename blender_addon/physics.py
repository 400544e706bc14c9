"""Everything the add-on computes, without ``bpy``: validated parameters, the sky image,
the sun lamp, the exposure and (volumetric mode) the RGB volume layers.

Every number that ends up in a Blender node comes from the physics core
(:mod:`skymodel`, through ordinary imports); this module only validates the panel's
choices and converts units. The environment image, its colour scale, the sun lamp and the
exposure rule are the core's :mod:`skymodel.render.environment` (its names are re-exported
here); what they mean in Blender is stated below (and in ``docs/blender.md``).

Colour scale ("Blender units")
    Scene-linear Rec.709 (Blender's working space) computed from spectra with the CIE 1931
    2-degree observer: ``RGB = M_709 @ integral(L(lambda) * (xbar, ybar, zbar) dlambda)``
    with L in W m^-2 sr^-1 nm^-1 (:func:`skymodel.colorimetry.spectral_to_rgb`). The
    luminance channel of that RGB (0.2126 R + 0.7152 G + 0.0722 B, Blender's own) is
    therefore ``Y = integral(L ybar dlambda)`` in W m^-2 sr^-1 of ybar-weighted radiance:
    **1.0 in an emission / environment pixel = 683 cd m^-2**. The sun lamp uses the same
    scale for irradiance: strength ``E_Y = integral(E ybar dlambda)`` in W m^-2 (Blender's
    "W/m^2" sun strength), so **1.0 of sun strength = 683 lux**, and a white Lambertian
    plate facing the sun renders at ``E_Y / pi``, the same scale as the sky around it.
    The lamp colour is ``RGB(E) / E_Y`` (luminance 1).

Orientation
    Blender's +X is east, +Y north, +Z up. Sun azimuth is clockwise from north (east 90).
    The environment image is rendered with the core's equirectangular camera centred on
    azimuth 90 (east), which is where Blender's Environment Texture puts the image centre
    (+X), with azimuth increasing to the right in both: no texture rotation is needed.

Exposure (the "incident-light meter" rule)
    ``exposure = log2(pi / E_h)`` where ``E_h`` is the horizontal illuminance at the
    observer in the scale above (direct sun ``E_Y sin(elevation)`` plus the sky's diffuse
    ``sum(Y cos(zenith) dOmega)`` over the upper hemisphere of the rendered sky, sun disc
    excluded). A white horizontal Lambertian surface then displays at scene value 1.0 and
    an 18 % grey card at 0.18 under the view transform (AgX), at noon and at dusk alike.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from skymodel import scene
from skymodel.errors import SkymodelInputError
from skymodel.models import SkyScene, blender_sky, get_model
from skymodel.optics.atmosphere import Atmosphere
from skymodel.render import environment
from skymodel.render.environment import (  # noqa: F401  (the colour scale, used by the add-on)
    CACHE_FORMAT, IMAGE_WIDTH, WAVELENGTH_STEP_NM, default_cache_dir, fit_into_gamut, spectrum_rgb, sun_lamp)
from skymodel.render.exposure import (  # noqa: F401  (the exposure rule, used by the add-on)
    LUMA_709, exposure_from_illuminance, horizontal_illuminance)
from skymodel.render.sky import add_sun_disc
from skymodel.sun import limb_darkening

#: Lowest sun elevation of a sunlit sky (the registry's, -18: astronomical dusk). Angles entered
#: directly are checked against it; a date/time may put the sun lower (the night: the core
#: renders the moonlit sky, stars and glow, :func:`is_night`).
MIN_SUN_ELEVATION_DEG = scene.parameter("sun_elevation").minimum
#: Sky models the Environment can come from (names of ``skymodel.models``, and "blender":
#: Blender's own Sky Texture node): only models with an absolute radiance (the CIE skies
#: are relative and not offered).
SKY_MODELS = ("ours", "preetham", "openspace_earth", "blender")


def _err(parameter, value, allowed):
    return SkymodelInputError(parameter, value, allowed)


# --------------------------------------------------------------------------- parameters


@dataclass(frozen=True)
class SkyParams:
    """The user's choices, plain Python (what the World panel holds), angles in degrees.

    ``location`` None means custom ``latitude_deg``/``longitude_deg`` (then ``aerosol``
    must be given). ``time_utc`` = (year, month, day, hour, minute) places the sun from
    the date (and the month comes from it); otherwise ``sun_elevation_deg`` /
    ``sun_azimuth_deg`` are used. ``aerosol`` None = the location's type. Defaults and
    ranges are the registry's (:mod:`skymodel.scene`).
    """

    location: str | None = scene.default("location")
    latitude_deg: float | None = None
    longitude_deg: float | None = None
    month: int = scene.default("month")
    time_utc: tuple | None = None
    #: the zone ``time_utc`` is read in (IANA name, UTC, +02:00 or auto: :func:`skymodel.scene.resolve_time`);
    #: None: the fields are UTC
    timezone: str | None = None
    sun_elevation_deg: float = scene.default("sun_elevation")
    sun_azimuth_deg: float = scene.default("sun_azimuth")
    aerosol: str | None = None
    aod550: float | None = None
    turbidity: float | None = None
    stratospheric: str = scene.default("stratospheric")
    ozone_du: float | None = None
    albedo: float | None = None
    observer_altitude_m: float = scene.default("observer_altitude")
    aerosol_model: str = scene.default("aerosol_model")
    site_altitude_m: float | None = scene.default("site_altitude")
    quality: str = scene.default("quality")
    image_width: int = scene.default("environment_width")
    mode: str = "ENVIRONMENT"
    n_layers: int = scene.default("volume_layers")
    sky_model: str = "ours"  # one of SKY_MODELS (Environment mode)
    # set by Auto mode's effect plan (skymodel.planner); None / True = the quality's own
    wavelength_step_nm: float | None = None
    orders: int | None = None  # highest scattering order; 0 = until converged
    earth_shadow: bool = True
    moon_lamp: bool = False  # with a date: a second lamp for the moon when it is up (:func:`moon_lamp`)


@dataclass(frozen=True)
class ResolvedSky:
    """Validated parameters: the core's :class:`~skymodel.Atmosphere` and the sun
    (what :func:`resolve` makes of :class:`SkyParams`)."""

    params: SkyParams
    atmosphere: object
    sun_elevation_deg: float
    sun_azimuth_deg: float
    earth_sun_distance_au: float
    time_iso: str | None
    time_local: str | None = None  #: the wall-clock time with its offset, when a date was given
    timezone: str | None = None  #: the zone it was read in (``auto`` resolved to its name)

    def profile(self, wavelengths_nm):
        """The atmosphere's optical profile, solar spectrum scaled to the date's distance."""
        return environment.profile_at_distance(self.atmosphere, wavelengths_nm, self.earth_sun_distance_au)

    def sun_angular_diameter_deg(self) -> float:
        return environment.sun_angular_diameter_deg(self.earth_sun_distance_au)


def _time_iso(t) -> str:
    """``(year, month, day, hour, minute)`` UTC as ISO 8601 text (:func:`skymodel.scene.time_iso`)."""
    return scene.time_iso(t)


def _check_field(field_name: str, parameter: str, value):
    """Check ``value`` against the registry's ``parameter`` (:mod:`skymodel.scene`), naming
    the SkyParams field in the error."""
    if isinstance(value, bool):
        raise _err(field_name, value, scene.parameter(parameter).allowed_text())
    return dataclasses.replace(scene.parameter(parameter), name=field_name).check(value)


def resolve(params: SkyParams) -> ResolvedSky:
    """Validate everything through the core (raises ``SkymodelInputError`` naming the
    parameter) and place the sun."""
    p = params
    quality = scene.check("quality", p.quality)
    # the date (if any) is checked first: a bad day is named before the atmosphere is built
    month = p.month if p.time_utc is None else scene.month_of(p.time_utc)
    day = None if p.time_utc is None else scene.day_of_year(p.time_utc)  # the date's ozone, as the CLI's

    def atmosphere(month, day):
        return Atmosphere(location=p.location, month=month, day_of_year=day, latitude=p.latitude_deg,
                          longitude=p.longitude_deg,
                          aerosol=p.aerosol, aod550=p.aod550, turbidity=p.turbidity, stratospheric=p.stratospheric,
                          ozone_du=p.ozone_du, albedo=p.albedo, aerosol_model=p.aerosol_model,
                          site_altitude_m=p.site_altitude_m)

    atm = atmosphere(month, day)
    if p.time_utc is not None and p.timezone is not None:
        # local time in the zone (auto: the zone at the place), read by the core as --timezone is: a
        # time skipped or repeated at a daylight-saving change is refused with its message; the
        # ozone is the UTC date's
        instant = scene.resolve_time(p.time_utc, p.timezone, atm.latitude, atm.longitude)
        utc = instant.utc_iso
        if (scene.month_of(utc), scene.day_of_year(utc)) != (month, day):
            month, day = scene.month_of(utc), scene.day_of_year(utc)
            atm = atmosphere(month, day)
        sun = scene.place_sun(atm.latitude, atm.longitude, instant.local_iso, allow_night=True)
        local, zone = instant.local_iso, instant.timezone
    elif p.time_utc is not None:  # the date places the sun; the angle fields are not used
        sun = scene.place_sun(atm.latitude, atm.longitude, p.time_utc, allow_night=True)
        local, zone = None, None
    else:
        sun = scene.place_sun(elevation_deg=p.sun_elevation_deg, azimuth_deg=p.sun_azimuth_deg)
        local, zone = None, None
    for rule in atm.location_rules:  # a custom place: which rule chose the aerosol type and the ground
        print(f"skymodel: {rule}")
    elev, az, dist, iso = sun.elevation_deg, sun.azimuth_deg, sun.earth_sun_distance_au, sun.time_utc
    scene.check("observer_altitude", p.observer_altitude_m)
    p = dataclasses.replace(p, quality=quality) if quality != p.quality else p
    if p.mode not in ("ENVIRONMENT", "VOLUMETRIC"):
        raise _err("mode", p.mode, "ENVIRONMENT or VOLUMETRIC")
    _check_field("image_width", "environment_width", p.image_width)
    _check_field("n_layers", "volume_layers", p.n_layers)
    if p.sky_model not in SKY_MODELS:
        raise _err("sky_model", p.sky_model, "one of: " + ", ".join(SKY_MODELS))
    if p.sky_model != "ours" and p.mode != "ENVIRONMENT":
        raise _err("sky_model", p.sky_model, "ours in Volumetric mode (the other models make environment images only)")
    if p.sky_model not in ("ours", "blender") and p.observer_altitude_m != 0.0:
        raise _err("observer_altitude", p.observer_altitude_m, f"0 m with the {p.sky_model} sky model (a ground observer)")
    if float(elev) < MIN_SUN_ELEVATION_DEG:  # night (only a date gets here): the core's night, Environment
        _check_night(p, float(elev), iso)
    return ResolvedSky(p, atm, float(elev), float(az), dist, iso, local, zone)


def is_night(sun_elevation_deg: float) -> bool:
    """Night: the sun below :data:`MIN_SUN_ELEVATION_DEG` (-18), where the core renders no sunlit
    sky, only the night's light (:func:`skymodel.render.night.sunlit`)."""
    return float(sun_elevation_deg) < MIN_SUN_ELEVATION_DEG


def _check_night(p: SkyParams, elevation_deg: float, time_iso) -> None:
    """What a night sky (sun below -18, from a date) needs: our model (the only one with the
    night's light) in Environment mode (the volumes have no stars, glow or moon disc: a moonless
    night would render black; Auto mode switches to Environment by itself, :mod:`.ops`)."""
    at = f"(the sun is at {elevation_deg:.1f} degrees at {time_iso}: night)"
    if p.mode != "ENVIRONMENT":
        raise _err("mode", p.mode, f"Environment at night {at}; the volumes show no stars or glow")
    if p.sky_model != "ours":
        raise _err("sky_model", p.sky_model, f"ours at night {at}; the other models and Blender's Sky Texture "
                                             "have no night")


def image_width(params: SkyParams) -> int:
    return environment.image_width(params.image_width, params.quality)


def cache_key(sky: ResolvedSky, kind: str, **extra) -> str:
    """SHA-256 (first 20 hex digits) of every input that changes the result."""
    return environment.cache_key(sky.atmosphere, sky.sun_elevation_deg, sky.sun_azimuth_deg,
                                 sky.earth_sun_distance_au, sky.params.observer_altitude_m, sky.params.quality,
                                 kind, **extra)


# --------------------------------------------------------------------------- environment


@dataclass
class SkyResult:
    """What the scene builder needs; ``info`` is shown in the panel and written as JSON."""

    mode: str
    sun_elevation_deg: float
    sun_azimuth_deg: float
    sun_strength: float
    sun_colour: tuple
    sun_angle_deg: float
    exposure: float
    image_path: str | None = None
    cache_hit: bool = False
    layers: list = field(default_factory=list)  # volumetric: dicts per ball, outermost first
    ground_albedo_rgb: tuple | None = None
    info: dict = field(default_factory=dict)
    moon: dict | None = None  #: the moon lamp (:func:`moon_lamp`), None when not asked for or the moon is down


def model_environment(sky: ResolvedSky, camera, wavelengths_nm, include_sun=False):
    """``(radiance (H, W, n_wl), direct sun irradiance (n_wl,))`` of the camera's pixels from
    the alternative sky model ``sky.params.sky_model`` (:mod:`skymodel.models`), its own
    sun (Preetham's transmittance; OpenSpace's marcher), scaled to the date's distance."""
    scene = SkyScene(sky.atmosphere, sky.sun_elevation_deg, sky.sun_azimuth_deg, wavelengths_nm, sky.params.quality)
    dirs, valid = camera.directions()
    radiance = np.zeros(valid.shape + (len(wavelengths_nm),))
    res = get_model(sky.params.sky_model, "sky_model")(scene, dirs[valid])
    scale = 1.0 / sky.earth_sun_distance_au**2
    radiance[valid] = np.asarray(res.values) * scale
    sun_irr = np.asarray(res.info["sun_irradiance"], dtype=float) * scale
    if include_sun:
        add_sun_disc(radiance, dirs, valid, camera.pixel_solid_angles(), scene.sun_direction, sun_irr,
                     wavelengths_nm, limb_darkening=limb_darkening)
    return radiance, sun_irr


def blender_sky_texture(sky: ResolvedSky, cache_dir=None, progress=None):
    """Sky model "blender": Blender's own Sky Texture node (Multiple Scattering) with air,
    aerosol and ozone densities matched to the atmosphere
    (:func:`skymodel.models.blender_sky.scene_parameters`); the sun lamp and the exposure
    come from our model at 64x32 (``SkyResult.image_path`` is None, the node settings are in
    ``info["sky_texture"]``). Sky Texture ``sun_rotation`` is the azimuth clockwise from
    north (+Y), as ours (measured with bpy 5.0.1: 0 puts the sun at +Y, 90 degrees at +X)."""
    small = dataclasses.replace(sky, params=dataclasses.replace(sky.params, sky_model="ours", image_width=64))
    _, res = render_environment(small, cache_dir, progress)
    scene = SkyScene(sky.atmosphere, sky.sun_elevation_deg, sky.sun_azimuth_deg, [550.0])
    prm = blender_sky.scene_parameters(scene)
    tex = {"sky_type": "MULTIPLE_SCATTERING", "sun_elevation_deg": sky.sun_elevation_deg,
           "sun_rotation_deg": sky.sun_azimuth_deg, "altitude_m": float(sky.params.observer_altitude_m),
           "air_density": prm["air_density"], "aerosol_density": prm["aerosol_density"],
           "ozone_density": prm["ozone_density"]}
    res.image_path = None
    res.info = dict(res.info, sky_model="blender", sky_texture=tex)
    return None, res


def render_environment(sky: ResolvedSky, cache_dir=None, progress=None, include_sun=False):
    """Render (or reuse) the equirectangular sky for ``sky`` with the core
    (:func:`skymodel.render.environment.render_environment`; the other sky models through
    :func:`model_environment`, Blender's own through :func:`blender_sky_texture`).

    Returns ``(rgb (H, W, 3) float32 or None on a cache hit, SkyResult)``; the EXR and a
    JSON with the lamp and exposure numbers are in ``cache_dir`` under the cache key.
    """
    p = sky.params
    if p.sky_model == "blender":
        return blender_sky_texture(sky, cache_dir, progress)
    rgb, env = environment.render_environment(
        sky.atmosphere, sky.sun_elevation_deg, sky.sun_azimuth_deg, earth_sun_distance_au=sky.earth_sun_distance_au,
        observer_altitude_m=p.observer_altitude_m, quality=p.quality, width=p.image_width,
        wavelength_step_nm=p.wavelength_step_nm, orders=p.orders, earth_shadow=p.earth_shadow,
        include_sun=include_sun, time_iso=sky.time_iso, sky_model=p.sky_model,
        model_radiance=None if p.sky_model == "ours" else (
            lambda camera, wavelengths_nm, disc: model_environment(sky, camera, wavelengths_nm, disc)),
        cache_dir=cache_dir, progress=progress)
    res = SkyResult(mode="ENVIRONMENT", image_path=env.image_path, cache_hit=env.cache_hit, **env.lamp())
    res.info = env.info
    return rgb, res


# --------------------------------------------------------------------------- the moon


#: Wavelength step (nm) of the moon lamp's spectrum (a lamp is one RGB colour: 10 nm is plenty).
MOON_WAVELENGTH_STEP_NM = 10.0


def _moon_above_atmosphere(wavelengths_nm, latitude_deg, longitude_deg, time_utc):
    """The moon lamp for Volumetric mode, where Cycles attenuates the lamp through the
    volumes and the ground sphere casts the horizon: the ROLO irradiance above the
    atmosphere (:func:`skymodel.astro.lunar_irradiance.moon_irradiance`), place and disc
    from :func:`skymodel.astro.moon.moon_position`."""
    from skymodel.astro.lunar_irradiance import moon_irradiance
    from skymodel.astro.moon import moon_position

    pos = moon_position(latitude_deg, longitude_deg, time_utc)
    irr = np.asarray(moon_irradiance(pos, wavelengths_nm), dtype=float)
    strength, colour = sun_lamp(irr, wavelengths_nm)
    visible = 1.0 if float(pos.elevation_deg) > -2.0 * float(pos.angular_radius_deg) else 0.0
    return {"elevation_deg": float(pos.elevation_deg), "azimuth_deg": float(pos.azimuth_deg),
            "strength": float(strength) * visible, "colour": tuple(colour),
            "angle_deg": 2.0 * float(pos.angular_radius_deg), "phase_angle_deg": float(pos.phase_angle_deg),
            "illuminated_fraction": float(pos.illuminated_fraction), "visible_fraction": visible,
            "source": "skymodel.astro (above the atmosphere)"}


def _moon_from_astro(profile, latitude_deg, longitude_deg, time_utc, observer_altitude_m):
    """The moon lamp from :mod:`skymodel.astro` and the core's transmittance table, used
    until the core's own :func:`skymodel.render.night.moon_lamp` is installed: topocentric
    place and disc (:func:`skymodel.astro.moon.moon_position`), ROLO irradiance above the
    atmosphere (:func:`skymodel.astro.lunar_irradiance.moon_irradiance`), times the direct
    transmittance of the atmosphere toward the moon and the fraction of the disc above the
    horizon (:class:`skymodel.render.sun_transmittance.SunTransmittance` of the profile's
    true extinction, as the sun lamp's)."""
    from skymodel.astro.lunar_irradiance import moon_irradiance
    from skymodel.astro.moon import moon_position
    from skymodel.render.medium import factor_medium
    from skymodel.render.sun_transmittance import SunTransmittance

    pos = moon_position(latitude_deg, longitude_deg, time_utc)
    wl = profile.wavelengths_nm
    top_irr = np.asarray(moon_irradiance(pos, wl), dtype=float)
    table = SunTransmittance([factor_medium(profile).extinction], profile.planet_radius_m, profile.top_altitude_m,
                             n_altitudes=16, n_x=128, n_steps=128)
    mu = np.array([math.sin(math.radians(float(pos.elevation_deg)))])
    alt = np.array([float(observer_altitude_m)])
    fraction = float(table.visible_fraction(alt, mu)[0])
    irr = top_irr * np.exp(-table.optical_depth(alt, mu)[0]) * fraction
    strength, colour = sun_lamp(irr, wl)
    return {"elevation_deg": float(pos.elevation_deg), "azimuth_deg": float(pos.azimuth_deg),
            "strength": float(strength), "colour": tuple(colour),
            "angle_deg": 2.0 * float(pos.angular_radius_deg), "phase_angle_deg": float(pos.phase_angle_deg),
            "illuminated_fraction": float(pos.illuminated_fraction), "visible_fraction": fraction,
            "source": "skymodel.astro"}


_MOON_KEYS = ("elevation_deg", "azimuth_deg", "strength", "colour", "angle_deg", "phase_angle_deg",
              "illuminated_fraction", "visible_fraction")


def moon_from_info(info: dict) -> dict | None:
    """The moon lamp the core's environment render recorded in its info (``info["moon"]``,
    issue 24's night rendering, also on a cache hit) in :func:`moon_lamp`'s form; None when
    absent, incomplete or the moon is down."""
    moon = info.get("moon") if isinstance(info, dict) else None
    if not isinstance(moon, dict) or not all(k in moon for k in _MOON_KEYS):
        return None
    out = {k: (tuple(float(c) for c in moon[k]) if k == "colour" else float(moon[k])) for k in _MOON_KEYS}
    if not out["strength"] > 0.0:
        return None
    out["illuminance_lux"] = 683.0 * out["strength"]
    out["source"] = "skymodel.render.environment (info['moon'])"
    return out


def moon_lamp(sky: ResolvedSky, above_atmosphere: bool = False) -> dict | None:
    """The moon as a second lamp for a sky with a date: ``{"elevation_deg", "azimuth_deg"
    (topocentric, clockwise from north), "strength" (W m^-2 ybar-weighted at the observer,
    the sun lamp's scale: 1.0 = 683 lux on a surface facing the moon), "colour" (Rec.709,
    luminance 1), "angle_deg" (apparent diameter), "phase_angle_deg",
    "illuminated_fraction", "visible_fraction", "illuminance_lux", "source"}``; None
    without a date or when the moon is below the horizon (no light reaches the observer).

    From the core's :func:`skymodel.render.night.moon_lamp` when it is installed; else
    from :mod:`skymodel.astro` (:func:`_moon_from_astro`). ``above_atmosphere`` (Volumetric
    mode, whose volumes attenuate the lamp as they do the sun's): the irradiance above the
    atmosphere instead (:func:`_moon_above_atmosphere`; the lamp is kept while the disc is
    within two radii below the horizon, where the ground sphere shades it). No bpy (safe in
    the build thread)."""
    if sky.time_iso is None:
        return None
    from skymodel.wavelengths import default_wavelengths

    wl = default_wavelengths(MOON_WAVELENGTH_STEP_NM)
    lat, lon, alt = sky.atmosphere.latitude, sky.atmosphere.longitude, float(sky.params.observer_altitude_m)
    if above_atmosphere:
        moon = _moon_above_atmosphere(wl, lat, lon, sky.time_iso)
        if not moon["strength"] > 0.0:
            return None
        moon["illuminance_lux"] = 683.0 * moon["strength"]
        return moon
    profile = sky.atmosphere.optical_profile(wl)
    try:
        from skymodel.render.night import moon_lamp as core_moon_lamp
    except ImportError:
        core_moon_lamp = None
    if core_moon_lamp is not None:
        lamp = core_moon_lamp(profile, lat, lon, sky.time_iso, observer_altitude_m=alt)
        moon = {"elevation_deg": float(lamp.elevation_deg), "azimuth_deg": float(lamp.azimuth_deg),
                "strength": float(lamp.strength), "colour": tuple(float(c) for c in lamp.colour),
                "angle_deg": float(lamp.angle_deg), "phase_angle_deg": float(lamp.phase_angle_deg),
                "illuminated_fraction": float(lamp.illuminated_fraction),
                "visible_fraction": float(lamp.visible_fraction), "source": "skymodel.render.night"}
    else:
        moon = _moon_from_astro(profile, lat, lon, sky.time_iso, alt)
    if not moon["strength"] > 0.0:
        return None
    moon["illuminance_lux"] = 683.0 * moon["strength"]
    return moon
