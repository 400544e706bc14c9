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
