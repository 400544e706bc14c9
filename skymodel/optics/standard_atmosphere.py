"""The U.S. Standard Atmosphere 1976 (NOAA/NASA/USAF, NOAA-S/T 76-1562), 0–100 km.

Below 86 km geometric altitude the model is seven layers in *geopotential* altitude H,
each with a constant temperature lapse rate L (K per geopotential metre). Within a
layer starting at H_b with temperature T_b and pressure P_b, hydrostatic balance of an
ideal gas of constant molecular weight gives (Table 4 and Eqs. 33a/33b of the standard):

* L != 0:  P = P_b (T_b / (T_b + L (H - H_b)))^(g0 M0 / (R* L))
* L == 0:  P = P_b exp(-g0 M0 (H - H_b) / (R* T_b))

Temperature is the *molecular-scale* temperature T_M; the kinetic temperature is
T = T_M M/M0, where M/M0 falls from 1 at 80 km to 0.999579 at 86 km (Table 8); we apply
that ratio (its effect on the number density is 4e-4 at most).

From 86 to 100 km the standard gives the kinetic temperature in *geometric* altitude Z:
isothermal 186.8673 K to 91 km, then an elliptical segment
T = Tc + A sqrt(1 - ((Z - 91 km)/a)^2), Tc = 263.1905 K, A = -76.3232 K, a = -19.9429 km
(Eqs. 27–29). Below the turbopause (~100 km) air is still well mixed, so we integrate
hydrostatic balance dP/dZ = -g(Z) M P / (R* T) with the 86 km mean molecular weight
instead of the standard's species-by-species diffusion; the result is within 1 % of the
standard's tabulated total number density at 90–100 km (tested), which matters for
nothing visible (the air above 86 km holds 7e-6 of the Rayleigh column).
"""

from __future__ import annotations

import numpy as np

from skymodel.errors import SkymodelInputError

#: Standard gravity, m s^-2.
G0 = 9.80665
#: Universal gas constant used by the 1976 standard, J K^-1 kmol^-1 (note: not CODATA).
R_STAR = 8.31432e3
#: Mean molecular weight of sea-level air, kg kmol^-1.
M0 = 28.9644
#: Boltzmann constant as defined in the standard, J K^-1.
K_BOLTZMANN = 1.380622e-23
#: Effective Earth radius used for geopotential altitude in the standard, m.
R0 = 6_356_766.0

# Layer bases: geopotential altitude (m), lapse rate (K/m), Table 4.
_H_B = np.array([0.0, 11_000.0, 20_000.0, 32_000.0, 47_000.0, 51_000.0, 71_000.0, 84_852.0])
_L_B = np.array([-0.0065, 0.0, 0.0010, 0.0028, 0.0, -0.0028, -0.0020, 0.0])
_T0 = 288.15
_P0 = 101_325.0

# Base temperature and pressure of every layer, from the closed-form layer equations.
_T_B = np.empty_like(_H_B)
_P_B = np.empty_like(_H_B)
_T_B[0], _P_B[0] = _T0, _P0
for _i in range(1, _H_B.size):
    _dh = _H_B[_i] - _H_B[_i - 1]
    _T_B[_i] = _T_B[_i - 1] + _L_B[_i - 1] * _dh
    if _L_B[_i - 1] == 0.0:
        _P_B[_i] = _P_B[_i - 1] * np.exp(-G0 * M0 * _dh / (R_STAR * _T_B[_i - 1]))
    else:
        _P_B[_i] = _P_B[_i - 1] * (_T_B[_i - 1] / _T_B[_i]) ** (G0 * M0 / (R_STAR * _L_B[_i - 1]))

#: Molecular-weight ratio M/M0 between 80 and 86 km, every 500 m (Table 8 of the standard).
_MRATIO_Z = np.arange(80_000.0, 86_001.0, 500.0)
_MRATIO = np.array([1.0, 0.999996, 0.999989, 0.999971, 0.999941, 0.999909, 0.999870,
                    0.999829, 0.999786, 0.999741, 0.999694, 0.999641, 0.999579])

Z_86 = 86_000.0
TOP_M = 100_000.0


def geopotential_altitude(z_m):
    """Geopotential altitude (m') of geometric altitude z (m): H = r0 z / (r0 + z)."""
    z = np.asarray(z_m, dtype=float)
    return R0 * z / (R0 + z)


def _lower(z):
    """Molecular-scale temperature and pressure for 0 <= z <= 86 km (geometric, m)."""
    h = geopotential_altitude(z)
    i = np.clip(np.searchsorted(_H_B, h, side="right") - 1, 0, _H_B.size - 2)
    tb, pb, lb, hb = _T_B[i], _P_B[i], _L_B[i], _H_B[i]
    tm = tb + lb * (h - hb)
    with np.errstate(divide="ignore", invalid="ignore"):
        p_grad = pb * (tb / tm) ** (G0 * M0 / (R_STAR * np.where(lb == 0, 1.0, lb)))
    p_iso = pb * np.exp(-G0 * M0 * (h - hb) / (R_STAR * tb))
    return tm, np.where(lb == 0.0, p_iso, p_grad)


def _upper_temperature(z):
    """Kinetic temperature (K) for 86–100 km geometric (Eqs. 25–29 of the standard)."""
    tc, a_k, a_m = 263.1905, -76.3232, -19_942.9
    ell = tc + a_k * np.sqrt(np.clip(1.0 - ((z - 91_000.0) / a_m) ** 2, 0.0, None))
    return np.where(z <= 91_000.0, 186.8673, ell)


# Pressure above 86 km on a fine grid, by integrating hydrostatic balance once at import.
_ZU = np.linspace(Z_86, TOP_M + 20_000.0, 1201)
_TU = _upper_temperature(_ZU)
_M86 = M0 * _MRATIO[-1]
_GU = G0 * (R0 / (R0 + _ZU)) ** 2
_integrand = _GU * _M86 / (R_STAR * _TU)
_cum = np.concatenate([[0.0], np.cumsum(0.5 * (_integrand[1:] + _integrand[:-1]) * np.diff(_ZU))])
_P86 = float(_lower(np.array(Z_86))[1])
_PU = _P86 * np.exp(-_cum)


def temperature(altitudes_m):
    """Kinetic temperature in K at geometric altitudes in metres (0..100 km; above is
    extrapolated with the 100 km formula)."""
    z = _check(altitudes_m)
    tm, _ = _lower(np.minimum(z, Z_86))
    ratio = np.interp(z, _MRATIO_Z, _MRATIO, left=1.0, right=_MRATIO[-1])
    return np.where(z <= Z_86, tm * ratio, _upper_temperature(z))


def pressure(altitudes_m):
    """Pressure in Pa at geometric altitudes in metres."""
    z = _check(altitudes_m)
    _, p_low = _lower(np.minimum(z, Z_86))
    p_up = np.exp(np.interp(z, _ZU, np.log(_PU)))
    return np.where(z <= Z_86, p_low, p_up)


def number_density(altitudes_m):
    """Total number density of air molecules, m^-3, n = P / (k T)."""
    return pressure(altitudes_m) / (K_BOLTZMANN * temperature(altitudes_m))


def _check(altitudes_m):
    z = np.asarray(altitudes_m, dtype=float)
    if np.any(~np.isfinite(z)) or np.any(z < -5_000.0) or np.any(z > TOP_M + 20_000.0):
        bad = z[~np.isfinite(z) | (z < -5_000.0) | (z > TOP_M + 20_000.0)].ravel()[0]
        raise SkymodelInputError("altitude_m", float(bad), "altitudes in [-5000, 120000] m")
    return z
