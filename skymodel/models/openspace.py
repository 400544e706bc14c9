"""The OpenSpace parameterisation (Costa et al. 2021) for Earth and Mars, rendered by our marcher.

Costa, Bock, Emmart, Hansen, Ynnerman & Silva, "Interactive Visualization of Atmospheric
Effects for Celestial Bodies", IEEE TVCG 27(2), 2021, describe an atmosphere by a few
analytic ingredients; :func:`openspace_profile` turns them into an
:class:`~skymodel.optics.profile.OpticalProfile` (per-metre coefficients on an altitude grid, the
planet's own radius and atmosphere top) that :class:`skymodel.render.marcher.SkyMarcher`
renders like ours, with multiple scattering, so any difference from ``ours`` comes from the
parameterisation and not from the solver. The numbers are in
``skymodel/data/sources/models/openspace.toml`` (each with its source); in short:

* Rayleigh: ``beta_R = 8 pi^3 (n^2 - 1)^2 / (3 N lambda^4) (6 + 3 d) / (6 - 7 d)`` at the
  ground, ``exp(-h / H_R)`` above; Penndorf's phase function (``d = 0.035`` on Earth gives
  exactly ``0.7629 (1 + 0.9324 cos^2 theta) / 4 pi``; Mars uses CO2's d = 0.09).
* Mie (haze, Martian dust): ``exp(-h / H_M)`` density, the spectral shape of van de
  Hulst's turbidity formula ``0.434 c pi (2 pi / lambda)^(v - 2) K(lambda)`` with the
  level set by an optical depth at 550 nm (Earth: the scene's AOD550, or the turbidity
  ``T = (tau_R + tau_M) / tau_R``; Mars: the dust optical depth). We do not use the
  formula's absolute concentration ``c = (0.6544 T - 0.6510) 1e-16``: read in SI units it
  gives ~8e-3 m^-1 at T = 2 (an optical depth near 9 over a 1.2 km scale height), so the
  turbidity definition fixes the level instead. Scattering / extinction = the assets'
  single-scattering albedo.
* Mie phase: double Henyey-Greenstein ``alpha HG(g1(lambda)) + (1 - alpha) HG(-g2)``.
* Oxygen absorption ``exp(-h / H_O2)`` and an ozone layer (triangular 10-40 km, our shape)
  with skymodel's spectral ozone cross section, put in the profile's ``ozone_absorption``.
* The sun: our extraterrestrial spectrum scaled by ``1 / distance_au^2`` (Mars 1.5237 AU).

Observers: the marcher takes observers from the ground up to
:data:`skymodel.render.marcher.MAX_OBSERVER_ALTITUDE_M` (120 km) on any planet, so above
the top of the OpenSpace atmospheres (70 km on Earth, 77 km on Mars) the observer is in
space and sees the lit limb from outside (``observer_altitude_m`` of the models below).
"""

from __future__ import annotations

import functools

import numpy as np

from skymodel.data import load_toml
from skymodel.errors import check_choice, check_finite, check_range
from skymodel.optics.profile import OpticalProfile
from skymodel.models import ModelRadiance, SkyModel, SkyScene, register

TABLE = "sources/models/openspace.toml"
PLANETS = ("earth", "mars")
#: Scattering angles (degrees) of the tabulated Mie phase functions: fine near the
#: forward peak, 1 degree steps beyond 10 degrees.
PHASE_ANGLES_DEG = np.unique(np.concatenate([[0.0], np.geomspace(0.01, 10.0, 160), np.arange(10.0, 180.5, 1.0)]))


@functools.lru_cache(maxsize=1)
def _table() -> dict:
    return load_toml(TABLE)


def planet_parameters(planet: str) -> dict:
    """The preset of ``planet`` ("earth" or "mars"), a copy."""
    return dict(_table()[check_choice("planet", str(planet).lower(), PLANETS)])


def henyey_greenstein(cos_theta, g):
    """Henyey-Greenstein phase function, sr^-1 (normalised over 4 pi); broadcasts."""
    c = np.asarray(cos_theta, dtype=float)
    g = np.asarray(g, dtype=float)
    return (1.0 - g * g) / (4.0 * np.pi * (1.0 + g * g - 2.0 * g * c) ** 1.5)


def double_hg(cos_theta, g1, g2, alpha):
    """``alpha HG(g1) + (1 - alpha) HG(-g2)``: a forward lobe and a backward lobe, sr^-1."""
    return alpha * henyey_greenstein(cos_theta, g1) + (1.0 - alpha) * henyey_greenstein(cos_theta, -np.asarray(g2))


def penndorf_phase(cos_theta):
    """Penndorf's Rayleigh phase function 0.7629 (1 + 0.9324 cos^2 theta) / (4 pi), sr^-1."""
    c = np.asarray(cos_theta, dtype=float)
    return 0.7629 * (1.0 + 0.9324 * c * c) / (4.0 * np.pi)


def _interp(wl, nodes, values):
    return np.interp(np.asarray(wl, float), np.asarray(nodes, float), np.asarray(values, float))


def refractive_index_minus_1(params: dict, wavelengths_nm) -> np.ndarray:
    """n - 1 at the preset's reference density, linear in 1/lambda^2 through the table."""
    s_nodes = 1.0 / np.asarray(params["rayleigh_wavelengths_nm"], float) ** 2
    vals = np.asarray(params["refractive_index_minus_1"], float)
    s = 1.0 / np.asarray(wavelengths_nm, float) ** 2
    order = np.argsort(s_nodes)
    slope, icpt = np.polyfit(s_nodes[order], vals[order], 1) if vals.size > 1 else (0.0, vals[0])
    inside = (s >= s_nodes.min()) & (s <= s_nodes.max())
    return np.where(inside, np.interp(s, s_nodes[order], vals[order]), slope * s + icpt)


def rayleigh_ground_coefficient(params: dict, wavelengths_nm) -> np.ndarray:
    """Rayleigh scattering coefficient at the ground, m^-1 (see the module doc).

    With n given at a reference density N_ref and the ground at N (Mars), n - 1 scales
    with N, so beta = 8 pi^3 (2 (n-1))^2 (N / N_ref)^2 / (3 N lambda^4) x King factor."""
    lam = np.asarray(wavelengths_nm, float) * 1e-9
    nm1 = refractive_index_minus_1(params, wavelengths_nm)
    n_ref = float(params.get("refractive_index_number_density_m3", params.get("number_density_m3")))
    if "surface_pressure_pa" in params:
        n_ground = params["surface_pressure_pa"] / (1.380649e-23 * params["surface_temperature_k"])
    else:
        n_ground = float(params["number_density_m3"])
    n2m1 = (1.0 + nm1) ** 2 - 1.0  # at the reference density
    n2m1 = n2m1 * (n_ground / n_ref)
    d = float(params["depolarization"])
    return 8.0 * np.pi**3 * n2m1**2 / (3.0 * n_ground * lam**4) * (6.0 + 3.0 * d) / (6.0 - 7.0 * d)


def mie_spectral_shape(params: dict, wavelengths_nm) -> np.ndarray:
    """van de Hulst's ``0.434 pi (2 pi / lambda)^(v - 2) K(lambda)`` (lambda in m), to be
    scaled by a concentration; only its ratio across wavelengths is used."""
    lam = np.asarray(wavelengths_nm, float) * 1e-9
    k = _interp(wavelengths_nm, params["mie_wavelengths_nm"], params["kappa"])
    return 0.434 * np.pi * (2.0 * np.pi / lam) ** (float(params["junge_exponent"]) - 2.0) * k


def ozone_layer_density(params: dict, altitudes_m, column_du: float) -> np.ndarray:
    """Triangular ozone layer (number density, m^-3) holding ``column_du`` Dobson units."""
    from skymodel.optics.ozone import DOBSON_UNIT_M2

    h = np.asarray(altitudes_m, float)
    b, p, t = (params[k] * 1e3 for k in ("ozone_bottom_km", "ozone_peak_km", "ozone_top_km"))
    shape = np.where(h < p, (h - b) / (p - b), (t - h) / (t - p))
    shape = np.clip(shape, 0.0, 1.0)
    area = 0.5 * (t - b)  # integral of the triangle, metres
    return shape * column_du * DOBSON_UNIT_M2 / area


def openspace_profile(planet: str = "earth", wavelengths_nm=None, aod550: float | None = None,
                      ozone_du: float | None = None, ground_albedo: float | None = None,
                      n_altitudes: int = 301) -> OpticalProfile:
    """An :class:`OpticalProfile` of the OpenSpace parameterisation of ``planet``.

    ``aod550``: Mie (haze / dust) optical depth at 550 nm (default: Earth from the
    preset's turbidity, Mars its dust optical depth); ``ozone_du``: ozone column
    (default the preset's); ``ground_albedo``: Lambertian albedo (default the preset's)."""
    from skymodel import sun
    from skymodel.geometry import altitude_grid
    from skymodel.optics.ozone import ozone_cross_section
    from skymodel.wavelengths import as_wavelengths

    key = check_choice("planet", str(planet).lower(), PLANETS)
    prm = planet_parameters(key)
    wl = as_wavelengths(wavelengths_nm)
    radius = prm["planet_radius_km"] * 1e3
    top = prm["atmosphere_radius_km"] * 1e3 - radius
    h = altitude_grid(int(n_altitudes), top)
    h_r, h_m = prm["rayleigh_scale_height_km"] * 1e3, prm["mie_scale_height_km"] * 1e3
    # the column integrals of exp(-h/H) up to the top
    col_r = h_r * -np.expm1(-top / h_r)
    col_m = h_m * -np.expm1(-top / h_m)
    ray0 = rayleigh_ground_coefficient(prm, wl)
    ray = ray0[None, :] * np.exp(-h / h_r)[:, None]
    tau_r550 = float(rayleigh_ground_coefficient(prm, [550.0])[0] * col_r)
    if aod550 is None:
        aod = prm["dust_optical_depth_550"] if "dust_optical_depth_550" in prm else (prm["turbidity"] - 1.0) * tau_r550
    else:
        aod = check_range("aod550", aod550, 0.0, 10.0)
    shape = mie_spectral_shape(prm, wl) / float(mie_spectral_shape(prm, [550.0])[0])
    ext0 = aod * shape / col_m  # Mie extinction at the ground, m^-1
    ssa = check_range("mie_single_scattering_albedo", prm["mie_single_scattering_albedo"], 0.0, 1.0)
    mie_ext = ext0[None, :] * np.exp(-h / h_m)[:, None]
    du = float(prm["ozone_du"] if ozone_du is None else check_range("ozone_du", ozone_du, 0.0, 1000.0, "DU"))
    o3 = ozone_layer_density(prm, h, du)[:, None] * ozone_cross_section(wl)[None, :]
    o2 = (_interp(wl, prm["oxygen_wavelengths_nm"], prm["oxygen_absorption_per_km"]) * 1e-3)[None, :] \
        * np.exp(-h / (prm["oxygen_scale_height_km"] * 1e3))[:, None]
    mu = np.cos(np.radians(PHASE_ANGLES_DEG))
    g1 = _interp(wl, prm["mie_wavelengths_nm"], prm["g1"])
    phase = double_hg(mu[:, None], g1[None, :], prm["g2"], prm["alpha"])
    # renormalise on the table's own quadrature (the marcher integrates the table this way)
    from skymodel.numerics import trapezoid

    phase = phase / (-2.0 * np.pi * trapezoid(phase, mu, axis=0))[None, :]
    albedo = float(prm["ground_albedo"] if ground_albedo is None else check_range("ground_albedo", ground_albedo, 0.0, 1.0))
    e_sun = sun.solar_irradiance(wl) / float(prm["sun_distance_au"]) ** 2
    meta = {"model": f"openspace_{key}", "planet": key, "aod550": float(aod), "ozone_du": du, "albedo": albedo,
            "rayleigh_optical_depth_550": tau_r550, "planet_radius_m": radius, "top_altitude_m": top,
            "source": _table()["source"]}
    prof = OpticalProfile(
        wavelengths_nm=wl, rayleigh_depolarization=np.full(wl.shape, float(prm["depolarization"])),
        aerosol_phase_angles_deg=PHASE_ANGLES_DEG.copy(), aerosol_phase=phase[None, :, :],
        ground_albedo=np.full(wl.shape, albedo), solar_irradiance=e_sun, planet_radius_m=radius,
        top_altitude_m=top, metadata=meta, altitudes_m=h, rayleigh_scattering=ray,
        ozone_absorption=o3 + o2, aerosol_scattering_by_regime=(ssa * mie_ext)[None, :, :],
        aerosol_absorption=(1.0 - ssa) * mie_ext)
    for name in ("rayleigh_scattering", "ozone_absorption", "aerosol_scattering_by_regime", "aerosol_phase"):
        check_finite(name, getattr(prof, name))
    return prof


# ------------------------------------------------------------------ the registered models
_CACHE: dict = {}


def render(planet: str, scene: SkyScene, directions, observer_altitude_m: float = 0.0, use_scene: bool = True):
    """Marcher radiance of the OpenSpace ``planet`` for ``directions`` (N, 3); with
    ``use_scene`` (Earth only) the aerosol optical depth and ozone column come from
    ``scene.atmosphere`` so that only the parameterisation differs from ``ours``."""
    import hashlib

    from skymodel.render.marcher import SkyMarcher
    from skymodel.render.sky import quality_settings

    d = np.asarray(directions, float)
    kw = {}
    if use_scene and planet == "earth":
        meta = scene.atmosphere.optical_profile([550.0]).metadata
        kw = {"aod550": float(meta["aod550"]), "ozone_du": float(meta["ozone_du"])}
    key = (planet, tuple(sorted(kw.items())), scene.sun_elevation_deg, scene.sun_azimuth_deg,
           tuple(scene.wavelengths_nm.tolist()), str(scene.quality), float(observer_altitude_m),
           hashlib.sha1(np.ascontiguousarray(d).tobytes()).hexdigest())
    if key not in _CACHE:
        prof = openspace_profile(planet, scene.wavelengths_nm, **kw)
        res = SkyMarcher(prof, scene.sun_elevation_deg, scene.sun_azimuth_deg, observer_altitude_m,
                         quality_settings(scene.quality)).radiance(d)
        _CACHE.clear()
        _CACHE[key] = (prof, res)
    return _CACHE[key]


def _make(planet):
    def fn(scene: SkyScene, d) -> ModelRadiance:
        prof, res = render(planet, scene, d)
        info = {k: prof.metadata[k] for k in ("planet", "aod550", "ozone_du", "albedo", "rayleigh_optical_depth_550")}
        info["sun_irradiance"] = np.asarray(res.sun_irradiance)
        return ModelRadiance("spectral", np.asarray(res.radiance), scene.wavelengths_nm, info)

    return fn


register(SkyModel("openspace_earth", "spectral", "OpenSpace parameterisation (Costa et al. 2021), Earth preset, "
                  "scene AOD and ozone, rendered by our marcher", _make("earth")))
register(SkyModel("openspace_mars", "spectral", "OpenSpace parameterisation (Costa et al. 2021), Mars preset "
                  "(dust optical depth 0.5, 1.52 AU), rendered by our marcher", _make("mars")))

