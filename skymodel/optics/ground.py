"""Ground reflection: Lambertian albedo, per surface type (``skymodel/data/presets/surfaces.toml``).

A Lambertian ground of albedo A reflects radiance L = A E / pi for an incident
irradiance E. Albedo is grey (wavelength independent) unless the caller gives a
spectrum (one value per wavelength).
"""

from __future__ import annotations

import numpy as np

from skymodel.data import load_toml
from skymodel.errors import SkymodelInputError, check_choice


def surfaces() -> dict[str, float]:
    """Surface name -> default broadband albedo."""
    return {k: float(v["albedo"]) for k, v in load_toml("presets/surfaces.toml")["surfaces"].items()}


def surface_albedo(surface: str) -> float:
    name = check_choice("surface", surface, surfaces())
    return surfaces()[name]


def albedo_spectrum(albedo, wavelengths_nm) -> np.ndarray:
    """Albedo per wavelength: a scalar in [0, 1] is spread over the grid; an array must
    match the grid. Values outside [0, 1] raise :class:`SkymodelInputError`."""
    wl = np.asarray(wavelengths_nm, dtype=float)
    a = np.asarray(albedo, dtype=float)
    if a.ndim == 0:
        a = np.full(wl.shape, float(a))
    if a.shape != wl.shape:
        raise SkymodelInputError("albedo", albedo, f"a number in [0, 1] or {wl.size} values (one per wavelength)")
    if np.any(~np.isfinite(a)) or np.any(a < 0) or np.any(a > 1):
        raise SkymodelInputError("albedo", albedo.tolist() if hasattr(albedo, "tolist") else albedo, "values in [0, 1]")
    return a
