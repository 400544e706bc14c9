"""The wavelength grid (nanometres, vacuum).

The default grid is 380–780 nm every 5 nm (81 samples), the range of the CIE 1931
colour-matching functions that carry visible colour. Any sub-grid inside
:data:`MIN_NM`..:data:`MAX_NM` is allowed (10 or 20 nm steps, or a handful of
wavelengths); the tabulated data in ``presets/`` covers that range.
"""

from __future__ import annotations

import numpy as np

from skymodel.errors import SkymodelInputError

MIN_NM = 380.0
MAX_NM = 780.0
DEFAULT_STEP_NM = 5.0


def default_wavelengths(step_nm: float = DEFAULT_STEP_NM) -> np.ndarray:
    """Evenly spaced grid from 380 to 780 nm inclusive with ``step_nm`` spacing (nm)."""
    if not (0 < step_nm <= MAX_NM - MIN_NM):
        raise SkymodelInputError("step_nm", step_nm, f"a step in (0, {MAX_NM - MIN_NM}] nm")
    n = int(round((MAX_NM - MIN_NM) / step_nm)) + 1
    return np.linspace(MIN_NM, MAX_NM, n)


def as_wavelengths(wavelengths=None) -> np.ndarray:
    """Validate and return a 1-D float array of wavelengths in nm (default grid if None).

    Raises :class:`SkymodelInputError` for values outside 380–780 nm, non-finite values,
    or an empty list.
    """
    if wavelengths is None:
        return default_wavelengths()
    wl = np.atleast_1d(np.asarray(wavelengths, dtype=float)).ravel()
    if wl.size == 0:
        raise SkymodelInputError("wavelengths", list(wl), f"at least one wavelength in [{MIN_NM:g}, {MAX_NM:g}] nm")
    bad = ~np.isfinite(wl) | (wl < MIN_NM) | (wl > MAX_NM)
    if np.any(bad):
        raise SkymodelInputError(
            "wavelengths", float(wl[bad][0]), f"wavelengths in [{MIN_NM:g}, {MAX_NM:g}] nm (the tabulated range)"
        )
    return wl
