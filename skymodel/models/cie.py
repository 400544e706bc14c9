"""CIE standard general sky (ISO 15469:2004 / CIE S 011/E:2003): relative luminance.

    L(Z, chi) / L_z = f(chi) phi(Z) / (f(Z_s) phi(0))
    phi(Z) = 1 + a exp(b / cos Z)   (phi = 1 at and below the horizon)
    f(chi) = 1 + c (exp(d chi) - exp(d pi / 2)) + e cos^2 chi

Z is the zenith angle of the sky element, Z_s that of the sun and chi the angle between
them. The 15 sky types combine six gradation groups (a, b) and six indicatrix groups
(c, d, e) (``skymodel/data/sources/models/cie.toml``); type 12 (V.4: a = -1, b = -0.32, c = 10,
d = -3, e = 0.45) is the CIE standard clear sky, the usual validation reference for a
clear-sky luminance pattern. The standard fixes neither the absolute level nor a colour:
the registered models ``cie1`` .. ``cie15`` return ``kind = "relative"`` (L / L_z), and
below the horizon 0.
"""

from __future__ import annotations

import functools

import numpy as np

from skymodel.data import load_toml
from skymodel.errors import SkymodelInputError
from skymodel.models import ModelRadiance, SkyModel, SkyScene, register

TABLE = "sources/models/cie.toml"


@functools.lru_cache(maxsize=1)
def _table() -> dict:
    return load_toml(TABLE)


def sky_type_parameters(sky_type) -> tuple[float, float, float, float, float]:
    """(a, b, c, d, e) of CIE standard sky type 1..15."""
    key = str(sky_type)
    types = _table()["types"]
    if key not in types:
        raise SkymodelInputError("sky_type", sky_type, "a CIE standard sky type 1..15")
    grad, ind, _ = types[key]
    a, b = _table()["gradation"][grad]
    c, d, e = _table()["indicatrix"][ind]
    return float(a), float(b), float(c), float(d), float(e)


def gradation(zenith_rad, a, b):
    """phi(Z) = 1 + a exp(b / cos Z); 1 at the horizon (cos Z -> 0+) and below."""
    cz = np.cos(np.asarray(zenith_rad, dtype=float))
    pos = cz > 1e-9
    return np.where(pos, 1.0 + a * np.exp(b / np.where(pos, cz, 1.0)), 1.0)


def indicatrix(chi_rad, c, d, e):
    """f(chi) = 1 + c (exp(d chi) - exp(d pi/2)) + e cos^2 chi."""
    chi = np.asarray(chi_rad, dtype=float)
    return 1.0 + c * (np.exp(d * chi) - np.exp(d * np.pi / 2.0)) + e * np.cos(chi) ** 2


def relative_luminance(zenith_rad, chi_rad, sun_zenith_rad, sky_type=12):
    """L / L_z of CIE standard sky ``sky_type`` (angles in radians)."""
    a, b, c, d, e = sky_type_parameters(sky_type)
    return (indicatrix(chi_rad, c, d, e) * gradation(zenith_rad, a, b)
            / (indicatrix(sun_zenith_rad, c, d, e) * gradation(0.0, a, b)))


def _make(sky_type):
    def fn(scene: SkyScene, d) -> ModelRadiance:
        theta, gamma = scene.view_angles(d)
        rel = relative_luminance(theta, gamma, scene.sun_zenith_rad, sky_type)
        rel = np.where(theta <= np.pi / 2, rel, 0.0)
        return ModelRadiance("relative", rel, None, {"sky_type": sky_type, "parameters": sky_type_parameters(sky_type)})

    return fn


for _t in range(1, 16):
    register(SkyModel(f"cie{_t}", "relative", f"CIE standard general sky type {_t}: "
                      f"{_table()['types'][str(_t)][2]} (relative luminance only)", _make(_t)))
