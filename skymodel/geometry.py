"""Planet geometry constants and the altitude grid (metres); the view-elevation bands the
measured error tables report by.

Spherical Earth of radius 6360 km (the value of Bruneton & Neyret 2008 and of the
paper this project follows), atmosphere up to 100 km (the Karman line).
"""

from __future__ import annotations

import numpy as np

from skymodel.errors import SkymodelInputError

#: Ground radius of the spherical Earth, metres.
EARTH_RADIUS_M = 6_360_000.0
#: Altitude of the top of the atmosphere, metres.
TOA_ALTITUDE_M = 100_000.0
#: View-elevation bands (degrees, [low, high), the last one closed at 90) in which the
#: planner's measured tables report the error of the sky seen directly: the effect table
#: (``benchmarks/bench_planner.py``) and the accuracy table's knob rows
#: (:mod:`skymodel.validation.accuracy`).
VIEW_BANDS_DEG = {"ground": (-90.0, 0.0), "horizon": (0.0, 10.0), "low": (10.0, 30.0), "high": (30.0, 90.0)}


def view_band_masks(elevation_deg) -> dict:
    """``{band: boolean mask}`` of the view elevations (degrees, any shape) in each of
    :data:`VIEW_BANDS_DEG`."""
    e = np.asarray(elevation_deg, float)
    return {b: (e >= lo) & ((e < hi) if hi < 90.0 else (e <= hi)) for b, (lo, hi) in VIEW_BANDS_DEG.items()}


def altitude_grid(n: int = 401, top_m: float = TOA_ALTITUDE_M, stretch: float = 3.0) -> np.ndarray:
    """Altitudes in metres from 0 to ``top_m``, ``n`` points, denser near the ground.

    Points follow ``h = top * (exp(s*u) - 1) / (exp(s) - 1)`` for ``u`` evenly spaced in
    [0, 1]; ``stretch = s`` controls the crowding (0 gives an even grid). With the
    default 401 points the spacing is ~40 m at the ground and ~0.6 km at 100 km, and
    column integrals of every species converge to better than 0.1 % (tested).
    """
    if int(n) < 2:
        raise SkymodelInputError("n_altitudes", n, "an integer >= 2")
    u = np.linspace(0.0, 1.0, int(n))
    if stretch == 0:
        return top_m * u
    return top_m * np.expm1(stretch * u) / np.expm1(stretch)
