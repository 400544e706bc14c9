"""Alternative sky models, selectable by name, for side-by-side comparison.

Every model is a callable ``model(scene, directions) -> ModelRadiance``: ``scene`` is a
:class:`SkyScene` (the atmosphere, the sun, the wavelength grid), ``directions`` unit
vectors ``(N, 3)`` in the observer frame of :mod:`skymodel.render.rays` (x east, y north,
z up; azimuth clockwise from north). Ask for all the directions of a comparison in one
call: some models do their expensive set-up (our marcher's multiple-scattering solution,
Blender's render) once per call.

What a model returns (``ModelRadiance.kind``):

``"spectral"``
    spectral radiance ``(N, n_wl)`` in W m^-2 sr^-1 nm^-1 on ``scene.wavelengths_nm``
    (``ours``, ``preetham``, ``openspace_earth``).
``"xyz"``
    CIE 1931 XYZ ``(N, 3)`` on the radiometric scale of
    :func:`skymodel.colorimetry.spectral_to_xyz` (W m^-2 sr^-1, luminous-weighted;
    ``683 Y`` is luminance in cd m^-2) — models known only as colours (Blender's).
``"relative"``
    relative luminance ``L / L_zenith`` ``(N,)`` — the CIE standard general skies, which
    define no absolute level and no colour.

Registered names (``model_names()``): ``ours`` (the spectral marcher with multiple
scattering), ``ours_single`` (the same, single scattering only), ``preetham``
(Preetham, Shirley & Smits 1999), ``cie1`` .. ``cie15`` (CIE standard general skies;
``cie12`` is the CIE standard clear sky), ``blender_multiple`` / ``blender_single`` /
``blender_preetham`` / ``blender_hosek`` (Blender 5.0's Sky Texture, rendered with
``bpy``, optional), ``openspace_earth`` (the exponential OpenSpace parameterisation of
Costa et al. rendered by our marcher).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from skymodel import scene
from skymodel.errors import SkymodelInputError, check_range

KINDS = ("spectral", "xyz", "relative")


@dataclass(frozen=True)
class SkyScene:
    """What every model is asked to reproduce: an atmosphere (``skymodel.Atmosphere``),
    the sun (degrees; azimuth clockwise from north) and the wavelength grid (nm)."""

    atmosphere: object
    sun_elevation_deg: float
    sun_azimuth_deg: float = 180.0
    wavelengths_nm: np.ndarray | None = None
    quality: str = scene.default("quality")

    def __post_init__(self):
        check_range("sun_elevation", self.sun_elevation_deg, -90.0, 90.0, "degrees")
        check_range("sun_azimuth", self.sun_azimuth_deg, -360.0, 360.0, "degrees")
        if self.wavelengths_nm is None:
            from skymodel.wavelengths import default_wavelengths

            object.__setattr__(self, "wavelengths_nm", default_wavelengths(10.0))
        else:
            from skymodel.wavelengths import as_wavelengths

            object.__setattr__(self, "wavelengths_nm", as_wavelengths(self.wavelengths_nm))

    @property
    def sun_zenith_rad(self) -> float:
        return float(np.radians(90.0 - self.sun_elevation_deg))

    @property
    def sun_direction(self) -> np.ndarray:
        from skymodel.render.rays import sun_direction

        return np.asarray(sun_direction(self.sun_elevation_deg, self.sun_azimuth_deg), dtype=float)

    def view_angles(self, directions):
        """``(theta, gamma)`` in radians: zenith angle of each direction and its angle to the sun."""
        d = as_directions(directions)
        theta = np.arccos(np.clip(d[:, 2], -1.0, 1.0))
        gamma = np.arccos(np.clip(d @ self.sun_direction, -1.0, 1.0))
        return theta, gamma

    def relative_azimuth(self, directions):
        """Azimuth of each direction from the sun's, radians in [0, pi] (the skies are symmetric)."""
        d = as_directions(directions)
        az = np.arctan2(d[:, 0], d[:, 1])
        rel = np.abs((az - np.radians(self.sun_azimuth_deg) + np.pi) % (2.0 * np.pi) - np.pi)
        return rel


def as_directions(directions) -> np.ndarray:
    """Unit vectors (N, 3) from any (..., 3) array (zero vectors are refused)."""
    d = np.asarray(directions, dtype=float)
    if d.ndim < 1 or d.shape[-1] != 3:
        raise SkymodelInputError("directions", f"array of shape {d.shape}", "an array of shape (..., 3)")
    d = d.reshape(-1, 3)
    n = np.linalg.norm(d, axis=1)
    if not np.all(np.isfinite(n) & (n > 0)):
        raise SkymodelInputError("directions", "zero or non-finite vectors", "non-zero finite vectors")
    return d / n[:, None]


@dataclass
class ModelRadiance:
    """One model's answer for a set of directions (see the module doc for ``kind``)."""

    kind: str
    values: np.ndarray
    wavelengths_nm: np.ndarray | None = None
    info: dict = field(default_factory=dict)

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"kind must be one of {KINDS}")

    @property
    def is_absolute(self) -> bool:
        return self.kind != "relative"

    def xyz(self) -> np.ndarray:
        """CIE XYZ (N, 3), radiometric scale (683 Y = cd m^-2). Relative models give the
        D65 white of luminance ``Y = L / L_zenith``."""
        if self.kind == "spectral":
            from skymodel.colorimetry import spectral_to_xyz

            return spectral_to_xyz(self.values, self.wavelengths_nm)
        if self.kind == "xyz":
            return np.asarray(self.values, dtype=float)
        x, y = D65_XY
        Y = np.asarray(self.values, dtype=float)
        return np.stack([x / y * Y, Y, (1.0 - x - y) / y * Y], axis=-1)

    def luminance(self) -> np.ndarray:
        """Luminance in cd m^-2 (absolute models) or L / L_zenith (relative models)."""
        if self.kind == "relative":
            return np.asarray(self.values, dtype=float)
        from skymodel.colorimetry import K_M

        return K_M * self.xyz()[:, 1]


#: CIE 1931 chromaticity of illuminant D65 (colour-science's value, to 4 decimals).
D65_XY = (0.3127, 0.3290)


@dataclass(frozen=True)
class SkyModel:
    """A registered model: ``fn(scene, directions) -> ModelRadiance``."""

    name: str
    kind: str
    description: str
    fn: Callable
    requires: str | None = None  # an optional module it needs ("bpy")

    def __call__(self, scene: SkyScene, directions) -> ModelRadiance:
        return self.fn(scene, as_directions(directions))

    def available(self) -> bool:
        if self.requires is None:
            return True
        import importlib.util

        return importlib.util.find_spec(self.requires) is not None


_REGISTRY: dict[str, SkyModel] = {}
_LOADED = False


def register(model: SkyModel) -> SkyModel:
    _REGISTRY[model.name] = model
    return model


def _ensure_registered():
    global _LOADED
    if _LOADED:
        return
    _LOADED = True
    register(SkyModel("ours", "spectral", "skymodel's spectral marcher: Rayleigh, ozone, Mie aerosols, "
                      "multiple scattering, ground albedo", _ours))
    register(SkyModel("ours_single", "spectral", "skymodel's marcher, single-scattering part only "
                      "(shows the multiple-scattering share)", _ours_single))
    from skymodel.models import preetham, cie, blender_sky  # noqa: F401  (each registers its models)

    try:
        from skymodel.models import openspace  # noqa: F401
    except ImportError:  # pragma: no cover - optional module
        pass


_OURS_CACHE: dict = {}


def _ours_result(scene: SkyScene, d):
    """Our marcher's answer (single, multiple and ground parts), cached for the last scene
    and directions so that ``ours`` and ``ours_single`` share one solution."""
    import hashlib

    from skymodel.render.marcher import SkyMarcher
    from skymodel.render.quality import quality_settings

    key = (scene.atmosphere, scene.sun_elevation_deg, scene.sun_azimuth_deg, tuple(scene.wavelengths_nm.tolist()),
           str(scene.quality), hashlib.sha1(np.ascontiguousarray(d).tobytes()).hexdigest())
    if key not in _OURS_CACHE:
        profile = scene.atmosphere.optical_profile(scene.wavelengths_nm)
        res = SkyMarcher(profile, scene.sun_elevation_deg, scene.sun_azimuth_deg, 0.0,
                         quality_settings(scene.quality)).radiance(d)
        _OURS_CACHE.clear()
        _OURS_CACHE[key] = (profile, res)
    return _OURS_CACHE[key]


def _ours(scene: SkyScene, d) -> ModelRadiance:
    profile, res = _ours_result(scene, d)
    info = {"aod550": profile.metadata["aod550"], "ozone_du": profile.metadata["ozone_du"],
            "orders": res.info.get("orders"), "sun_irradiance": np.asarray(res.sun_irradiance)}
    return ModelRadiance("spectral", np.asarray(res.radiance), scene.wavelengths_nm, info)


def _ours_single(scene: SkyScene, d) -> ModelRadiance:
    profile, res = _ours_result(scene, d)
    return ModelRadiance("spectral", np.asarray(res.single + res.ground), scene.wavelengths_nm,
                         {"aod550": profile.metadata["aod550"], "note": "single scattering + ground only"})


def model_names(available_only: bool = False) -> list[str]:
    _ensure_registered()
    return [n for n, m in _REGISTRY.items() if not available_only or m.available()]


def get_model(name, parameter: str = "model") -> SkyModel:
    """The model called ``name`` (case-insensitive); :class:`SkymodelInputError` naming
    ``parameter`` and listing the names otherwise."""
    _ensure_registered()
    key = str(name).strip().lower()
    if key not in _REGISTRY:
        raise SkymodelInputError(parameter, name, "one of: " + ", ".join(_REGISTRY))
    return _REGISTRY[key]


def parse_model_list(text, parameter: str = "models") -> list[SkyModel]:
    """``"ours,preetham,cie12"`` (or a list of names) -> models, in order, without repeats."""
    names = [t.strip() for t in text.split(",")] if isinstance(text, str) else [str(t).strip() for t in text]
    names = [n for n in names if n]
    if not names:
        raise SkymodelInputError(parameter, text, "a comma-separated list of model names")
    out = []
    for n in names:
        m = get_model(n, parameter)
        if m not in out:
            out.append(m)
    return out


def sky_radiance(name, scene: SkyScene, directions) -> ModelRadiance:
    """Shorthand: ``get_model(name)(scene, directions)``."""
    return get_model(name)(scene, directions)
