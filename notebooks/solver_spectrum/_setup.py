"""Shared by measure.py and variants.py: a solution cut down to some of its solver wavelengths, and
the linear map they compare against."""
from dataclasses import replace

import numpy as np

from skymodel.render.marcher import profile_at_wavelengths
from skymodel.render.medium import factor_medium


def sub_solution(sol, profile, idx, to_full):
    """``sol`` (a SkySolution solved at every wavelength of ``profile``) keeping only the solver
    wavelengths ``idx``, carried to the profile's by ``to_full`` (any callable on (..., n_idx))."""
    f = sol.field
    w = f.wavelengths_nm[idx]
    sc = None if f.scattering is None else replace(f.scattering, weights=f.scattering.weights[:, idx])
    field = replace(f, wavelengths_nm=w, source=np.ascontiguousarray(f.source[idx]),
                    ground_diffuse_irradiance=f.ground_diffuse_irradiance[:, idx], scattering=sc)
    pm = replace(profile_at_wavelengths(profile, w), solar_irradiance=np.ones_like(w))
    return replace(sol, medium_ms=factor_medium(pm, sol.medium.cutoff_deg), field=field, to_full=to_full)


class LinearMap:
    """Spectra carried by a plain matrix (the linear reading before the log-ozone map), called
    as the marcher calls its ``to_full``."""

    def __init__(self, matrix):
        self.matrix = matrix

    def __call__(self, values):
        return np.asarray(values) @ self.matrix
