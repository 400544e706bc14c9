"""Small numerical helpers that work on numpy 1.26 (Blender 5.0's numpy) and numpy 2.x."""

from __future__ import annotations

import numpy as np

_trapz = getattr(np, "trapezoid", None) or getattr(np, "trapz")


def trapezoid(y, x=None, axis=-1):
    """Trapezoidal rule (``numpy.trapezoid`` on numpy 2, ``numpy.trapz`` on 1.26)."""
    return _trapz(y, x=x, axis=axis)


def cumulative_trapezoid(y, x, axis=0):
    """Running trapezoidal integral starting at 0, same shape as ``y``."""
    from scipy.integrate import cumulative_trapezoid as ct

    return ct(y, x, axis=axis, initial=0.0)


def linear_interp_matrix(src, dst) -> np.ndarray:
    """Matrix W (n_src, n_dst) of linear interpolation from nodes ``src`` (ascending) to
    points ``dst`` (clamped to the end nodes): values on ``dst`` = values on ``src`` @ W.
    A single node is copied everywhere.

    ``src`` must be strictly ascending and finite (``ValueError`` otherwise): a descending
    or unsorted grid would give a wrong matrix without a word, which is how unsorted
    wavelengths once gave 40 % wrong radiance."""
    src = np.asarray(src, float)
    dst = np.asarray(dst, float)
    if src.ndim != 1 or src.size == 0 or not np.all(np.isfinite(src)) or np.any(np.diff(src) <= 0):
        raise ValueError("linear_interp_matrix: the nodes must be a non-empty, finite, strictly ascending 1-D "
                         f"array (got {src.size} nodes)")
    if not np.all(np.isfinite(dst)):
        raise ValueError("linear_interp_matrix: the points must be finite")
    w = np.zeros((src.size, dst.size))
    if src.size == 1:
        w[0] = 1.0
        return w
    i = np.clip(np.searchsorted(src, dst, side="right") - 1, 0, src.size - 2)
    f = np.clip((dst - src[i]) / (src[i + 1] - src[i]), 0.0, 1.0)
    w[i, np.arange(dst.size)] += 1 - f
    w[i + 1, np.arange(dst.size)] += f
    return w
