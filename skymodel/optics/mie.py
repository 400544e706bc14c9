r"""Lorentz–Mie scattering by a homogeneous sphere, vectorised in numpy.

This module computes the far-field optical properties of a homogeneous, isotropic sphere
illuminated by a plane wave: the Mie coefficients :math:`a_n, b_n`, the efficiencies
(extinction, scattering, absorption, radar backscatter), the asymmetry parameter, the
scattering amplitudes :math:`S_1, S_2` and the normalised phase function. Every function
is vectorised over the refractive index ``m`` and the size parameter ``x`` (which
broadcast against each other); the only Python loop runs over the series order ``n``,
with all particles advanced together at each order.

Conventions
-----------
* **Size parameter** :math:`x = 2\pi r\, n_\mathrm{med} / \lambda = k r` (dimensionless),
  with :math:`r` the sphere radius, :math:`\lambda` the vacuum wavelength and
  :math:`n_\mathrm{med}` the (real) refractive index of the surrounding medium.
* **Refractive index** :math:`m = n + i\kappa` is the index of the sphere *relative to
  the medium*, with :math:`\kappa \ge 0` for an absorbing sphere. This is the convention
  of Bohren & Huffman (1983, "Absorption and Scattering of Light by Small Particles",
  hereafter BH) with time dependence :math:`e^{-i\omega t}`. (``miepython`` and
  Wiscombe's MIEV0 use :math:`m = n - i\kappa`; pass ``numpy.conj`` of their index.)
  A negative imaginary part is rejected rather than silently conjugated.
* **Efficiencies** are cross sections divided by the geometric cross section
  :math:`\pi r^2`: :math:`Q = C / (\pi r^2)`. ``qback`` is BH's backscattering
  (radar) efficiency, :math:`Q_b = 4\pi\, (dC_\mathrm{sca}/d\Omega)(\theta=\pi) / (\pi r^2)`
  (BH Sec. 4.6), *not* a hemispheric back-scattered fraction.
* **Scattering amplitudes** :math:`S_1` (perpendicular) and :math:`S_2` (parallel) are
  BH's (Eq. 4.74), dimensionless, with the differential cross section for unpolarised
  incident light :math:`dC_\mathrm{sca}/d\Omega = (|S_1|^2 + |S_2|^2) / (2 k^2)`.
* **Phase function** :math:`p(\mu)`, :math:`\mu = \cos\theta` (:math:`\theta = 0` is
  forward scattering), in sr\ :sup:`-1`, normalised over the sphere of directions:
  :math:`\int_{4\pi} p\, d\Omega = 2\pi \int_{-1}^{1} p(\mu)\, d\mu = 1`.

The algorithm
-------------
The Mie coefficients (BH Eq. 4.88) are

.. math::

    a_n = \frac{[D_n(mx)/m + n/x]\,\psi_n(x) - \psi_{n-1}(x)}
               {[D_n(mx)/m + n/x]\,\xi_n(x) - \xi_{n-1}(x)}, \qquad
    b_n = \frac{[m D_n(mx) + n/x]\,\psi_n(x) - \psi_{n-1}(x)}
               {[m D_n(mx) + n/x]\,\xi_n(x) - \xi_{n-1}(x)},

with the Riccati–Bessel functions :math:`\psi_n(\rho) = \rho j_n(\rho)`,
:math:`\chi_n(\rho) = -\rho y_n(\rho)`, :math:`\xi_n = \psi_n - i\chi_n` and the
logarithmic derivative :math:`D_n(z) = \psi_n'(z)/\psi_n(z)`. Evaluated literally these
formulas cancel catastrophically for small ``x`` (numerator and denominator are
:math:`O(x)` while :math:`a_1 = O(x^3)`; with :math:`x = 10^{-6}` nothing survives) and,
for :math:`n > x`, need :math:`\psi_n(x)`, the *minimal* solution of its recurrence,
which the upward recurrence cannot deliver. We therefore rewrite them exactly in terms
of the Bessel-function ratios

.. math::

    r_n(z) = \psi_n(z) / \psi_{n-1}(z), \qquad
    D_n(z) = \frac{1}{r_n(z)} - \frac{n}{z} = \frac{n+1}{z} - r_{n+1}(z),

(the last form from the recurrence :math:`\psi_{n-1} + \psi_{n+1} = \frac{2n+1}{z}\psi_n`),
and use the Casoratian :math:`\psi_{n-1}\chi_n - \psi_n\chi_{n-1} = 1`. Dividing
numerator and denominator of :math:`a_n` by :math:`\psi_n \xi_n` gives

.. math::

    a_n = \frac{\psi_n^2 A_n}{\psi_n \xi_n A_n - i}, \qquad
    b_n = \frac{\psi_n^2 B_n}{\psi_n \xi_n B_n - i},

    A_n = \frac{D_n(mx)}{m} - D_n(x)
        = \frac{(n+1)(m^{-2} - 1)}{x} + r_{n+1}(x) - \frac{r_{n+1}(mx)}{m}, \qquad
    B_n = m D_n(mx) - D_n(x) = r_{n+1}(x) - m\, r_{n+1}(mx),

where :math:`\psi_n, \xi_n` are taken at :math:`x`. The large, cancelling
:math:`(n+1)/z` parts of the two logarithmic derivatives have been subtracted
analytically, so :math:`A_n` and :math:`B_n` carry full relative precision for any
``x``; the small-particle limit (:math:`a_1 \to -\tfrac{2i}{3}x^3\frac{m^2-1}{m^2+2}`,
BH Sec. 5.1) comes out of the same formulas, without the separate small-particle
expansion of Wiscombe (1979) that MIEV0 and miepython switch to for :math:`|m|x < 0.1`.

A further exact identity (expand :math:`\mathrm{Re}(a_n) = \mathrm{Re}(\psi_n^2 A_n
\overline{\mathrm{den}})/|\mathrm{den}|^2`) separates absorption from scattering term by term,

.. math::

    \mathrm{Re}(a_n) - |a_n|^2 = -\frac{\psi_n^2\, \mathrm{Im} A_n}{|\psi_n\xi_n A_n - i|^2},

and likewise for :math:`b_n`. We sum :math:`Q_\mathrm{abs}` from this positive-definite
form and :math:`Q_\mathrm{sca}` from :math:`|a_n|^2 + |b_n|^2`, and set
:math:`Q_\mathrm{ext} = Q_\mathrm{sca} + Q_\mathrm{abs}` (mathematically identical to BH
Eq. 4.62). This avoids the loss of all significant digits in
:math:`\sum \mathrm{Re}(a_n + b_n)` for small, weakly absorbing spheres and makes
:math:`Q_\mathrm{abs}` exactly zero for real ``m``.

The three sequences are computed as follows.

* :math:`r_n(z)` for ``z = x`` and ``z = mx``: **downward** recurrence
  :math:`r_n = z / (2n + 1 - z\, r_{n+1})`, started with :math:`r_{N+1} = 0`
  (Miller's algorithm; it is the recurrence :math:`D_{n-1} = n/z - 1/(D_n + n/z)` of
  BH and Wiscombe written for :math:`r_n = 1/(D_n + n/z)`). The arbitrary start adds a
  multiple of the other solution of the three-term recurrence. Above the turning point
  (:math:`n > |z|`) :math:`\psi_n` is the minimal solution, so running downwards that
  contamination shrinks at every step; below it, for real ``z``, the two solutions
  oscillate with comparable amplitude and the contamination neither grows nor decays,
  while for absorbing ``z`` it still decays, at the rate
  :math:`2\,\mathrm{Im}\arccos(n/z)` per order. Downward recurrence is therefore stable
  for every ``z``, and the start must be high enough that the contamination has died
  out by :math:`n_\mathrm{stop}`: :math:`N = \max(n_\mathrm{stop}, |z|) + 16 +
  8|z|^{1/3}` in general (several widths :math:`(|z|/2)^{1/3}` of the Airy transition
  region beyond :math:`|z|`), or the much lower order where the absorbing-case damping
  reaches :math:`e^{-40}` (see :func:`_start_order`). BH's BHMIE starts at
  :math:`\max(n_\mathrm{stop}, |mx|) + 15`, which we found too close for large real
  :math:`|mx|` (errors of 1e-3 in :math:`Q_\mathrm{ext}` at :math:`x \sim 10^3`);
  Wiscombe's MIEV0 instead evaluates the start from Lentz's (1976) continued fraction.
* :math:`\psi_n(x) = \psi_{n-1}(x)\, r_n(x)` upward from :math:`\psi_0 = \sin x`: a product
  of ratios, each accurate to rounding, so :math:`\psi_n` keeps full relative accuracy
  even where it is the minimal solution (:math:`n > x`), where the plain upward
  recurrence used by BHMIE/MIEV0 loses digits.
* :math:`\chi_n(x)` by the **upward** recurrence
  :math:`\chi_{n+1} = \frac{2n+1}{x}\chi_n - \chi_{n-1}` from :math:`\chi_0 = \cos x`,
  :math:`\chi_1 = \cos x / x + \sin x`; :math:`\chi_n` is the dominant solution, so the
  upward direction is stable for real ``x`` (as in BHMIE and MIEV0).

The series is truncated after Wiscombe's (1980)
:math:`n_\mathrm{stop} = \lceil x + 4.05 x^{1/3} + 2 \rceil` terms, per particle: at each
order only the particles that still need terms are advanced (the particles are sorted by
:math:`n_\mathrm{stop}`, so they form a shrinking prefix) and work arrays are chunked to
a fixed number of elements, so memory stays bounded for arrays of large spheres.

References
----------
* C. F. Bohren & D. R. Huffman (1983), *Absorption and Scattering of Light by Small
  Particles*, Wiley, ch. 4 and App. A (BHMIE).
* W. J. Wiscombe (1979), *Mie scattering calculations: advances in technique and fast,
  vector-speed computer codes*, NCAR/TN-140+STR (revised 1996).
* W. J. Wiscombe (1980), Improved Mie scattering algorithms, *Appl. Opt.* 19, 1505–1509.
* W. J. Lentz (1976), Generating Bessel functions in Mie scattering calculations using
  continued fractions, *Appl. Opt.* 15, 668–671.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from skymodel.errors import SkymodelInputError

__all__ = [
    "MieEfficiencies",
    "efficiencies",
    "mie_coefficients",
    "phase_function",
    "scattering_amplitudes",
    "wiscombe_nstop",
]

#: Upper bound on the number of (order x particle) elements held in one work table; the
#: particle axis is chunked so that ``n_orders * n_particles <= _WORK_ELEMENTS``
#: (2**20 elements = 16 MiB per complex table; a chunk holds ~5 such tables, twice that
#: when the coefficients are kept for the angular sums).
_WORK_ELEMENTS = 1 << 20

#: Largest number of (particle x angle) elements of one matrix product in the angular sums.
_ANGLE_ELEMENTS = 1 << 18

#: Series orders evaluated together (as 2-D arrays) once the recurrences are done, and
#: the cap on (orders x particles) of such a block (about 20 temporaries of this size).
_ORDER_BLOCK = 32
_BLOCK_ELEMENTS = 1 << 16


class MieEfficiencies(NamedTuple):
    r"""Mie efficiencies of a sphere; every field has shape ``broadcast(m, x).shape``.

    Attributes
    ----------
    qext : extinction efficiency :math:`Q_\mathrm{ext} = C_\mathrm{ext}/(\pi r^2)`.
    qsca : scattering efficiency :math:`Q_\mathrm{sca}
        = \frac{2}{x^2}\sum_n (2n+1)(|a_n|^2 + |b_n|^2)` (BH Eq. 4.61).
    qabs : absorption efficiency :math:`Q_\mathrm{ext} - Q_\mathrm{sca}` (exactly 0 for
        real ``m``; computed without cancellation, see the module docstring).
    qback : radar backscattering efficiency
        :math:`\frac{1}{x^2}|\sum_n (2n+1)(-1)^n (a_n - b_n)|^2`
        :math:`= 4\pi\, Q_\mathrm{sca}\, p(\mu=-1)`.
    g : asymmetry parameter :math:`\langle\cos\theta\rangle` (BH Sec. 4.5).
    """

    qext: np.ndarray
    qsca: np.ndarray
    qabs: np.ndarray
    qback: np.ndarray
    g: np.ndarray

    @property
    def single_scattering_albedo(self) -> np.ndarray:
        r""":math:`Q_\mathrm{sca} / Q_\mathrm{ext}` (1 for a non-absorbing sphere)."""
        return self.qsca / self.qext


# --------------------------------------------------------------------------------------
# Input handling
# --------------------------------------------------------------------------------------


def wiscombe_nstop(x) -> np.ndarray:
    r"""Number of series terms, Wiscombe's (1980) ``ceil(x + 4.05 x**(1/3) + 2)``.

    Beyond :math:`n \approx x` the coefficients decay faster than exponentially, and at
    this order they are of order 1e-7 or smaller. Measured by adding 30 more terms
    (``x = 1e-3 .. 1e4``): ``qext``, ``qsca`` and ``g`` change by < 1e-9 (relative), but
    ``qback`` by up to ~5e-5 and the phase function near 180 degrees by ~1e-6, since
    backscatter is a small sum of large terms of alternating sign.
    """
    x = np.asarray(x, dtype=float)
    return np.ceil(x + 4.05 * np.cbrt(x) + 2.0).astype(np.int64)


def _as_inputs(m, x):
    """Broadcast and validate ``m`` (complex) and ``x`` (real); return flat arrays and shape."""
    try:
        m_arr = np.asarray(m, dtype=complex)
    except (TypeError, ValueError):
        raise SkymodelInputError("m", m, "a complex refractive index n + ik (array-like)") from None
    try:
        x_arr = np.asarray(x, dtype=float)
    except (TypeError, ValueError):
        raise SkymodelInputError("x", x, "a real size parameter 2*pi*r/lambda > 0 (array-like)") from None
    if not np.all(np.isfinite(x_arr)) or np.any(x_arr <= 0.0):
        bad = x_arr[~(np.isfinite(x_arr) & (x_arr > 0.0))].ravel()[0]
        raise SkymodelInputError("x", float(bad), "finite size parameters x = 2*pi*r/lambda > 0")
    ok = np.isfinite(m_arr) & (m_arr.real >= 0.0) & (m_arr.imag >= 0.0) & (m_arr != 0.0)
    if not np.all(ok):
        bad = m_arr[~ok].ravel()[0]
        raise SkymodelInputError(
            "m", complex(bad),
            "a finite, non-zero refractive index n + ik with n >= 0 and k >= 0 (k > 0 absorbs; "
            "miepython's n - ik convention needs numpy.conj)")
    try:
        m_b, x_b = np.broadcast_arrays(m_arr, x_arr)
    except ValueError:
        raise SkymodelInputError("m, x", (m_arr.shape, x_arr.shape), "shapes that broadcast together") from None
    return m_b.ravel().copy(), x_b.ravel().copy(), m_b.shape


def _start_order(nstop: np.ndarray, z: np.ndarray) -> np.ndarray:
    r"""Order ``N`` at which the downward ratio recurrence for argument ``z`` starts (``r_{N+1} = 0``).

    The arbitrary start adds to :math:`\psi_n` a multiple of the other solution of the
    recurrence; running downwards, that contamination shrinks relative to
    :math:`\psi_n` by :math:`\exp(-2\,\mathrm{Im}\arccos(\nu/z))` per order
    (:math:`\nu = n + 1/2`; the Debye/WKB phase of the two solutions, principal branch,
    for ``Im z >= 0``). Two cases:

    * **General (conservative)**: for real ``z`` the rate vanishes for ``n < |z|`` (both
      solutions oscillate and errors neither grow nor decay), so the start must lie
      beyond the turning point ``n ~ |z|`` by several widths ``(|z|/2)**(1/3)`` of the Airy
      transition region: ``N = max(nstop, |z|) + 16 + 8 |z|**(1/3)``. BH's
      ``max(nstop, |mx|) + 15`` is too close for large real ``|mx|`` (started there, our
      recurrence gave errors of 1e-3 in Q_ext and 1e-1 in Q_back for ``m = 1.5, 2`` at
      ``x = 5e2 .. 2e4``); with ``8 |z|**(1/3)`` the results agree to the last bit with a
      start 4000 orders higher (``tests/test_mie.py`` keeps a check of this).
    * **Absorbing**: for ``Im z > 0`` the rate is positive already below ``|z|`` and
      increases with ``n``, so ``N = nstop + 16 + 40 / (2 |Im arccos(nstop/z)|)`` damps the
      start by ``e^-40`` before order ``nstop`` is reached. For a large, strongly
      absorbing sphere (``m = 1.5 + 10i``, ``x = 2e4``: ``|mx| = 2e5``) this starts the
      recurrence ~10 times lower than the general rule.

    The smaller of the two is used (it is never below ``nstop + 16``).
    """
    z = np.asarray(z, dtype=complex)
    z_abs = np.abs(z)
    general = np.maximum(nstop, z_abs) + 16.0 + 8.0 * np.cbrt(z_abs)
    with np.errstate(divide="ignore"):
        rate = 2.0 * np.abs(np.arccos((nstop + 0.5) / z).imag)
        absorbing = nstop + 16.0 + 40.0 / rate
    return np.minimum(general, absorbing).astype(np.int64) + 1


def _chunks(sizes_desc: np.ndarray, budget: int):
    """Split indices 0..P-1 (``sizes_desc`` non-increasing) so ``len * sizes[first] <= budget``."""
    p = sizes_desc.size
    i = 0
    while i < p:
        per = max(1, budget // max(int(sizes_desc[i]), 1))
        j = min(p, i + per)
        yield i, j
        i = j


# --------------------------------------------------------------------------------------
# Core: one chunk of particles sorted by nstop (descending)
# --------------------------------------------------------------------------------------


def _downward_ratios(z: np.ndarray, start: np.ndarray, n_use: int) -> np.ndarray:
    r"""Bessel ratios :math:`r_n(z) = \psi_n(z)/\psi_{n-1}(z)` for n = 1 .. ``n_use`` by
    downward recurrence, one start order per particle.

    Returns a table of shape ``(n_use + 1, P)`` (row ``n`` = order ``n``, row 0 unused)
    with ``z``'s dtype. The recurrence :math:`r_n = z/(2n+1 - z\,r_{n+1})` is the
    three-term recurrence :math:`\psi_{n-1} + \psi_{n+1} = \frac{2n+1}{z}\psi_n` divided
    by :math:`\psi_n`, run downwards (it is BH's/Wiscombe's
    :math:`D_{n-1} = n/z - 1/(D_n + n/z)` for :math:`D_n = 1/r_n - n/z`). Particle ``i``
    starts at ``start[i]`` with :math:`r_{N+1} = 0` (:func:`_start_order` says why that
    is far enough up). To keep the active particles a prefix of the arrays, a particle
    joins as soon as any later particle does (``suffix max`` of ``start``): starting
    higher than needed only adds damping orders. Rows are written for the active prefix
    only; the rest of the table stays zero.
    """
    p = z.size
    suffix_max = np.maximum.accumulate(start[::-1])[::-1]
    n_top = int(suffix_max[0])
    active = np.searchsorted(-suffix_max, -np.arange(n_top + 1), side="right")
    table = np.zeros((n_use + 1, p), dtype=z.dtype)
    state = np.zeros(p, dtype=z.dtype)  # r_{n+1} above the stored rows
    buf = np.empty(p, dtype=z.dtype)
    prev = state
    for n in range(n_top, 0, -1):
        k = int(active[n])
        zk = z[:k]
        t = np.multiply(zk, prev[:k], out=buf[:k])
        np.subtract(2.0 * n + 1.0, t, out=t)
        dst = table[n] if n <= n_use else state
        np.divide(zk, t, out=dst[:k])  # in place is fine: prev[:k] was consumed above
        prev = dst
    return table


def _series_chunk(m: np.ndarray, x: np.ndarray, nstop: np.ndarray, keep: bool):
    """Mie series for one chunk of particles (``nstop`` non-increasing).

    Returns the sums ``(s_sca, s_abs, s_back, s_g)`` and, if ``keep``, the coefficient
    tables ``a, b`` with shape ``(max(nstop), P)`` (row ``n - 1`` is order ``n``; zero
    beyond each particle's own ``nstop``). The sums are

    * ``s_sca  = sum (2n+1) (|a_n|^2 + |b_n|^2)``,
    * ``s_abs  = sum (2n+1) [(Re a_n - |a_n|^2) + (Re b_n - |b_n|^2)]``, from the
      positive-definite form ``-psi_n^2 Im(A_n) / |psi_n xi_n A_n - i|^2`` (module docstring),
    * ``s_back = sum (2n+1) (-1)^n (a_n - b_n)``,
    * ``s_g    = sum n(n+2)/(n+1) Re(a_n a*_{n+1} + b_n b*_{n+1})
      + (2n+1)/(n(n+1)) Re(a_n b_n*)`` (so that ``g = 4 s_g / (x^2 Q_sca)``).

    Only the recurrences are sequential in ``n``: the downward ratios
    (:func:`_downward_ratios`), ``psi_n(x)`` as a running product of ``r_n(x)`` and the
    upward ``chi_n(x)``. Everything else is evaluated on blocks of up to
    ``_ORDER_BLOCK`` orders at once, for the particles that still need the block's first
    order (a prefix, since ``nstop`` is sorted).
    """
    p = x.size
    n_max = int(nstop[0])
    z = m * x
    rx_tab = _downward_ratios(x, _start_order(nstop, x), n_max + 1)
    rz_tab = _downward_ratios(z, _start_order(nstop, z), n_max + 1)
    # number of particles that still need order n: a prefix because nstop is sorted
    active = np.searchsorted(-nstop, -np.arange(n_max + 2), side="right")

    # psi_n(x) = sin(x) prod_{j<=n} r_j(x): every factor is a ratio accurate to rounding,
    # so psi_n keeps full relative accuracy even where it is the minimal solution (n > x).
    # chi_n(x), the dominant solution, by the upward recurrence (stable for real x),
    # from chi_{-1} = -sin x, chi_0 = cos x (chi_full row j + 1 holds chi_j). Both are
    # filled only up to each particle's own nstop and are zero beyond, which makes a_n =
    # b_n = 0 there without masking and avoids the overflow of chi_n for n >> x.
    psi_tab = np.zeros((n_max + 1, p))
    chi_full = np.zeros((n_max + 2, p))
    chi_tab = chi_full[1:]
    inv_x = 1.0 / x
    psi_tab[0] = np.sin(x)
    chi_full[0] = -psi_tab[0]
    chi_tab[0] = np.cos(x)
    for n in range(1, n_max + 1):
        k = int(active[n])
        np.multiply(psi_tab[n - 1, :k], rx_tab[n, :k], out=psi_tab[n, :k])
        row = chi_tab[n, :k]
        np.multiply(inv_x[:k], chi_tab[n - 1, :k], out=row)
        row *= 2.0 * n - 1.0
        row -= chi_full[n - 1, :k]  # chi_{n-2}

    inv_m = 1.0 / m
    w = (inv_m * inv_m - 1.0) * inv_x  # (m^-2 - 1)/x; its Im part has full relative accuracy

    s_sca = np.zeros(p)
    s_abs = np.zeros(p)
    s_back = np.zeros(p, dtype=complex)
    s_g = np.zeros(p)
    a_last = np.zeros(p, dtype=complex)  # a_{n0-1}, b_{n0-1}: the previous block's last row
    b_last = np.zeros(p, dtype=complex)
    if keep:
        a_tab = np.zeros((n_max, p), dtype=complex)
        b_tab = np.zeros((n_max, p), dtype=complex)

    n0 = 1
    while n0 <= n_max:
        k = int(active[n0])
        n1 = min(n_max, n0 + max(1, min(_ORDER_BLOCK, _BLOCK_ELEMENTS // k)) - 1)  # orders n0..n1
        n = np.arange(n0, n1 + 1, dtype=float)[:, None]
        psi = psi_tab[n0:n1 + 1, :k]
        rx1 = rx_tab[n0 + 1:n1 + 2, :k]
        rz1 = rz_tab[n0 + 1:n1 + 2, :k]
        big_a = (n + 1.0) * w[:k] + rx1 - rz1 * inv_m[:k]   # D_n(mx)/m - D_n(x)
        big_b = rx1 - m[:k] * rz1                           # m D_n(mx) - D_n(x)
        psi2 = psi * psi
        psi_xi = np.empty(psi.shape, dtype=complex)        # psi_n xi_n = psi_n^2 - i psi_n chi_n
        psi_xi.real = psi2
        np.multiply(psi, chi_tab[n0:n1 + 1, :k], out=psi_xi.imag)
        np.negative(psi_xi.imag, out=psi_xi.imag)
        den_a = psi_xi * big_a
        den_a.imag -= 1.0
        den_b = psi_xi * big_b
        den_b.imag -= 1.0
        a = psi2 * big_a / den_a
        b = psi2 * big_b / den_b

        c = 2.0 * n + 1.0
        s_sca[:k] += (c * (a.real**2 + a.imag**2 + b.real**2 + b.imag**2)).sum(axis=0)
        absorb = big_a.imag / (den_a.real**2 + den_a.imag**2) + big_b.imag / (den_b.real**2 + den_b.imag**2)
        s_abs[:k] -= (c * psi2 * absorb).sum(axis=0)
        s_back[:k] += (np.where(n % 2 == 0, c, -c) * (a - b)).sum(axis=0)
        # g: Re(a_n b_n*) / order n, and the cross terms Re(a_n a_{n+1}* + b_n b_{n+1}*)
        # with weight n(n+2)/(n+1), inside the block and across its lower boundary
        ab = a.real * b.real + a.imag * b.imag
        cross = (a.real[:-1] * a.real[1:] + a.imag[:-1] * a.imag[1:]
                 + b.real[:-1] * b.real[1:] + b.imag[:-1] * b.imag[1:])
        edge = (a_last.real[:k] * a.real[0] + a_last.imag[:k] * a.imag[0]
                + b_last.real[:k] * b.real[0] + b_last.imag[:k] * b.imag[0])
        wn = n * (n + 2.0) / (n + 1.0)
        s_g[:k] += ((c / (n * (n + 1.0))) * ab).sum(axis=0) + (wn[:-1] * cross).sum(axis=0)
        s_g[:k] += (n0 - 1.0) * (n0 + 1.0) / n0 * edge
        a_last[:k] = a[-1]
        b_last[:k] = b[-1]
        if keep:
            a_tab[n0 - 1:n1, :k] = a
            b_tab[n0 - 1:n1, :k] = b
        n0 = n1 + 1

    # an index-matched sphere (m = 1) scatters nothing; the different rounding of the
    # complex r_n(mx) and the real r_n(x) would otherwise leave a ~1e-32 residue
    matched = m == 1.0
    if np.any(matched):
        for s in (s_sca, s_abs, s_back, s_g):
            s[matched] = 0.0
        if keep:
            a_tab[:, matched] = 0.0
            b_tab[:, matched] = 0.0
    if keep:
        return s_sca, s_abs, s_back, s_g, a_tab, b_tab
    return s_sca, s_abs, s_back, s_g


def _series_chunk_safe(m: np.ndarray, x: np.ndarray, nstop: np.ndarray, keep: bool):
    """:func:`_series_chunk` with a guard against an exactly singular recurrence step.

    For real arguments the downward step ``r_n = z / (2n + 1 - z r_{n+1})`` divides by
    zero if ``psi_{n-1}(z)`` happens to vanish to the last bit; the NaN that follows is
    confined to that particle. Rather than test every step (which would cost a third of
    the loop), such particles are recomputed with ``x`` moved by a few ulps, a change far
    below the accuracy of any physical input.
    """
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        res = list(_series_chunk(m, x, nstop, keep))
    for attempt in range(1, 4):
        bad = ~(np.isfinite(res[0]) & np.isfinite(res[1]) & np.isfinite(res[2]) & np.isfinite(res[3]))
        if keep:
            bad |= ~(np.all(np.isfinite(res[4]), axis=0) & np.all(np.isfinite(res[5]), axis=0))
        if not np.any(bad):
            break
        idx = np.flatnonzero(bad)
        x_nudged = x[idx] * (1.0 + 4.0 * attempt * np.finfo(float).eps)
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            sub = _series_chunk(m[idx], x_nudged, nstop[idx], keep)
        for full, part in zip(res, sub):
            full[..., idx] = part
    return tuple(res)


def _sorted(nstop: np.ndarray) -> np.ndarray:
    """Permutation that sorts particles by ``nstop``, largest first (stable)."""
    return np.argsort(-nstop, kind="stable")


# --------------------------------------------------------------------------------------
# Public API
# --------------------------------------------------------------------------------------


def mie_coefficients(m, x, n_max: int | None = None):
    """Mie coefficients :math:`a_n, b_n` (BH Eq. 4.53/4.88) for orders ``n = 1 .. n_max``.

    Parameters
    ----------
    m : complex array-like
        Refractive index of the sphere relative to the medium, ``n + ik`` with ``k >= 0``.
    x : float array-like
        Size parameter ``2 pi r n_medium / lambda`` (> 0). Broadcasts against ``m``.
    n_max : int, optional
        Number of orders returned. If omitted, ``max(wiscombe_nstop(x))`` orders are
        returned and each particle's coefficients beyond its *own* Wiscombe ``nstop``
        are set to zero (the truncated series that the other functions sum). If given,
        every particle gets exactly ``n_max`` computed orders; coefficients that
        underflow (far beyond ``x``) are returned as 0.

    Returns
    -------
    (a, b) : complex arrays of shape ``broadcast(m, x).shape + (n_max,)``; index ``[..., j]``
        is order ``n = j + 1``. Time convention ``exp(-i omega t)`` as in BH; for
        a non-absorbing sphere ``Re(a_n) = |a_n|**2``.
    """
    m_f, x_f, shape = _as_inputs(m, x)
    if n_max is None:
        nstop = wiscombe_nstop(x_f)
        n_out = int(nstop.max()) if nstop.size else 0
    else:
        if int(n_max) != n_max or n_max < 1:
            raise SkymodelInputError("n_max", n_max, "a positive integer number of orders")
        n_out = int(n_max)
        nstop = np.full(x_f.shape, n_out, dtype=np.int64)
    a_out = np.zeros((x_f.size, n_out), dtype=complex)
    b_out = np.zeros((x_f.size, n_out), dtype=complex)
    order = _sorted(nstop)
    ms, xs, ns = m_f[order], x_f[order], nstop[order]
    with np.errstate(over="ignore", invalid="ignore", under="ignore", divide="ignore"):
        for i, j in _chunks(ns + 2, _WORK_ELEMENTS):
            *_, a_tab, b_tab = _series_chunk(ms[i:j], xs[i:j], ns[i:j], keep=True)
            a_out[order[i:j], : a_tab.shape[0]] = a_tab.T
            b_out[order[i:j], : b_tab.shape[0]] = b_tab.T
    # far beyond x, psi_n**2 underflows and chi_n overflows: the coefficient is 0
    for arr in (a_out, b_out):
        arr[~np.isfinite(arr)] = 0.0
    return a_out.reshape(shape + (n_out,)), b_out.reshape(shape + (n_out,))


def efficiencies(m, x) -> MieEfficiencies:
    """Extinction, scattering, absorption and backscattering efficiencies and ``g``.

    Parameters
    ----------
    m : complex array-like
        Refractive index of the sphere relative to the medium, ``n + ik``, ``k >= 0``.
    x : float array-like
        Size parameter ``2 pi r n_medium / lambda`` (> 0); broadcasts against ``m``.

    Returns
    -------
    MieEfficiencies
        ``qext, qsca, qabs, qback, g`` as float arrays of shape ``broadcast(m, x).shape``
        (0-d arrays for scalar input). See :class:`MieEfficiencies` for definitions.

    Notes
    -----
    Each particle's series is summed to its own Wiscombe ``nstop``. The work per particle
    is ~``nstop`` orders plus the downward recurrence from its start order
    (:func:`_start_order`: ~``max(nstop, |m| x)`` for weak absorption, close to ``nstop``
    for strong absorption), all particles advancing together at each order; memory is
    bounded by chunking (``_WORK_ELEMENTS``). ``qext = qsca + qabs`` with both parts
    summed from positive-definite terms (module docstring), so the relative accuracy
    holds down to ``x = 1e-6`` and for tiny ``k``: against a 60-digit mpmath evaluation
    of the same truncated series the relative errors were ~1e-15 (1e-12 for
    ``m = 1.0001``, whose coefficients are proportional to ``m - 1``).
    """
    m_f, x_f, shape = _as_inputs(m, x)
    p = x_f.size
    nstop = wiscombe_nstop(x_f)
    s_sca = np.zeros(p)
    s_abs = np.zeros(p)
    s_back = np.zeros(p, dtype=complex)
    s_g = np.zeros(p)
    order = _sorted(nstop)
    ms, xs, ns = m_f[order], x_f[order], nstop[order]
    for i, j in _chunks(ns + 2, _WORK_ELEMENTS):
        res = _series_chunk_safe(ms[i:j], xs[i:j], ns[i:j], keep=False)
        idx = order[i:j]
        s_sca[idx], s_abs[idx], s_back[idx], s_g[idx] = res
    x2 = x_f * x_f
    qsca = 2.0 * s_sca / x2
    qabs = 2.0 * s_abs / x2
    qback = (s_back.real**2 + s_back.imag**2) / x2
    with np.errstate(invalid="ignore", divide="ignore"):
        g = np.where(s_sca > 0.0, 2.0 * s_g / s_sca, 0.0)  # (4/x^2) s_g / qsca
    out = (qsca + qabs, qsca, qabs, qback, g)
    return MieEfficiencies(*(q.reshape(shape) for q in out))


def _angular_tables(mu: np.ndarray, n_max: int):
    r"""Angular functions :math:`\pi_n(\mu), \tau_n(\mu)` for n = 1 .. n_max, shape ``(n_max, M)``.

    Upward recurrences (BH Eq. 4.47), stable for all ``mu`` in [-1, 1]:
    :math:`\pi_n = \frac{2n-1}{n-1}\mu\pi_{n-1} - \frac{n}{n-1}\pi_{n-2}`,
    :math:`\pi_0 = 0`, :math:`\pi_1 = 1`, and :math:`\tau_n = n\mu\pi_n - (n+1)\pi_{n-1}`.
    """
    pi_tab = np.empty((n_max, mu.size))
    tau_tab = np.empty((n_max, mu.size))
    pi_prev = np.zeros(mu.size)
    pi_n = np.ones(mu.size)
    for n in range(1, n_max + 1):
        if n > 1:
            pi_next = ((2.0 * n - 1.0) * mu * pi_n - n * pi_prev) / (n - 1.0)
            pi_prev, pi_n = pi_n, pi_next
        pi_tab[n - 1] = pi_n
        tau_tab[n - 1] = n * mu * pi_n - (n + 1.0) * pi_prev
    return pi_tab, tau_tab


def _as_mu(mu):
    try:
        mu_arr = np.asarray(mu, dtype=float)
    except (TypeError, ValueError):
        raise SkymodelInputError("mu", mu, "cosines of the scattering angle in [-1, 1]") from None
    if not np.all(np.isfinite(mu_arr) & (np.abs(mu_arr) <= 1.0)):
        bad = mu_arr[~(np.isfinite(mu_arr) & (np.abs(mu_arr) <= 1.0))].ravel()[0]
        raise SkymodelInputError("mu", float(bad), "cosines of the scattering angle in [-1, 1]")
    return mu_arr


def _angular_sums(m_f, x_f, mu_flat, intensity: bool):
    """Angular sums for flat inputs.

    Returns ``(S1, S2, s_sca)`` with ``S1, S2`` complex of shape ``(P, M)`` or, if
    ``intensity``, ``(|S1|^2 + |S2|^2, None, s_sca)`` (the intensity is formed chunk by
    chunk so the complex amplitudes are never held in full). ``s_sca`` is
    ``sum (2n+1)(|a_n|^2 + |b_n|^2)`` per particle.

    The sums over ``n`` are matrix products: with ``c_n = (2n+1)/(n(n+1))``,
    ``W = [Re c a; Im c a; Re c b; Im c b]`` (shape ``(4P, N)``) and the tables
    ``Pi[n, j] = pi_n(mu_j)``, ``T[n, j] = tau_n(mu_j)``, ``S1 = (W Pi)_a + (W T)_b`` and
    ``S2 = (W T)_a + (W Pi)_b`` (BH Eq. 4.74). Particles are chunked as in
    :func:`efficiencies` and angles so that neither the tables nor the products exceed
    ``_WORK_ELEMENTS`` / ``_ANGLE_ELEMENTS`` elements.
    """
    p, n_mu = x_f.size, mu_flat.size
    nstop = wiscombe_nstop(x_f)
    if intensity:
        out1, out2 = np.empty((p, n_mu)), None
    else:
        out1, out2 = np.empty((p, n_mu), dtype=complex), np.empty((p, n_mu), dtype=complex)
    s_sca = np.empty(p)
    order = _sorted(nstop)
    ms, xs, ns = m_f[order], x_f[order], nstop[order]
    for i, j in _chunks(ns + 2, _WORK_ELEMENTS):
        s_sca_c, _, _, _, a_tab, b_tab = _series_chunk_safe(ms[i:j], xs[i:j], ns[i:j], keep=True)
        idx = order[i:j]
        s_sca[idx] = s_sca_c
        n_max = a_tab.shape[0]
        n = np.arange(1, n_max + 1, dtype=float)
        coef = ((2.0 * n + 1.0) / (n * (n + 1.0)))[:, None]
        ca = coef * a_tab
        cb = coef * b_tab
        del a_tab, b_tab
        pc = j - i
        w = np.concatenate([ca.real.T, ca.imag.T, cb.real.T, cb.imag.T], axis=0)
        del ca, cb
        m_step = max(1, min(_WORK_ELEMENTS // n_max, _ANGLE_ELEMENTS // pc))
        for k0 in range(0, n_mu, m_step):
            k1 = min(n_mu, k0 + m_step)
            pi_tab, tau_tab = _angular_tables(mu_flat[k0:k1], n_max)
            wp = w @ pi_tab
            wt = w @ tau_tab
            s1_re = wp[:pc] + wt[2 * pc:3 * pc]
            s1_im = wp[pc:2 * pc] + wt[3 * pc:]
            s2_re = wt[:pc] + wp[2 * pc:3 * pc]
            s2_im = wt[pc:2 * pc] + wp[3 * pc:]
            if intensity:
                out1[idx, k0:k1] = s1_re**2 + s1_im**2 + s2_re**2 + s2_im**2
            else:
                out1[idx, k0:k1] = s1_re + 1j * s1_im
                out2[idx, k0:k1] = s2_re + 1j * s2_im
    return out1, out2, s_sca


def scattering_amplitudes(m, x, mu):
    r"""Scattering amplitudes :math:`S_1(\mu), S_2(\mu)` (BH Eq. 4.74), dimensionless.

    :math:`S_1 = \sum_n \frac{2n+1}{n(n+1)}(a_n\pi_n + b_n\tau_n)` (perpendicular
    polarisation), :math:`S_2 = \sum_n \frac{2n+1}{n(n+1)}(a_n\tau_n + b_n\pi_n)`
    (parallel), summed to Wiscombe's ``nstop``. Forward,
    :math:`S_1(1) = S_2(1) = \sum_n \frac{2n+1}{2}(a_n + b_n)` and the optical theorem
    reads :math:`Q_\mathrm{ext} = \frac{4}{x^2}\mathrm{Re}\,S(1)`.

    Parameters
    ----------
    m, x : as in :func:`efficiencies` (broadcast together).
    mu : float array-like
        Cosines of the scattering angle, in [-1, 1] (1 = forward).

    Returns
    -------
    (S1, S2) : complex arrays of shape ``broadcast(m, x).shape + mu.shape``, in BH's
        ``exp(-i omega t)`` convention (complex conjugates of the amplitudes of codes
        using ``m = n - ik``).
    """
    m_f, x_f, shape = _as_inputs(m, x)
    mu_arr = _as_mu(mu)
    s1, s2, _ = _angular_sums(m_f, x_f, mu_arr.ravel(), intensity=False)
    out_shape = shape + mu_arr.shape
    return s1.reshape(out_shape), s2.reshape(out_shape)


def phase_function(m, x, mu):
    r"""Unpolarised single-scattering phase function :math:`p(\mu)` in sr\ :sup:`-1`.

    .. math::

        p(\mu) = \frac{1}{C_\mathrm{sca}}\frac{dC_\mathrm{sca}}{d\Omega}
                = \frac{|S_1|^2 + |S_2|^2}{2 k^2} \frac{k^2}{\pi r^2 Q_\mathrm{sca}}
                = \frac{|S_1(\mu)|^2 + |S_2(\mu)|^2}{2\pi x^2 Q_\mathrm{sca}}
                = \frac{|S_1|^2 + |S_2|^2}{4\pi \sum_n (2n+1)(|a_n|^2 + |b_n|^2)},

    normalised so that :math:`2\pi\int_{-1}^{1} p(\mu)\, d\mu = 1` (an isotropic
    scatterer has :math:`p = 1/(4\pi)`). The last form, with the same truncated
    coefficients as the amplitudes, makes the normalisation exact up to rounding:
    :math:`|S_1|^2 + |S_2|^2` is a polynomial of degree ``2 nstop`` in ``mu``, so a
    Gauss–Legendre rule with ``nstop + 1`` nodes or more integrates it exactly.

    Parameters
    ----------
    m, x : as in :func:`efficiencies`; ``m`` must differ from 1 (a sphere that does not
        scatter has no phase function).
    mu : float array-like
        Cosines of the scattering angle, in [-1, 1] (1 = forward).

    Returns
    -------
    float array of shape ``broadcast(m, x).shape + mu.shape``.

    Notes
    -----
    The forward peak has angular width ~``1/x`` (in ``mu``: ``1 - mu ~ 1/(2 x**2)``);
    sample it accordingly when integrating numerically. Work is chunked over particles
    and angles (``_WORK_ELEMENTS``, ``_ANGLE_ELEMENTS``).
    """
    m_f, x_f, shape = _as_inputs(m, x)
    mu_arr = _as_mu(mu)
    inten, _, s_sca = _angular_sums(m_f, x_f, mu_arr.ravel(), intensity=True)
    if np.any(s_sca <= 0.0):
        bad = np.flatnonzero(s_sca <= 0.0)[0]
        raise SkymodelInputError(
            "m, x", (complex(m_f[bad]), float(x_f[bad])),
            "a sphere that scatters (m != 1 and x large enough that Q_sca does not underflow)")
    p = inten / (4.0 * np.pi * s_sca[:, None])
    return p.reshape(shape + mu_arr.shape)
