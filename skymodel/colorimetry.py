"""Spectral radiance -> CIE XYZ -> scene-linear RGB, through colour-science.

* XYZ uses the CIE 1931 2-degree standard observer (``colour.MSDS_CMFS``), integrated
  over the wavelength grid with trapezoid weights, so a 5 nm and a 10 nm grid give the
  same colour for a smooth spectrum. ``Y`` of spectral radiance (W m^-2 sr^-1 nm^-1) is
  in W m^-2 sr^-1 "luminous-weighted"; multiply by K_m = 683 lm/W for luminance in cd/m^2
  (:func:`luminance_cd_m2`).
* Scene-linear Rec.709 (Blender's default working space; sRGB primaries, D65 white) and
  ACEScg (AP1 primaries, ACES white point, reached with the CAT02 chromatic adaptation
  from D65, the Academy's recommendation). No white balance is applied to the sky: a
  spectrally flat radiance maps to the equal-energy white E, which in Rec.709 is slightly
  pink. The RGB matrices come from colour-science (``colour.RGB_COLOURSPACES``).
"""

from __future__ import annotations

import functools

import numpy as np

from skymodel.numerics import trapezoid
from skymodel.wavelengths import as_wavelengths

#: Maximum luminous efficacy of photopic vision, lm W^-1.
K_M = 683.002

_CMFS_NAME = "CIE 1931 2 Degree Standard Observer"


@functools.lru_cache(maxsize=1)
def _cmfs_1nm():
    import colour

    c = colour.MSDS_CMFS[_CMFS_NAME]
    return np.asarray(c.wavelengths, dtype=float), np.asarray(c.values, dtype=float)


def cmf_weights(wavelengths_nm) -> np.ndarray:
    """Integration weights W (n_wl, 3) so that ``XYZ = L @ W`` for spectra sampled at
    ``wavelengths_nm``: the trapezoid rule applied to L(lambda) * cmf(lambda), where L is
    taken as piecewise linear between samples. For a single wavelength the weight is the
    CMF integrated over a 1 nm band."""
    wl = as_wavelengths(wavelengths_nm)
    cw, cv = _cmfs_1nm()
    if wl.size == 1:
        return np.array([np.interp(wl[0], cw, cv[:, k]) for k in range(3)])[None, :]
    order = np.argsort(wl)
    ws = wl[order]
    fine = np.arange(ws[0], ws[-1] + 0.25, 0.5)
    fine[-1] = min(fine[-1], ws[-1])
    # hat functions of linear interpolation on the sample grid, evaluated on a fine grid
    hats = np.empty((ws.size, fine.size))
    eye = np.eye(ws.size)
    for i in range(ws.size):
        hats[i] = np.interp(fine, ws, eye[i])
    cm = np.stack([np.interp(fine, cw, cv[:, k]) for k in range(3)], axis=1)  # (n_fine, 3)
    w_sorted = trapezoid(hats[:, :, None] * cm[None, :, :], fine, axis=1)
    w = np.empty_like(w_sorted)
    w[order] = w_sorted
    return w


def spectral_to_xyz(radiance, wavelengths_nm) -> np.ndarray:
    """CIE XYZ of spectra with the wavelength on the last axis (same units x nm)."""
    return np.asarray(radiance, dtype=float) @ cmf_weights(wavelengths_nm)


def luminance_cd_m2(radiance, wavelengths_nm) -> np.ndarray:
    """Photometric luminance in cd m^-2 of spectral radiance in W m^-2 sr^-1 nm^-1."""
    return K_M * spectral_to_xyz(radiance, wavelengths_nm)[..., 1]


@functools.lru_cache(maxsize=None)
def xyz_to_rgb_matrix(space: str = "rec709") -> np.ndarray:
    """3x3 matrix taking CIE XYZ (D65-referred) to linear RGB of ``space``
    (``"rec709"`` or ``"acescg"``)."""
    import colour

    if space == "rec709":
        return np.asarray(colour.RGB_COLOURSPACES["ITU-R BT.709"].matrix_XYZ_to_RGB, dtype=float)
    if space == "acescg":
        d65 = colour.CCS_ILLUMINANTS[_CMFS_NAME]["D65"]
        m = colour.XYZ_to_RGB(np.eye(3), colour.RGB_COLOURSPACES["ACEScg"], illuminant=d65,
                              chromatic_adaptation_transform="CAT02")
        return np.asarray(m, dtype=float).T
    from skymodel.errors import SkymodelInputError

    raise SkymodelInputError("colour_space", space, "one of: rec709, acescg")


def xyz_to_rgb(xyz, space: str = "rec709") -> np.ndarray:
    return np.asarray(xyz, dtype=float) @ xyz_to_rgb_matrix(space).T


def spectral_to_rgb(radiance, wavelengths_nm, space: str = "rec709") -> np.ndarray:
    """Scene-linear RGB (same radiometric scale as XYZ) of spectra on the last axis."""
    return xyz_to_rgb(spectral_to_xyz(radiance, wavelengths_nm), space)
