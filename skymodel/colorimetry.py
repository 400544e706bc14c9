"""Spectral radiance -> CIE XYZ -> scene-linear RGB.

* XYZ uses the CIE 1931 2-degree standard observer at 1 nm (the package table
  ``skymodel/data/sources/colour/cie_1931_2deg_cmf_1nm.csv``: the numbers colour-science
  ships as ``colour.MSDS_CMFS``, read without importing colour-science, whose import
  (matplotlib, pandas, scipy) cost every render 1.5-2.7 s), integrated
  over the wavelength grid with trapezoid weights, so a 5 nm and a 10 nm grid give the
  same colour for a smooth spectrum. ``Y`` of spectral radiance (W m^-2 sr^-1 nm^-1) is
  in W m^-2 sr^-1 "luminous-weighted"; multiply by K_m = 683 lm/W for luminance in cd/m^2
  (:func:`luminance_cd_m2`).
* Scene-linear Rec.709 (Blender's default working space; sRGB primaries, D65 white) and
  ACEScg (AP1 primaries, ACES white point, reached with the CAT02 chromatic adaptation
  from D65, the Academy's recommendation). No white balance is applied to the sky: a
  spectrally flat radiance maps to the equal-energy white E, which in Rec.709 is slightly
  pink. The RGB matrices are derived here from the spaces' published primaries and white
  points as colour-science derives them (``colour.RGB_COLOURSPACES``; equal to its matrices
  to 2.2e-16, tests/test_colorimetry.py, where colour-science stays the oracle).
"""

from __future__ import annotations

import functools

import numpy as np

from skymodel.numerics import trapezoid
from skymodel.wavelengths import as_wavelengths

#: Maximum luminous efficacy of photopic vision, lm W^-1.
K_M = 683.002

_CMFS_NAME = "CIE 1931 2 Degree Standard Observer"

#: The CIE 1931 2-degree colour-matching functions at 1 nm (package data, with its source).
CMF_TABLE = "sources/colour/cie_1931_2deg_cmf_1nm.csv"

#: CIE 1931 xy chromaticities of the white points: D65 (ITU-R BT.709-6, 4 digits, as
#: colour-science's ``CCS_ILLUMINANTS``) and the ACES white (SMPTE ST 2065-1).
WHITE_D65_XY = (0.3127, 0.3290)
WHITE_ACES_XY = (0.32168, 0.33767)
#: xy of the red, green and blue primaries: ITU-R BT.709-6 and ACES AP1 (ACEScg, S-2014-004).
PRIMARIES_BT709_XY = (0.64, 0.33, 0.30, 0.60, 0.15, 0.06)
PRIMARIES_AP1_XY = (0.713, 0.293, 0.165, 0.830, 0.128, 0.044)
#: The CAT02 chromatic adaptation matrix, XYZ -> LMS (CIE 159:2004, CIECAM02).
CAT02 = ((0.7328, 0.4296, -0.1624), (-0.7036, 1.6975, 0.0061), (0.0030, 0.0136, 0.9834))


@functools.lru_cache(maxsize=1)
def _cmfs_1nm():
    from skymodel.data import load_csv

    _, table = load_csv(CMF_TABLE)
    return np.array(table[:, 0]), np.array(table[:, 1:])


def _xy_to_xyz(xy) -> np.ndarray:
    """XYZ (Y = 1) of chromaticity ``xy``."""
    x, y = xy
    return np.array([x / y, 1.0, (1.0 - x - y) / y])


def _rgb_to_xyz_matrix(primaries_xy, white_xy) -> np.ndarray:
    """The normalised primary matrix (RGB -> XYZ, white -> Y = 1), computed as
    colour-science's ``normalised_primary_matrix`` does."""
    p = np.asarray(primaries_xy, dtype=float).reshape(3, 2)
    prim = np.transpose(np.hstack([p, (1.0 - p[:, 0] - p[:, 1])[:, None]]))
    return np.dot(prim, np.diagflat(np.dot(np.linalg.inv(prim), _xy_to_xyz(white_xy))))


def _cat02_matrix(white_from_xy, white_to_xy) -> np.ndarray:
    """Von Kries adaptation in the CAT02 cone space, XYZ under one white -> the other."""
    cat = np.asarray(CAT02)
    gain = (cat @ _xy_to_xyz(white_to_xy)) / (cat @ _xy_to_xyz(white_from_xy))
    return np.linalg.inv(cat) @ np.diag(gain) @ cat


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
    (``"rec709"`` or ``"acescg"``; ACEScg through CAT02 from D65 to the ACES white)."""
    if space == "rec709":
        return np.linalg.inv(_rgb_to_xyz_matrix(PRIMARIES_BT709_XY, WHITE_D65_XY))
    if space == "acescg":
        return (np.linalg.inv(_rgb_to_xyz_matrix(PRIMARIES_AP1_XY, WHITE_ACES_XY))
                @ _cat02_matrix(WHITE_D65_XY, WHITE_ACES_XY))
    from skymodel.errors import SkymodelInputError

    raise SkymodelInputError("colour_space", space, "one of: rec709, acescg")


def xyz_to_rgb(xyz, space: str = "rec709") -> np.ndarray:
    return np.asarray(xyz, dtype=float) @ xyz_to_rgb_matrix(space).T


def spectral_to_rgb(radiance, wavelengths_nm, space: str = "rec709") -> np.ndarray:
    """Scene-linear RGB (same radiometric scale as XYZ) of spectra on the last axis."""
    return xyz_to_rgb(spectral_to_xyz(radiance, wavelengths_nm), space)
