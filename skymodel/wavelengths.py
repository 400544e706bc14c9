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
#: Finest step of :func:`default_wavelengths` [nm] (4001 samples; the tabulated data are
#: no finer than 1 nm). A smaller step once asked numpy for an array beyond its size limit.
MIN_STEP_NM = 0.1


def _number(parameter: str, value, allowed: str) -> float:
    """``value`` as a finite float; booleans, text and non-numbers raise naming ``parameter``."""
    if isinstance(value, (bool, np.bool_, str, bytes)):
        raise SkymodelInputError(parameter, value, allowed)
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise SkymodelInputError(parameter, value, allowed) from None
    if not np.isfinite(v):
        raise SkymodelInputError(parameter, value, allowed)
    return v


def default_wavelengths(step_nm: float = DEFAULT_STEP_NM) -> np.ndarray:
    """Evenly spaced grid from 380 to 780 nm inclusive with ``step_nm`` spacing (nm).

    Raises :class:`SkymodelInputError` naming ``step_nm`` for a step that is not a finite
    number in [0.1, 400] nm (text such as ``'5'`` and booleans included)."""
    allowed = f"a number in [{MIN_STEP_NM:g}, {MAX_NM - MIN_NM:g}] nm"
    step = _number("step_nm", step_nm, allowed)
    if not (MIN_STEP_NM <= step <= MAX_NM - MIN_NM):
        raise SkymodelInputError("step_nm", step_nm, allowed)
    n = int(round((MAX_NM - MIN_NM) / step)) + 1
    return np.linspace(MIN_NM, MAX_NM, n)


def as_wavelengths(wavelengths=None, *, parameter: str = "wavelengths") -> np.ndarray:
    """Validate and return a 1-D float array of wavelengths in nm (default grid if None).

    The wavelengths must be finite numbers in 380–780 nm, strictly ascending (no
    duplicates): every table in the core is interpolated on an ascending grid, and an
    unsorted list once came back silently wrong. A caller holding a list in another order
    sorts it and answers in the user's order (:func:`ascending_order`).

    Raises :class:`SkymodelInputError` naming ``parameter`` for text, booleans, nested
    (2-D) lists, values outside 380–780 nm, non-finite values, an empty list, duplicates
    or a descending/unsorted list.
    """
    if wavelengths is None:
        return default_wavelengths()
    allowed = f"a list of numbers in [{MIN_NM:g}, {MAX_NM:g}] nm, strictly ascending"
    if isinstance(wavelengths, (str, bytes, bool, np.bool_)):
        raise SkymodelInputError(parameter, wavelengths, allowed)
    try:
        raw = np.asarray(wavelengths)
    except (TypeError, ValueError):  # ragged nesting
        raise SkymodelInputError(parameter, wavelengths, allowed) from None
    if raw.ndim > 1:
        raise SkymodelInputError(parameter, f"an array of shape {raw.shape}", allowed + " (one dimension)")
    if raw.dtype.kind not in "iuf":
        raise SkymodelInputError(parameter, wavelengths, allowed)
    wl = np.atleast_1d(raw.astype(float))
    if wl.size == 0:
        raise SkymodelInputError(parameter, [], f"at least one wavelength in [{MIN_NM:g}, {MAX_NM:g}] nm")
    bad = ~np.isfinite(wl) | (wl < MIN_NM) | (wl > MAX_NM)
    if np.any(bad):
        raise SkymodelInputError(
            parameter, float(wl[bad][0]), f"wavelengths in [{MIN_NM:g}, {MAX_NM:g}] nm (the tabulated range)"
        )
    step = np.diff(wl)
    if np.any(step == 0):
        raise SkymodelInputError(parameter, float(wl[1:][step == 0][0]), "wavelengths without duplicates")
    if np.any(step < 0):
        raise SkymodelInputError(parameter, wl.tolist() if wl.size <= 8 else f"{wl.size} wavelengths",
                                 "wavelengths in ascending order")
    return wl


def ascending_order(wavelengths, *, parameter: str = "wavelengths"):
    """For a list of wavelengths in any order: ``(ascending, back)`` where ``ascending``
    is the validated ascending grid (:func:`as_wavelengths`) and ``back`` the index array
    that puts a result computed on it into the user's order (``result[..., back]``).
    Duplicates are refused (they have no single place in the answer)."""
    if wavelengths is None:
        wl = default_wavelengths()
        return wl, np.arange(wl.size)
    if isinstance(wavelengths, (str, bytes, bool, np.bool_)):
        return as_wavelengths(wavelengths, parameter=parameter), None  # raises
    try:
        raw = np.asarray(wavelengths)
    except (TypeError, ValueError):
        return as_wavelengths(wavelengths, parameter=parameter), None  # raises
    if raw.ndim != 1 or raw.dtype.kind not in "iuf":
        return as_wavelengths(wavelengths, parameter=parameter), None  # raises (or validates a scalar)
    order = np.argsort(raw, kind="stable")
    wl = as_wavelengths(raw[order], parameter=parameter)
    back = np.empty_like(order)
    back[order] = np.arange(order.size)
    return wl, back


def spread_indices(wavelengths_nm, step_nm: float) -> np.ndarray:
    """Indices of wavelengths spread evenly over an ascending grid (nm), at most about
    ``step_nm`` apart, both ends included: ceil(range / step) + 1 targets evenly spaced in
    wavelength, each the nearest grid wavelength (its fractional index on the grid, rounded;
    a tie goes to the even index), duplicates dropped. On an evenly spaced grid this is
    evenly spaced in index. Used for the probe wavelengths at which costly corrections are
    computed and read between (the peak paths, the solver's spherical correction)."""
    wl = np.asarray(wavelengths_nm, float)
    n_probe = int(np.clip(np.ceil((wl[-1] - wl[0]) / max(step_nm, 1e-9) - 1e-9) + 1, 1, wl.size))
    steps = np.diff(wl)
    if steps.size and np.ptp(steps) <= 1e-9 * abs(steps[0]):  # evenly spaced: in index
        at = np.linspace(0, wl.size - 1, n_probe)
    else:
        at = np.interp(np.linspace(wl[0], wl[-1], n_probe), wl, np.arange(wl.size, dtype=float))
    return np.unique(np.round(at).astype(int))
