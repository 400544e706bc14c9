"""The user-facing description of an atmosphere: where, when, which aerosols.

>>> from skymodel import Atmosphere
>>> atm = Atmosphere(location="urban", month=6)
>>> prof = atm.optical_profile([400, 550, 700])      # per-height coefficients, m^-1
>>> prof.layered(n_layers=8)                          # the same as piecewise-constant shells

An :class:`Atmosphere` gathers the choices (location preset or latitude/longitude,
month, aerosol type and amount, stratospheric aerosol, ozone column, ground albedo) and
validates them once; :meth:`Atmosphere.optical_profile` turns them into an
:class:`~skymodel.optics.profile.OpticalProfile` for any wavelength grid, combining

* molecules: U.S. Standard Atmosphere 1976 + Bucholtz Rayleigh (:mod:`skymodel.optics.rayleigh`),
* ozone: monthly zonal climatology and measured cross sections (:mod:`skymodel.optics.ozone`),
* aerosols: the type's component mixture, Mie lookups and vertical profile
  (:mod:`skymodel.optics.aerosols`),
* ground albedo (:mod:`skymodel.optics.ground`) and the extraterrestrial solar spectrum
  (:mod:`skymodel.sun`).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from skymodel.optics import aerosols, ground, ozone, rayleigh
from skymodel import sun
from skymodel.data import load_toml
from skymodel import scene
from skymodel.errors import SkymodelInputError, check_finite, check_range
from skymodel.geometry import EARTH_RADIUS_M, TOA_ALTITUDE_M, altitude_grid
from skymodel.optics.profile import OpticalProfile
from skymodel.wavelengths import as_wavelengths


def locations() -> dict[str, dict]:
    """Named location presets (``skymodel/data/presets/locations.toml``)."""
    return dict(load_toml("presets/locations.toml")["locations"])


@dataclass(frozen=True)
class Atmosphere:
    """A validated set of atmosphere choices.

    Defaults, ranges and accepted names are the registry's (:mod:`skymodel.scene`).

    Parameters
    ----------
    location : name of a preset in ``skymodel/data/presets/locations.toml`` (``skymodel presets``
        lists them), or None: with ``latitude``/``longitude`` the place is custom (aerosol type
        and surface from the location rule unless given), without them the registry's default.
    month : 1..12, selects the ozone climatology (and nothing else: aerosol types carry
        no seasonal cycle in the sources).
    day_of_year : 1..366 (1 = 1 January), or None; when given, the ozone climatology of
        that day (interpolated between mid-month values, :func:`skymodel.optics.ozone.month_weights`)
        instead of ``month``'s mean, so consecutive days never jump.
    latitude, longitude : degrees (north, east positive); override the preset's.
    aerosol : tropospheric aerosol type (``skymodel presets``) or ``"none"``, aliases
        accepted (``"desert_dust"`` is ``"desert"``); default the location's.
    aod550 : aerosol optical depth at 550 nm of the tropospheric aerosol (0..10); default: the
        preset's measured ``aod550`` when it has one and its aerosol type is used (Mauna Loa), else
        what the type's number densities give. Exclusive with ``turbidity``.
    turbidity : Preetham et al.'s (1999) (tau_Rayleigh + tau_aerosol) / tau_Rayleigh at 550 nm (1..64).
    stratospheric : ``"background"``, ``"volcanic"`` or ``"none"``.
    stratospheric_aod550 : optical depth of the stratospheric aerosol at 550 nm.
    ozone_du : total ozone column in Dobson units (default: the monthly climatology at
        the latitude).
    albedo : ground albedo 0..1 (default: the location's surface); or ``surface`` name.
    n_altitudes : points of the altitude grid (ground to 100 km above sea level, denser near the ground).
    aerosol_model : ``"guimera2018"`` (the paper's Table 1 mixtures) or ``"opac"``
        (:data:`skymodel.optics.aerosols.MODELS`). None (the default): the registry's default
        (the paper's), or ``"opac"`` when the aerosol type is one only that model has
        (``continental_polluted``, ``maritime_mineral``; the choice is recorded in
        ``location_rules``, which the CLI prints).
    site_altitude_m : height of the ground above sea level [m]: the atmosphere starts there
        (molecules and ozone of the standard atmosphere above that height, so the Rayleigh depth
        is the sea-level one times p(site)/p0; aerosols at their ground concentration at the site).
        Heights in the profile stay heights above the ground; the observer's height above the
        ground is the renderer's ``observer_altitude``.

    Without ``location``, given ``latitude`` and ``longitude``, the aerosol type and the ground
    surface that are not given are chosen by :func:`skymodel.optics.location_rule.choose`
    (polar bands, land mask, deserts); :attr:`location_rules` says which rule chose what.
    """

    location: str | None = None  # the registry's default location unless latitude and longitude are given
    month: int = scene.default("month")
    day_of_year: float | None = scene.default("day_of_year")
    latitude: float | None = scene.default("latitude")
    longitude: float | None = scene.default("longitude")
    aerosol: str | None = scene.default("aerosol")
    aod550: float | None = scene.default("aod550")
    turbidity: float | None = scene.default("turbidity")
    stratospheric: str = scene.default("stratospheric")
    stratospheric_aod550: float | None = scene.default("stratospheric_aod550")
    ozone_du: float | None = scene.default("ozone_du")
    albedo: float | None = scene.default("albedo")
    surface: str | None = scene.default("surface")
    n_altitudes: int = scene.default("n_altitudes")
    co2_ppm: float = rayleigh.DEFAULT_CO2_PPM
    aerosol_model: str | None = None
    site_altitude_m: float | None = scene.default("site_altitude")  # None: the location's (0 without a preset)
    location_rules: tuple = ()

    def __post_init__(self):
        set_ = functools.partial(object.__setattr__, self)
        if isinstance(self.month, bool) or not isinstance(self.month, (int, np.integer)):
            raise SkymodelInputError("month", self.month, scene.parameter("month").allowed_text())
        set_("month", scene.check("month", self.month))
        set_("day_of_year", scene.check("day_of_year", self.day_of_year))
        preset = {}
        if self.location is None and self.latitude is None and self.longitude is None:
            set_("location", scene.default("location"))
        if self.location is not None:
            name = scene.check("location", self.location)
            set_("location", name)
            preset = locations()[name]
        elif self.latitude is None or self.longitude is None:
            raise SkymodelInputError("location", None, "a preset name, or a latitude and a longitude")
        else:
            from skymodel.optics import location_rule

            choice = location_rule.choose(scene.check("latitude", self.latitude),
                                          scene.check("longitude", self.longitude))
            preset = {"aerosol": choice.aerosol, "surface": choice.surface}
            rules = []
            if self.aerosol is None:
                rules.append(f"aerosol {choice.aerosol}: {choice.aerosol_rule}")
            if self.albedo is None and self.surface is None:
                rules.append(f"surface {choice.surface}: {choice.surface_rule}")
            set_("location_rules", tuple(rules))
        if self.aerosol_model is not None:
            set_("aerosol_model", scene.check("aerosol_model", self.aerosol_model))
        site = preset.get("site_altitude_m", 0.0) if self.site_altitude_m is None else self.site_altitude_m
        set_("site_altitude_m", scene.check("site_altitude", site))
        lat = preset.get("latitude") if self.latitude is None else self.latitude
        lon = preset.get("longitude", 0.0) if self.longitude is None else self.longitude
        set_("latitude", scene.parameter("latitude").check(lat))
        set_("longitude", scene.parameter("longitude").check(lon))
        aer_from_preset = self.aerosol is None
        aer = self.aerosol if self.aerosol is not None else preset.get("aerosol", "continental")
        set_("aerosol", scene.check("aerosol", aer))  # aliases (desert_dust) give the canonical name
        if self.aerosol_model is None:
            set_("aerosol_model", _model_for_type(self.aerosol))
            if self.aerosol_model != scene.default("aerosol_model"):
                set_("location_rules", self.location_rules + (
                    f"aerosol model {self.aerosol_model}: {self.aerosol} is a type of that model only",))
        if self.aerosol != "none":  # the type must exist in the chosen model
            set_("aerosol", aerosols.resolve_type(self.aerosol, "aerosol", model=self.aerosol_model))
        set_("stratospheric", scene.check("stratospheric", self.stratospheric))
        if self.aod550 is not None and self.turbidity is not None:
            raise SkymodelInputError("aod550", self.aod550, "either aod550 or turbidity, not both")
        if (self.aod550 is None and self.turbidity is None and aer_from_preset and "aod550" in preset
                and self.aerosol != "none"):
            set_("aod550", float(preset["aod550"]))  # a measured amount of the place (its type's table amount is not)
        for name in ("aod550", "turbidity", "stratospheric_aod550", "ozone_du", "albedo"):
            set_(name, scene.check(name, getattr(self, name)))
        if self.albedo is None:
            surf = self.surface or preset.get("surface", "grass")
            set_("surface", scene.check("surface", surf))
            set_("albedo", ground.surface_albedo(self.surface))
        set_("n_altitudes", scene.check("n_altitudes", self.n_altitudes))
        check_range("co2_ppm", self.co2_ppm, 0.0, 10_000.0, "ppm")

    # ------------------------------------------------------------------ derived
    @property
    def altitudes_m(self) -> np.ndarray:
        """Heights above the ground [m], from the ground (at ``site_altitude_m``) to 100 km above sea level."""
        return altitude_grid(int(self.n_altitudes), TOA_ALTITUDE_M - self.site_altitude_m)

    def optical_profile(self, wavelengths_nm=None) -> OpticalProfile:
        """Per-height optical properties on ``wavelengths_nm`` (default 380–780 nm, 5 nm)."""
        return _build_profile(self, tuple(as_wavelengths(wavelengths_nm).tolist()))


def _model_for_type(aerosol: str) -> str:
    """The aerosol model of a type given without a model: the registry's default model if it
    has the type (or for ``none``), else the first model that has it."""
    default = scene.default("aerosol_model")
    if aerosol == "none":
        return default
    for model in (default, *scene.parameter("aerosol_model").choices):
        try:
            aerosols.resolve_type(aerosol, "aerosol", model=model)
            return model
        except SkymodelInputError:
            continue
    return default  # unknown everywhere: the default model's check names the choices


@functools.lru_cache(maxsize=32)
def _build_profile(atm: Atmosphere, wavelengths: tuple) -> OpticalProfile:
    wl = np.asarray(wavelengths, dtype=float)
    h = atm.altitudes_m
    z = h + atm.site_altitude_m  # heights above sea level, for the standard atmosphere and ozone
    ray = rayleigh.scattering_coefficient(z, wl, atm.co2_ppm)
    o3_density = ozone.ozone_number_density(z, atm.month, atm.latitude, total_column_du=atm.ozone_du,
                                            day_of_year=atm.day_of_year)
    o3 = o3_density[:, None] * ozone.ozone_cross_section(wl)[None, :]
    tau_r550 = float(rayleigh.optical_depth([550.0], atm.co2_ppm, z)[0])
    aer = aerosols.aerosol_optics(
        atm.aerosol, h, wl, aod550=atm.aod550, turbidity=atm.turbidity,
        stratospheric=atm.stratospheric, stratospheric_aod550=atm.stratospheric_aod550,
        rayleigh_optical_depth_550=tau_r550, model=atm.aerosol_model,
    )
    meta = {
        "location": atm.location,
        "latitude_deg": atm.latitude,
        "longitude_deg": atm.longitude,
        "month": atm.month,
        "day_of_year": atm.day_of_year,
        "aerosol": atm.aerosol,
        "aerosol_model": atm.aerosol_model,
        "site_altitude_m": float(atm.site_altitude_m),
        "location_rules": list(atm.location_rules),
        "stratospheric": atm.stratospheric,
        "aod550": float(aer.aod550),
        "angstrom_exponent": float(aer.angstrom_exponent),
        "ozone_du": float(ozone.ozone_column_du(z, o3_density)),
        "albedo": float(atm.albedo),
        "surface": atm.surface,
        "rayleigh_optical_depth_550": tau_r550,
    }
    prof = OpticalProfile(
        wavelengths_nm=wl,
        rayleigh_depolarization=rayleigh.depolarization_factor(wl, atm.co2_ppm),
        aerosol_phase_angles_deg=np.asarray(aer.angles_deg, dtype=float),
        aerosol_phase=np.asarray(aer.phase, dtype=float),
        ground_albedo=ground.albedo_spectrum(atm.albedo, wl),
        solar_irradiance=sun.solar_irradiance(wl),
        planet_radius_m=EARTH_RADIUS_M + atm.site_altitude_m,
        top_altitude_m=TOA_ALTITUDE_M - atm.site_altitude_m,
        metadata=meta,
        altitudes_m=h,
        rayleigh_scattering=ray,
        ozone_absorption=o3,
        aerosol_scattering_by_regime=np.asarray(aer.scattering_by_regime, dtype=float),
        aerosol_absorption=np.asarray(aer.absorption, dtype=float),
    )
    for name in ("rayleigh_scattering", "ozone_absorption", "aerosol_scattering_by_regime", "aerosol_absorption",
                 "aerosol_phase", "solar_irradiance"):
        arr = getattr(prof, name)
        check_finite(name, arr)
        arr.setflags(write=False)
    return prof
