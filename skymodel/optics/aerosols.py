"""Aerosols: component mixtures, vertical profiles and their optical properties per height.

Two *aerosol models* (:data:`MODELS`; the ``aerosol_model`` parameter of :mod:`skymodel.scene`):

* ``"guimera2018"`` (the default): the paper's model (Guimera, Gutierrez & Jarabo 2018, Eqs. 10-12,
  Table 1), ``skymodel/data/presets/aerosols/paper.toml``: per type the Table 1 proportions w_c (by
  number), ONE size distribution shared by the components (a sum of three Jaenicke 1993 lognormals),
  the components' d'Almeida/OPAC refractive indices, and the full Eq. 12 profile
  (:func:`eq12_concentration`, no top). Its Mie lookup is ``generated/mie_lookup_paper.npz``
  (:func:`skymodel.optics.mie_lookup.build_paper`), one entry per (distribution, refractive index).
* ``"opac"``: the OPAC mixtures of ``types.toml`` described below (each component with its own
  size distribution, the profile normalised at the ground and cut at 12 km).

An aerosol *type* (``skymodel/data/presets/aerosols/types.toml``) is an external mixture of *components*
(``skymodel/data/presets/aerosols/components.toml``: a refractive index and a lognormal size distribution each),
given as number densities at a reference level, and a vertical profile (the paper's Eq. 12). Types
live in one of two *regimes*: 0 = troposphere (the type chosen by the user: urban, desert, ...),
1 = stratosphere (``"background"`` sulfate layer, ``"volcanic"``, or ``"none"``).

For a regime with mixture ``N_i`` and relative profile ``f(h)``, scaled by ``s``::

    scattering(h, l) = s f(h) sum_i N_i C_sca,i(l)          (m^-1)
    absorption(h, l) = s f(h) sum_i N_i (C_ext,i - C_sca,i)(l)
    phase(theta, l)  = sum_i N_i C_sca,i p_i(theta, l) / sum_i N_i C_sca,i    (sr^-1)

with the size-integrated cross sections ``C`` and phase functions ``p`` of each component read from
the Mie lookup table ``skymodel/data/generated/mie_lookup.npz`` (built by :mod:`skymodel.optics.mie_lookup`; no Mie
computation happens at run time). Off the lookup's 5 nm grid everything is linear in wavelength.

Amount of the tropospheric aerosol (``s``): by default 1, i.e. the number densities of the table
(its default AOD, :func:`default_aod550`); or given as the aerosol optical depth at 550 nm
(``aod550``), or as the turbidity ``T = (tau_R + tau_A) / tau_R`` at 550 nm, which needs the
Rayleigh optical depth at 550 nm. The stratospheric amount is its AOD at 550 nm
(``stratospheric_aod550``, default from the type). Column integrals use the trapezoid rule on the
altitude grid passed in (as :meth:`skymodel.optics.profile.OpticalProfile.vertical_optical_depth` does), so
an AOD that is asked for is what the returned coefficients integrate to.

The Angstrom exponent is reported for 440/675 nm (both inside the visible grid; AERONET's usual
440-870 nm pair is outside it): ``alpha = -ln(tau(440)/tau(675)) / ln(440/675)`` of the column AOD.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from skymodel.data import load_npz, load_toml
from skymodel.errors import SkymodelInputError, check_choice, check_range
from skymodel.numerics import trapezoid
from skymodel.scene import parameter
from skymodel.wavelengths import as_wavelengths

#: Path of the OPAC model's Mie lookup under ``skymodel/data/``.
LOOKUP = "generated/mie_lookup.npz"
#: The aerosol models: name -> (types file, Mie lookup). Their names are the registry's
#: ``aerosol_model`` choices (tests/test_aerosols_paper.py checks that they agree).
MODELS = {
    "guimera2018": ("presets/aerosols/paper.toml", "generated/mie_lookup_paper.npz"),
    "opac": ("presets/aerosols/types.toml", LOOKUP),
}
#: Stratospheric choices -> type names in types.toml.
STRATOSPHERIC = {"background": "stratospheric_background", "volcanic": "volcanic", "none": None}
#: Allowed amounts.
AOD_RANGE = (parameter("aod550").minimum, parameter("aod550").maximum)
TURBIDITY_RANGE = (parameter("turbidity").minimum, parameter("turbidity").maximum)
STRATOSPHERIC_AOD_RANGE = (parameter("stratospheric_aod550").minimum, parameter("stratospheric_aod550").maximum)
#: Wavelength pair of the reported Angstrom exponent, nm.
ANGSTROM_PAIR_NM = (440.0, 675.0)


# ------------------------------------------------------------------------------------- tables


def resolve_model(model=None) -> str:
    """Canonical aerosol-model name (default: the registry's ``aerosol_model``)."""
    from skymodel import scene

    return scene.check("aerosol_model", scene.default("aerosol_model") if model is None else model)


@functools.lru_cache(maxsize=4)
def _types_file(model: str = "opac") -> dict:
    return load_toml(MODELS[model][0])


@functools.lru_cache(maxsize=4)
def _all_types(model: str = "opac") -> dict[str, dict]:
    """Type entries of a model; the paper's are given the OPAC shape: ``mixture`` = lookup entry ->
    number density at the Eq. 12 reference C0 (cm^-3; relative for stratospheric types)."""
    t = _types_file(model)
    if model == "opac":
        return dict(t["types"])
    from skymodel.optics.mie_lookup import paper_entry_name

    out = {}
    for name, ty in t["types"].items():
        modes = t["distributions"][ty["distribution"]]["modes"]
        c0 = float(sum(float(md["n_cm3"]) for md in modes))
        total_w = float(sum(ty["table1"].values()))
        mix: dict[str, float] = {}
        for comp, w in ty["table1"].items():
            key = paper_entry_name(ty["distribution"], t["component_index"][comp]["index"])
            mix[key] = mix.get(key, 0.0) + c0 * float(w) / total_w
        out[name] = {**ty, "mixture": mix, "c0_cm3": c0,
                     "mixture_source": ty["table1_source"] + "; sizes: " + ty["distribution_source"]}
    return out


def aerosol_types(model=None) -> list[str]:
    """Canonical names of a model's tropospheric aerosol types (for the ``aerosol_type`` argument)."""
    return [n for n, t in _all_types(resolve_model(model)).items() if t["regime"] == "troposphere"]


def stratospheric_types() -> list[str]:
    """Choices of the ``stratospheric`` argument."""
    return list(STRATOSPHERIC)


def components() -> list[str]:
    """Names of the aerosol components of the OPAC model (``skymodel/data/presets/aerosols/components.toml``),
    each with its own size distribution; the rows of ``generated/mie_lookup.npz``."""
    return list(load_toml("presets/aerosols/components.toml")["components"])


def paper_components() -> list[str]:
    """The paper's ten-component names used in Table 1 (``paper.toml`` ``[component_index]``)."""
    return list(_types_file("guimera2018")["component_index"])


def aliases(model=None) -> dict[str, str]:
    """Accepted alternative type names -> canonical name."""
    return dict(_types_file(resolve_model(model)).get("aliases", {}))


def resolve_type(name, parameter: str = "aerosol_type", regime: str | None = "troposphere", model=None) -> str:
    """Canonical type name for ``name`` in ``model`` (case-insensitive, aliases accepted); raises
    :class:`SkymodelInputError` naming ``parameter`` and listing the known names otherwise."""
    model = resolve_model(model)
    types = _all_types(model)
    known = [n for n, t in types.items() if regime is None or t["regime"] == regime]
    key = str(name).strip().lower()
    al = aliases(model)
    key = al.get(key, key)
    if key not in known:
        extra = ["none"] if parameter == "aerosol_type" else []
        raise SkymodelInputError(parameter, name, f"one of ({model} aerosol model): "
                                 + ", ".join(sorted(known) + extra)
                                 + " (case-insensitive; aliases: " + ", ".join(sorted(al)) + ")")
    return key


def type_info(type_name: str, model=None) -> dict:
    """The entry of a (tropospheric or stratospheric) type of ``model``."""
    model = resolve_model(model)
    return dict(_all_types(model)[resolve_type(type_name, "type_name", regime=None, model=model)])


def type_composition(model=None) -> dict[str, dict]:
    """For every type of ``model``: its components with their fractions and sources, its size
    description and its profile, as ``skymodel presets --json`` shows them."""
    model = resolve_model(model)
    t = _types_file(model)
    out = {}
    for name, ty in t["types"].items():
        if model == "opac":
            mix = {k: float(v) for k, v in ty["mixture"].items()}
            total = sum(mix.values())
            comps = {k: {"number_fraction": v / total, "number_density_cm3": v,
                         "size": load_toml("presets/aerosols/components.toml")["components"][k]["source"]}
                     for k, v in mix.items()}
            out[name] = {"regime": ty["regime"], "description": ty["description"], "components": comps,
                         "source": ty["mixture_source"], "profile": dict(ty.get("profile", {}))}
        else:
            comps = {k: {"table1_fraction": float(v), "refractive_index": t["component_index"][k]["index"],
                         "refractive_index_source": t["component_index"][k]["source"]}
                     for k, v in ty["table1"].items()}
            out[name] = {"regime": ty["regime"], "description": ty["description"], "components": comps,
                         "source": ty["table1_source"], "w_c_reading": t["w_c_reading"],
                         "size_distribution": ty["distribution"],
                         "size_distribution_source": ty["distribution_source"],
                         "profile": dict(ty.get("profile", {}))}
            if "table1_note" in ty:
                out[name]["table1_note"] = ty["table1_note"]
    return out


def lognormal_number_distribution(r_um, n_total, r_mod_um, sigma):
    """Lognormal number size distribution ``dN/dln r`` (same units as ``n_total``):

    ``n_total / (sqrt(2 pi) ln sigma) * exp(-(ln r - ln r_mod)^2 / (2 ln^2 sigma))``,
    ``r_mod_um`` the number-median radius (um), ``sigma`` > 1 the geometric standard deviation.
    """
    r = np.asarray(r_um, dtype=float)
    if np.any(~np.isfinite(r)) or np.any(r <= 0):
        raise SkymodelInputError("r_um", r_um, "radii > 0 in micrometres")
    if not (np.isfinite(sigma) and sigma > 1.0):
        raise SkymodelInputError("sigma", sigma, "a geometric standard deviation > 1")
    if not (np.isfinite(r_mod_um) and r_mod_um > 0.0):
        raise SkymodelInputError("r_mod_um", r_mod_um, "a mode radius > 0 in micrometres")
    ls = math.log(sigma)
    return n_total / (math.sqrt(2.0 * math.pi) * ls) * np.exp(-0.5 * ((np.log(r) - math.log(r_mod_um)) / ls) ** 2)


# --------------------------------------------------------------------------------- profiles


def _as_altitudes(altitudes_m) -> np.ndarray:
    try:
        h = np.asarray(altitudes_m, dtype=float)
    except (TypeError, ValueError):
        raise SkymodelInputError("altitudes_m", altitudes_m, "altitudes in metres (array-like)") from None
    if h.ndim != 1 or h.size < 2 or not np.all(np.isfinite(h)) or np.any(np.diff(h) <= 0) or h[0] < 0:
        raise SkymodelInputError("altitudes_m", altitudes_m,
                                 "at least 2 finite, strictly increasing altitudes >= 0 in metres")
    return h


def eq12_concentration(z_m, c0, cb, hp_m):
    """The paper's Eq. 12 (Guimera et al. 2018, after Jaenicke 1993), concentration at heights
    ``z_m`` above the ground [m], in the unit of ``c0`` and ``cb``:

    ``C(z) = C0 (exp(-z / Hp) + (Cb / C0)^v)^v``, ``v = sign(Hp)``.

    ``hp_m`` [m] may be negative (v = -1) or ``inf`` (no height dependence: C0 + Cb). At z = 0,
    C = C0 + Cb for v = +1 and C0 Cb / (C0 + Cb) for v = -1.
    """
    z = np.asarray(z_m, dtype=float)
    c0 = float(c0)
    cb = float(cb)
    hp = float(hp_m)
    if not (c0 > 0.0 and cb >= 0.0 and hp != 0.0 and not math.isnan(hp)):
        raise SkymodelInputError("eq12", (c0, cb, hp), "C0 > 0, Cb >= 0 and a non-zero Hp")
    v = 1.0 if hp > 0 else -1.0
    if v < 0 and cb == 0.0:
        return np.zeros_like(z)
    with np.errstate(over="ignore"):
        e = np.exp(-z / hp)
    return c0 * (e + (cb / c0) ** v) ** v


def _profile_params(type_name: str, model: str = "opac") -> dict:
    t = _all_types(model)[type_name]
    p = dict(t.get("profile", {}))
    if t["regime"] == "stratosphere":
        return {"kind": "layer", "peak_m": float(p["peak_km"]) * 1e3, "width_m": float(p["width_km"]) * 1e3}
    if model != "opac":
        return {"kind": "eq12", "c0": t["c0_cm3"], "cb": float(p["background_cm3"]),
                "hp_m": float(p["scale_height_km"]) * 1e3, "top_m": float(p.get("top_km", math.inf)) * 1e3}
    d = dict(_types_file(model).get("defaults", {}))
    total = float(sum(t["mixture"].values()))
    return {
        "kind": "exponential",
        "scale_height_m": float(p["scale_height_km"]) * 1e3,
        "top_m": float(p.get("top_km", d.get("top_km", 12.0))) * 1e3,
        "b": float(p.get("background_cm3", d.get("background_cm3", 0.0))) / total,
    }


def vertical_profile(type_name, altitudes_m, model=None) -> np.ndarray:
    """Relative number density of the type at ``altitudes_m`` (metres above the ground).

    ``"guimera2018"``: the paper's Eq. 12 in full (:func:`eq12_concentration`) divided by the type's
    C0 (the sum of its Jaenicke modes, the number the mixture is given at), no top, except for
    the height-independent background type (uniform up to its ``top_km``, the tropopause).

    ``"opac"``: Eq. 12 with v = 1, normalised to 1 at the ground and limited to the troposphere:
    ``f = (exp(-h/Hp) + b) / (1 + b)`` for ``h <= top``, 0 above, with ``b = N_B / N0`` (types.toml
    ``[defaults]``); ``Hp = inf`` is a uniform layer.

    Stratospheric types (both models): ``f = exp(-(h - peak)^2 / (2 width^2))``, 1 at the peak.
    """
    model = resolve_model(model)
    name = resolve_type(type_name, "type_name", regime=None, model=model)
    h = np.asarray(altitudes_m, dtype=float)
    if not np.all(np.isfinite(h)):
        raise SkymodelInputError("altitudes_m", altitudes_m, "finite altitudes in metres")
    p = _profile_params(name, model)
    if p["kind"] == "layer":
        return np.exp(-0.5 * ((h - p["peak_m"]) / p["width_m"]) ** 2)
    if p["kind"] == "eq12":
        f = eq12_concentration(np.maximum(h, 0.0), p["c0"], p["cb"], p["hp_m"]) / p["c0"]
        return f if math.isinf(p["top_m"]) else np.where(h <= p["top_m"], f, 0.0)
    with np.errstate(over="ignore"):
        e = np.exp(-np.maximum(h, 0.0) / p["scale_height_m"])
    f = (e + p["b"]) / (1.0 + p["b"])
    return np.where(h <= p["top_m"], f, 0.0)


# ------------------------------------------------------------------------------- the lookup


@functools.lru_cache(maxsize=2)
def _lookup(model: str = "opac") -> dict:
    path = MODELS[model][1]
    z = load_npz(path)
    names = [str(n) for n in z["components"]]
    needed = components() if model == "opac" else sorted({c for t in _all_types(model).values() for c in t["mixture"]})
    missing = [c for c in needed if c not in names]
    if missing:
        cmd = "build" if model == "opac" else "build-paper"
        raise RuntimeError(f"{path} lacks entries {missing}: run `python -m skymodel.optics.mie_lookup {cmd}`")
    return {**z, "index": {n: i for i, n in enumerate(names)}}


@functools.lru_cache(maxsize=16)
def _optics_at(wavelengths: tuple, model: str = "opac") -> dict:
    """Lookup arrays linearly interpolated to ``wavelengths``: ext, sca, g (n_comp, n_wl) and
    phase (n_comp, n_angle, n_wl)."""
    lk = _lookup(model)
    grid = lk["wavelengths_nm"]
    wl = np.asarray(wavelengths, dtype=float)
    if np.any(wl < grid[0] - 1e-9) or np.any(wl > grid[-1] + 1e-9):
        raise SkymodelInputError("wavelengths", wl.tolist(), f"wavelengths in [{grid[0]:g}, {grid[-1]:g}] nm")
    i = np.clip(np.searchsorted(grid, wl, side="right") - 1, 0, grid.size - 2)
    t = (wl - grid[i]) / (grid[i + 1] - grid[i])
    exact = np.isclose(t, 0.0, atol=1e-12)

    def lerp(a):  # interpolate along the last axis
        out = a[..., i] * (1.0 - t) + a[..., i + 1] * t
        out[..., exact] = a[..., i[exact]]
        return out

    sca = lerp(lk["sca"])
    g_sca = lerp(lk["g"] * lk["sca"])  # interpolate the scattering-weighted g
    out = {"ext": lerp(lk["ext"]), "sca": sca, "g": g_sca / sca, "phase": lerp(lk["phase"])}
    for a in out.values():
        a.setflags(write=False)
    return out


@functools.lru_cache(maxsize=64)
def _mixture(type_name: str, wavelengths: tuple, model: str = "opac") -> dict:
    """Per unit profile (``f = 1``): extinction, scattering coefficients (n_wl,) in m^-1, the
    scattering-weighted g (n_wl,) and phase (n_angle, n_wl) of a type's mixture."""
    t = _all_types(model)[type_name]
    opt = _optics_at(wavelengths, model)
    idx = _lookup(model)["index"]
    rows = [idx[c] for c in t["mixture"]]
    n = np.array([float(v) for v in t["mixture"].values()]) * 1e6  # cm^-3 -> m^-3
    ext = n @ opt["ext"][rows]
    w_sca = n[:, None] * opt["sca"][rows]  # (n_c, n_wl)
    sca = w_sca.sum(axis=0)
    g = (w_sca * opt["g"][rows]).sum(axis=0) / sca
    phase = np.einsum("cw,caw->aw", w_sca, opt["phase"][rows]) / sca
    out = {"ext": ext, "sca": sca, "g": g, "phase": phase}
    for a in out.values():
        a.setflags(write=False)
    return out


def default_aod550(type_name, altitudes_m=None, model=None) -> float:
    """AOD at 550 nm of a tropospheric type at its table number densities (dry particles), the
    column integral of its profile on ``altitudes_m`` (default: the model atmosphere's grid,
    0-100 km, 401 points, for the paper's model; a fine 0-12 km grid for OPAC's)."""
    model = resolve_model(model)
    name = resolve_type(type_name, model=model)
    if altitudes_m is None:
        top = _profile_params(name, model)["top_m"]
        if math.isfinite(top):
            h = np.linspace(0.0, top, 24001)
        else:
            from skymodel.geometry import altitude_grid

            h = altitude_grid()
    else:
        h = _as_altitudes(altitudes_m)
    return float(_mixture(name, (550.0,), model)["ext"][0] * trapezoid(vertical_profile(name, h, model), h))


# ----------------------------------------------------------------------------------- output


@dataclass(frozen=True)
class AerosolOptics:
    """Aerosol optical properties on an altitude and wavelength grid (regime 0 = troposphere,
    1 = stratosphere).

    Attributes
    ----------
    wavelengths_nm (n_wl,), altitudes_m (n_alt,), angles_deg (n_angle,): the grids.
    scattering_by_regime : (2, n_alt, n_wl) scattering coefficient, m^-1.
    absorption : (n_alt, n_wl) absorption coefficient of both regimes, m^-1.
    phase : (2, n_angle, n_wl) each regime's mixture phase function, sr^-1, normalised over 4 pi
        (piecewise linear in angle); isotropic for an empty regime.
    aod550 : tropospheric aerosol optical depth at 550 nm (the amount that ``aod550`` or
        ``turbidity`` sets).
    stratospheric_aod550 : the stratospheric regime's AOD at 550 nm.
    optical_depth : (n_wl,) column AOD of both regimes; ``optical_depth_by_regime`` (2, n_wl).
    single_scattering_albedo, asymmetry : (n_wl,) of the whole column (scattering-weighted g);
        1 and 0 where there is no aerosol.
    angstrom_exponent : of the column AOD between 440 and 675 nm (0 without aerosol).
    """

    wavelengths_nm: np.ndarray
    altitudes_m: np.ndarray
    angles_deg: np.ndarray
    scattering_by_regime: np.ndarray
    absorption: np.ndarray
    phase: np.ndarray
    aod550: float
    stratospheric_aod550: float
    optical_depth: np.ndarray
    optical_depth_by_regime: np.ndarray
    single_scattering_albedo: np.ndarray
    asymmetry: np.ndarray
    angstrom_exponent: float
    aerosol_type: str
    stratospheric: str
    aerosol_model: str = "opac"

    @property
    def scattering(self) -> np.ndarray:
        return self.scattering_by_regime.sum(axis=0)

    @property
    def extinction(self) -> np.ndarray:
        return self.scattering + self.absorption


def _rayleigh_tau550() -> float:
    from skymodel.optics import rayleigh  # imported lazily: the physics modules import each other

    fn = getattr(rayleigh, "rayleigh_optical_depth", None) or rayleigh.optical_depth
    return float(np.atleast_1d(fn([550.0]))[0])


def aerosol_optics(aerosol_type, altitudes_m, wavelengths_nm=None, aod550=None, turbidity=None,
                   stratospheric="background", stratospheric_aod550=None,
                   rayleigh_optical_depth_550=None, model=None) -> AerosolOptics:
    """Aerosol scattering, absorption and phase functions per height and wavelength.

    Parameters
    ----------
    aerosol_type : tropospheric type (:func:`aerosol_types`, case-insensitive, aliases accepted) or
        ``"none"`` (no tropospheric aerosol; the stratospheric regime is still set by ``stratospheric``).
    altitudes_m : strictly increasing altitudes above the ground, metres (>= 0).
    wavelengths_nm : 380-780 nm (default grid if None).
    aod550 : tropospheric AOD at 550 nm, in [0, 10]; scales the type's number densities.
    turbidity : ``(tau_R + tau_A) / tau_R`` at 550 nm, in [1, 64]; exclusive with ``aod550``.
    stratospheric : ``"background"`` (75 % H2SO4 Junge layer), ``"volcanic"`` or ``"none"``.
    stratospheric_aod550 : its AOD at 550 nm, in [0, 2] (default: the type's, 0.005 / 0.1).
    rayleigh_optical_depth_550 : Rayleigh optical depth at 550 nm for ``turbidity`` (default:
        :mod:`skymodel.optics.rayleigh` for the standard atmosphere).
    model : aerosol model, ``"guimera2018"`` (the paper's, default: the registry's) or ``"opac"``.
    """
    model = resolve_model(model)
    h = _as_altitudes(altitudes_m)
    wl = as_wavelengths(wavelengths_nm)
    trop_none = str(aerosol_type).strip().lower() == "none"
    trop = None if trop_none else resolve_type(aerosol_type, "aerosol_type", model=model)
    strat_key = check_choice("stratospheric", str(stratospheric).strip().lower(), list(STRATOSPHERIC))
    strat = STRATOSPHERIC[strat_key]
    if aod550 is not None and turbidity is not None:
        raise SkymodelInputError("aod550", aod550, "either aod550 or turbidity, not both")
    if aod550 is not None:
        aod550 = check_range("aod550", aod550, *AOD_RANGE)
    if turbidity is not None:
        turbidity = check_range("turbidity", turbidity, *TURBIDITY_RANGE)
        tau_r = _rayleigh_tau550() if rayleigh_optical_depth_550 is None else rayleigh_optical_depth_550
        tau_r = check_range("rayleigh_optical_depth_550", tau_r, 1e-6, 10.0)
        aod550 = (turbidity - 1.0) * tau_r
    if stratospheric_aod550 is not None:
        stratospheric_aod550 = check_range("stratospheric_aod550", stratospheric_aod550, *STRATOSPHERIC_AOD_RANGE)

    wl_key = tuple(wl.tolist())
    ref_key = (550.0,) + ANGSTROM_PAIR_NM
    angles = _lookup(model)["angles_deg"]
    n_wl, n_alt = wl.size, h.size
    sca_by_regime = np.zeros((2, n_alt, n_wl))
    absorption = np.zeros((n_alt, n_wl))
    phase = np.full((2, angles.size, n_wl), 1.0 / (4.0 * np.pi))
    tau_regime = np.zeros((2, n_wl))
    tau_sca_regime = np.zeros((2, n_wl))
    g_regime = np.zeros((2, n_wl))
    tau_ref = np.zeros(3)  # column AOD at 550, 440, 675
    amounts = [0.0, 0.0]

    for r, name in enumerate((trop, strat)):
        if name is None:
            continue
        f = vertical_profile(name, h, model)
        col = float(trapezoid(f, h))  # m
        mix = _mixture(name, wl_key, model)
        ref = _mixture(name, ref_key, model)
        if r == 0:
            target = aod550
        else:
            target = (stratospheric_aod550 if stratospheric_aod550 is not None
                      else float(_all_types(model)[name]["default_aod550"]))
        if target is None:
            scale = 1.0
        elif target == 0.0:
            scale = 0.0
        else:
            if col <= 0.0:
                raise SkymodelInputError("altitudes_m", [float(h[0]), float(h[-1])],
                                         f"an altitude grid that covers the {name} aerosol layer")
            scale = target / (ref["ext"][0] * col)
        amounts[r] = float(ref["ext"][0] * col * scale)
        sca_by_regime[r] = np.outer(f * scale, mix["sca"])
        absorption += np.outer(f * scale, mix["ext"] - mix["sca"])
        phase[r] = mix["phase"]
        tau_regime[r] = mix["ext"] * col * scale
        tau_sca_regime[r] = mix["sca"] * col * scale
        g_regime[r] = mix["g"]
        tau_ref += ref["ext"] * col * scale

    tau = tau_regime.sum(axis=0)
    tau_sca = tau_sca_regime.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        ssa = np.where(tau > 0, tau_sca / np.where(tau > 0, tau, 1.0), 1.0)
        g = np.where(tau_sca > 0, (tau_sca_regime * g_regime).sum(axis=0) / np.where(tau_sca > 0, tau_sca, 1.0), 0.0)
    if tau_ref[1] > 0 and tau_ref[2] > 0:
        alpha = -math.log(tau_ref[1] / tau_ref[2]) / math.log(ANGSTROM_PAIR_NM[0] / ANGSTROM_PAIR_NM[1])
    else:
        alpha = 0.0
    return AerosolOptics(
        wavelengths_nm=wl,
        altitudes_m=h,
        angles_deg=np.array(angles, dtype=float),
        scattering_by_regime=sca_by_regime,
        absorption=absorption,
        phase=phase,
        aod550=amounts[0],
        stratospheric_aod550=amounts[1],
        optical_depth=tau,
        optical_depth_by_regime=tau_regime,
        single_scattering_albedo=ssa,
        asymmetry=g,
        angstrom_exponent=float(alpha),
        aerosol_type="none" if trop is None else trop,
        stratospheric=strat_key,
        aerosol_model=model,
    )
