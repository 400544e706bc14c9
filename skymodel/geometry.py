"""Planet geometry constants and the altitude grid (metres).

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
