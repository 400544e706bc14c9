"""The sky as lighting: the irradiance on a horizontal surface and how far a render's is
from a reference's. One home for what the effect table (``benchmarks/bench_planner.py``)
and the accuracy table's knob rows (:mod:`skymodel.validation.accuracy`) both record, so
that the planner prices a sky seen only as lighting by the same measure in both.

* Irradiance: ``E_h = sum(L cos(zenith) dOmega)`` over the directions above the horizon
  plus the direct sun ``E_sun sin(sun elevation)`` (W m^-2 nm^-1, spectral).
* Errors of a render's ``E_h`` against the reference's: ``illuminance_rel`` =
  ``|Y - Y_ref| / Y_ref`` (fraction), ``de2000`` = CIEDE2000 of the two XYZ after the
  exposure ``XYZ / Y_ref`` and Reinhard's global operator on luminance (every channel
  scaled by ``1 / (1 + Y)``), Lab against D65: the colour of the light, white being the
  reference's.
"""

from __future__ import annotations

import numpy as np


def horizontal_irradiance(radiance, directions, omega, sun_irradiance, sun_elevation_deg) -> np.ndarray:
    """Spectral irradiance (W m^-2 nm^-1, shaped like the last axis of ``radiance``) on a
    horizontal surface: the sky's ``radiance`` (N, n_wl; W m^-2 sr^-1 nm^-1) over the
    unit ``directions`` (N, 3; z up) with solid angles ``omega`` (N,; sr), the directions
    below the horizon left out, plus the direct ``sun_irradiance`` (n_wl,; normal to the
    beam) times the sine of ``sun_elevation_deg`` (0 below the horizon)."""
    d = np.asarray(directions, float).reshape(-1, 3)
    w = np.asarray(omega, float).ravel()
    L = np.asarray(radiance, float).reshape(d.shape[0], -1)
    cz = d[:, 2]
    up = cz > 0
    sky = (L[up] * (cz[up] * w[up])[:, None]).sum(axis=0)
    return sky + np.asarray(sun_irradiance, float) * max(np.sin(np.radians(sun_elevation_deg)), 0.0)


def _lab(xyz_over_white):
    import colour

    d65 = colour.CCS_ILLUMINANTS["CIE 1931 2 Degree Standard Observer"]["D65"]
    return colour.XYZ_to_Lab(xyz_over_white, d65)


def reinhard_de2000(xyz_a, xyz_b, white_y) -> np.ndarray:
    """CIEDE2000 between two XYZ arrays (..., 3) after dividing by ``white_y`` and Reinhard's
    global operator on luminance (both through the same exposure, so a change of
    brightness counts)."""
    import colour

    def tone(xyz):
        x = np.asarray(xyz, float) / white_y
        return x / (1.0 + np.maximum(x[..., 1:2], 0.0))

    return np.asarray(colour.delta_E(_lab(tone(xyz_a)), _lab(tone(xyz_b)), method="CIE 2000"), float)


def lighting_errors(xyz, xyz_ref) -> dict:
    """``{"illuminance_rel", "de2000"}`` of the irradiance colour ``xyz`` (3,) against the
    reference's ``xyz_ref`` (3,) (module docstring)."""
    xyz = np.asarray(xyz, float)
    xyz_ref = np.asarray(xyz_ref, float)
    y_ref = max(float(xyz_ref[1]), 1e-30)
    return {"illuminance_rel": abs(float(xyz[1]) - y_ref) / y_ref,
            "de2000": float(reinhard_de2000(xyz, xyz_ref, y_ref))}
