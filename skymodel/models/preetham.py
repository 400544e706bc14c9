"""Preetham, Shirley & Smits (1999), "A Practical Analytic Model for Daylight".

The sky
-------
Luminance Y and chromaticity x, y of the sky each follow the Perez et al. (1993) form

    F(theta, gamma) = (1 + A exp(B / cos theta)) (1 + C exp(D gamma) + E cos^2 gamma)
    Y(theta, gamma) = Y_z F(theta, gamma) / F(0, theta_s)          (same for x and y)

with theta the view zenith angle, gamma the angle to the sun, theta_s the solar zenith
angle and A..E linear in the turbidity T (paper, Appendix A.2). The zenith values are

    Y_z = (4.0453 T - 4.9710) tan(chi) - 0.2155 T + 2.4192   [kcd m^-2],
    chi = (4/9 - T/120) (pi - 2 theta_s),
    x_z = [T^2 T 1] M_x [theta_s^3 theta_s^2 theta_s 1]^T     (y_z with M_y).

Spectral radiance comes from the CIE daylight basis (S0, S1, S2 of CIE 15, from
colour-science): M1, M2 follow from x, y by the CIE formulas
``M1 = (-1.3515 - 1.7703 x + 5.9114 y) / (0.0241 + 0.2562 x - 0.7341 y)`` and
``M2 = (0.0300 - 31.4424 x + 30.0717 y) / (0.0241 + 0.2562 x - 0.7341 y)``, and
``S0 + M1 S1 + M2 S2`` is scaled so that its luminance is Y. **Units**: Preetham's Y is
in kcd m^-2; we multiply by 1000 and divide by K_m = 683.002 lm W^-1 times the CIE y-bar
integral of the spectrum, so the result is spectral radiance in W m^-2 sr^-1 nm^-1 with
exactly the model's luminance (``683 * integral L ybar dlambda = 1000 Y``).

The sun
-------
The direct beam is the extraterrestrial spectrum (ours: ``skymodel.sun.solar_irradiance``)
times the paper's transmittances along Kasten's relative optical mass
``m = 1 / (cos theta_s + 0.15 (93.885 - theta_s[deg])^-1.253)``: Rayleigh
``exp(-0.008735 lambda^-4.08 m)``, Angstrom aerosol ``exp(-beta lambda^-1.3 m)`` with
``beta = 0.04608 T - 0.04586``, ozone ``exp(-k_o l m)`` (l = 0.35 cm), mixed gases and
water vapour (w = 2 cm) with Iqbal's absorption coefficients (lambda in micrometres; the
tables are in ``skymodel/data/sources/models/preetham.toml``).

Aerial perspective
------------------
:func:`aerial_perspective`: ``L = L0 F_ex(s) + L_in(s)`` with the extinction factor of the
path and the in-scattered sunlight ``(beta_R(theta) + beta_M(theta)) / (beta_R + beta_M)
E_sun (1 - F_ex)`` (paper's aerial-perspective section). Our choices, marked in the TOML:
exponential density fall-off (8 km air, 1.2 km haze) integrated in closed form along the
path, the haze extinction taken from the sun model's Angstrom optical depth so that the
sky, the sun and the aerial perspective share one turbidity, and a Henyey-Greenstein
haze phase function.

Turbidity from our atmosphere
-----------------------------
:func:`turbidity_from_aod`: the turbidity whose Angstrom haze optical depth at 550 nm,
``beta 0.55^-1.3``, equals our aerosol optical depth at 550 nm, i.e.
``T = (AOD550 0.55^1.3 + 0.04586) / 0.04608``. (Our own definition,
``T = (tau_R + tau_A) / tau_R`` at 550 nm, gives nearly the same number since the
paper's Rayleigh depth at 550 nm is 0.0999: T=2 <-> AOD 0.100 here, 0.097-0.100 there.)
The fitted coefficients only describe turbid-to-clear skies: below T = 2 the chromaticity
polynomials drift off the daylight locus (the zenith turns green-cyan at low sun), so the
model clamps T to [2, 10] and says so in ``info``.
"""

from __future__ import annotations

import functools

import numpy as np

from skymodel.colorimetry import K_M, cmf_weights
from skymodel.data import load_toml
from skymodel.errors import SkymodelInputError, check_range
from skymodel.models import ModelRadiance, SkyModel, SkyScene, register

TABLE = "sources/models/preetham.toml"
#: Turbidity range the model is used in (see the module doc).
T_MIN, T_MAX = 2.0, 10.0


@functools.lru_cache(maxsize=1)
def _table() -> dict:
    return load_toml(TABLE)


def perez(theta, gamma, A, B, C, D, E):
    """Perez et al. (1993) distribution F(theta, gamma) (angles in radians). ``cos theta``
    is floored at 1e-3 so the horizon stays finite (B < 0 makes the factor 1 there)."""
    c = np.maximum(np.cos(np.asarray(theta, dtype=float)), 1e-3)
    g = np.asarray(gamma, dtype=float)
    return (1.0 + A * np.exp(B / c)) * (1.0 + C * np.exp(D * g) + E * np.cos(g) ** 2)


def perez_coefficients(turbidity) -> dict[str, np.ndarray]:
    """A..E (as an array of 5) for ``"Y"``, ``"x"`` and ``"y"`` at turbidity T."""
    T = float(turbidity)
    out = {}
    for key in ("Y", "x", "y"):
        tab = _table()["perez"][key]
        out[key] = np.array([tab[c][0] * T + tab[c][1] for c in "ABCDE"])
    return out


def zenith_luminance_kcd(turbidity, sun_zenith_rad):
    """Preetham's zenith luminance Y_z in kcd m^-2."""
    z = _table()["zenith_luminance"]
    T = float(turbidity)
    chi = (4.0 / 9.0 - T / 120.0) * (np.pi - 2.0 * np.asarray(sun_zenith_rad, dtype=float))
    return (z["a"] * T + z["b"]) * np.tan(chi) + z["c"] * T + z["d"]


def zenith_chromaticity(turbidity, sun_zenith_rad):
    """(x_z, y_z) of the zenith."""
    z = _table()["zenith_chromaticity"]
    T = float(turbidity)
    ts = float(sun_zenith_rad)
    tv = np.array([T * T, T, 1.0])
    sv = np.array([ts**3, ts**2, ts, 1.0])
    return float(tv @ np.asarray(z["M_x"]) @ sv), float(tv @ np.asarray(z["M_y"]) @ sv)


def sky_xyY(turbidity, sun_zenith_rad, theta, gamma):
    """Chromaticity x, y and luminance Y (kcd m^-2) of the sky at (theta, gamma)."""
    co = perez_coefficients(turbidity)
    ts = float(sun_zenith_rad)
    xz, yz = zenith_chromaticity(turbidity, ts)
    Yz = zenith_luminance_kcd(turbidity, ts)
    out = []
    for key, zval in (("x", xz), ("y", yz), ("Y", Yz)):
        out.append(zval * perez(theta, gamma, *co[key]) / perez(0.0, ts, *co[key]))
    return tuple(out)


@functools.lru_cache(maxsize=8)
def _daylight_basis(wavelengths: tuple) -> np.ndarray:
    """S0, S1, S2 (3, n_wl) of the CIE daylight series, linearly interpolated."""
    import colour

    basis = colour.colorimetry.SDS_BASIS_FUNCTIONS_CIE_ILLUMINANT_D_SERIES
    wl = np.asarray(wavelengths, dtype=float)
    return np.stack([np.interp(wl, np.asarray(basis[k].wavelengths, float), np.asarray(basis[k].values, float))
                     for k in ("S0", "S1", "S2")])


def daylight_m1_m2(x, y):
    """CIE daylight coefficients M1, M2 from chromaticity (CIE 15)."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    den = 0.0241 + 0.2562 * x - 0.7341 * y
    return (-1.3515 - 1.7703 * x + 5.9114 * y) / den, (0.0300 - 31.4424 * x + 30.0717 * y) / den


def spectral_radiance_from_xyY(x, y, Y_kcd, wavelengths_nm) -> np.ndarray:
    """Spectral radiance (..., n_wl) W m^-2 sr^-1 nm^-1 with the daylight-basis shape of
    chromaticity (x, y) and luminance ``Y_kcd`` kcd m^-2."""
    wl = np.asarray(wavelengths_nm, dtype=float)
    S = _daylight_basis(tuple(wl.tolist()))
    m1, m2 = daylight_m1_m2(x, y)
    spec = S[0] + np.asarray(m1)[..., None] * S[1] + np.asarray(m2)[..., None] * S[2]
    ybar = cmf_weights(wl)[:, 1]
    lum = K_M * (spec @ ybar)  # cd m^-2 per unit of the spectrum
    scale = np.where(lum > 0, 1000.0 * np.asarray(Y_kcd, float) / np.where(lum > 0, lum, 1.0), 0.0)
    return spec * scale[..., None]


def turbidity_from_aod(aod550) -> float:
    """Preetham turbidity whose Angstrom haze depth at 550 nm equals ``aod550`` (unclamped)."""
    s = _table()["sun"]
    a = check_range("aod550", aod550, 0.0, 10.0)
    beta = a * 0.55 ** s["alpha"]
    return (beta - s["beta_intercept"]) / s["beta_slope"]


def angstrom_beta(turbidity) -> float:
    s = _table()["sun"]
    return s["beta_slope"] * float(turbidity) + s["beta_intercept"]


def relative_optical_mass(sun_zenith_rad):
    """Kasten's relative optical air mass (finite at the horizon: about 36.5)."""
    ts = np.asarray(sun_zenith_rad, dtype=float)
    deg = np.degrees(ts)
    return 1.0 / (np.cos(ts) + 0.15 * np.power(np.maximum(93.885 - deg, 1e-6), -1.253))


def _interp_table(name, wl):
    t = _table()["sun"][name]
    return np.interp(wl, np.asarray(t["nm"], float), np.asarray(t["k"], float), left=0.0, right=0.0)


def sun_transmittance(turbidity, sun_zenith_rad, wavelengths_nm, components: bool = False):
    """Spectral transmittance of the direct beam (paper's sun model). With ``components``
    a dict of the five factors (rayleigh, aerosol, ozone, gas, water) is returned too."""
    s = _table()["sun"]
    wl = np.asarray(wavelengths_nm, dtype=float)
    lam = wl / 1000.0  # micrometres
    m = float(relative_optical_mass(sun_zenith_rad))
    beta = angstrom_beta(turbidity)
    k_o, k_g, k_wa = _interp_table("k_o", wl), _interp_table("k_g", wl), _interp_table("k_wa", wl)
    parts = {
        "rayleigh": np.exp(-s["rayleigh_coefficient"] * lam ** -s["rayleigh_exponent"] * m),
        "aerosol": np.exp(-beta * lam ** -s["alpha"] * m),
        "ozone": np.exp(-k_o * s["ozone_cm"] * m),
        "gas": np.exp(-s["gas_a"] * k_g * m / (1.0 + s["gas_b"] * k_g * m) ** s["exponent"]),
        "water": np.exp(-s["water_a"] * k_wa * s["water_cm"] * m
                        / (1.0 + s["water_b"] * k_wa * s["water_cm"] * m) ** s["exponent"]),
    }
    total = np.prod(np.stack(list(parts.values())), axis=0)
    return (total, parts) if components else total


def sun_irradiance(turbidity, sun_zenith_rad, wavelengths_nm, extraterrestrial=None) -> np.ndarray:
    """Direct solar irradiance at the ground, W m^-2 nm^-1 (normal to the beam); the
    extraterrestrial spectrum defaults to ours (``skymodel.sun.solar_irradiance``)."""
    wl = np.asarray(wavelengths_nm, dtype=float)
    if extraterrestrial is None:
        from skymodel import sun

        extraterrestrial = sun.solar_irradiance(wl)
    if float(sun_zenith_rad) > np.pi / 2:
        return np.zeros_like(wl)
    return np.asarray(extraterrestrial, float) * sun_transmittance(turbidity, sun_zenith_rad, wl)


# ------------------------------------------------------------------ aerial perspective
def rayleigh_total_coefficient(wavelengths_nm) -> np.ndarray:
    """beta_R(lambda) at sea level, m^-1 (paper's formula with n, N, p_n of the TOML)."""
    a = _table()["aerial"]
    lam = np.asarray(wavelengths_nm, dtype=float) * 1e-9
    n2 = a["refractive_index"] ** 2 - 1.0
    pn = a["depolarization"]
    return 8.0 * np.pi**3 * n2**2 / (3.0 * a["molecules_per_m3"] * lam**4) * (6.0 + 3.0 * pn) / (6.0 - 7.0 * pn)


def _path_density_integral(scale_height, h0, cos_view, s):
    """integral_0^s exp(-(h0 + t cos_view) / H) dt (flat-earth closed form)."""
    base = np.exp(-np.asarray(h0, float) / scale_height)
    k = np.asarray(cos_view, float) * np.asarray(s, float) / scale_height
    small = np.abs(k) < 1e-6
    ks = np.where(small, 1.0, k)
    return base * np.where(small, np.asarray(s, float) * (1.0 - 0.5 * k),
                           np.asarray(s, float) * (1.0 - np.exp(-ks)) / ks)


def aerial_perspective(distance_m, view_zenith_deg, scattering_angle_deg, turbidity, wavelengths_nm,
                       sun_zenith_deg, observer_altitude_m=0.0, object_radiance=None):
    """Preetham's aerial perspective for an object at ``distance_m`` seen along a ray of
    zenith angle ``view_zenith_deg`` whose angle to the sun is ``scattering_angle_deg``.

    Returns ``(F_ex, L_in)``, each ``(..., n_wl)``: the extinction factor and the
    in-scattered radiance (W m^-2 sr^-1 nm^-1); the object appears as
    ``object_radiance * F_ex + L_in`` (returned third when ``object_radiance`` is given).
    """
    a = _table()["aerial"]
    s = np.asarray(distance_m, dtype=float)
    if not np.all(np.isfinite(s) & (s >= 0.0) & (s <= 1e6)):
        raise SkymodelInputError("distance_m", distance_m, "distances in [0, 1e6] metres")
    wl = np.asarray(wavelengths_nm, dtype=float)
    T = check_range("turbidity", turbidity, 1.0, 64.0)
    cos_v = np.cos(np.radians(np.asarray(view_zenith_deg, float)))
    cos_sc = np.cos(np.radians(np.asarray(scattering_angle_deg, float)))
    h0 = check_range("observer_altitude_m", observer_altitude_m, 0.0, 20000.0, "metres")
    HR, HM = a["rayleigh_scale_height_m"], a["haze_scale_height_m"]
    beta_r = rayleigh_total_coefficient(wl)  # sea level, m^-1
    lam = wl / 1000.0
    tau_haze = max(angstrom_beta(T), 0.0) * lam ** -_table()["sun"]["alpha"]  # column optical depth
    beta_m = tau_haze / HM  # sea-level haze extinction, m^-1
    uR = _path_density_integral(HR, h0, cos_v, s)[..., None]
    uM = _path_density_integral(HM, h0, cos_v, s)[..., None]
    f_ex = np.exp(-(beta_r * uR + beta_m * uM))
    g = a["haze_asymmetry"]
    c = np.asarray(cos_sc, float)[..., None]
    p_r = 3.0 / (16.0 * np.pi) * (1.0 + c**2)
    p_m = (1.0 - g * g) / (4.0 * np.pi * (1.0 + g * g - 2.0 * g * c) ** 1.5)
    # ratio of angular to total scattering, weighted by the densities met along the path
    wR, wM = beta_r * uR, beta_m * uM
    ratio = (wR * p_r + wM * p_m) / np.maximum(wR + wM, 1e-300)
    e_sun = sun_irradiance(T, np.radians(sun_zenith_deg), wl)
    l_in = ratio * e_sun * (1.0 - f_ex)
    if object_radiance is None:
        return f_ex, l_in
    return f_ex, l_in, np.asarray(object_radiance, float) * f_ex + l_in


# ------------------------------------------------------------------ the registered model
def scene_turbidity(scene: SkyScene) -> tuple[float, float]:
    """(used T, unclamped T) for a scene: from the atmosphere's AOD at 550 nm."""
    aod = float(scene.atmosphere.optical_profile([550.0]).metadata["aod550"])
    t_raw = turbidity_from_aod(aod)
    return float(np.clip(t_raw, T_MIN, T_MAX)), t_raw


def _preetham(scene: SkyScene, d) -> ModelRadiance:
    if scene.sun_elevation_deg < 0.0:
        raise SkymodelInputError("sun_elevation", scene.sun_elevation_deg,
                                 "0..90 degrees for the Preetham model (defined for the sun above the horizon)")
    T, t_raw = scene_turbidity(scene)
    theta, gamma = scene.view_angles(d)
    ts = scene.sun_zenith_rad
    x, y, Y = sky_xyY(T, ts, theta, gamma)
    above = theta <= np.pi / 2
    Y = np.where(above, Y, 0.0)
    L = spectral_radiance_from_xyY(x, y, Y, scene.wavelengths_nm)
    info = {"turbidity": T, "turbidity_unclamped": t_raw, "clamped": bool(t_raw != T),
            "zenith_luminance_cd_m2": 1000.0 * float(zenith_luminance_kcd(T, ts)),
            "zenith_xy": zenith_chromaticity(T, ts),
            "sun_irradiance": sun_irradiance(T, ts, scene.wavelengths_nm)}
    return ModelRadiance("spectral", L, scene.wavelengths_nm, info)


register(SkyModel("preetham", "spectral", "Preetham, Shirley & Smits 1999 analytic daylight (Perez fits, "
                  "turbidity from our AOD550, CIE daylight basis spectra)", _preetham))
