"""The deterministic spectral ray marcher: radiance arriving at an observer from any set
of directions, with single scattering under the Earth's shadow, multiple scattering,
ground reflection and (for images) the attenuated, limb-darkened sun.

For a view ray from the observer O in direction v (looking along v) the radiance is

    L(O, v) = integral over the ray of T(O, x) [J_1(x, v) + J_ms(x, v)] dt
              + T(O, G) (albedo / pi) E_ground(G)             (if the ray meets the ground)

* T is the transmittance of the true extinction (Rayleigh + ozone + aerosol);
* J_1 = E_sun T_sun(x) V(x) [sigma_R(x) p_R(v.s) + sum_r sigma_a,r(x) p_a,r(v.s)] is
  single scattering of sunlight: E_sun the top-of-atmosphere solar irradiance, T_sun the
  transmittance toward the sun and V the visible fraction of the solar disc (0 in the
  Earth's shadow) from :mod:`skymodel.render.sun_transmittance`; v.s is the cosine of
  the scattering angle, constant along a ray because the sun is a parallel beam;
* J_ms is the source of light scattered two or more times, from the order-by-order
  solution of :mod:`skymodel.render.multiple_scattering`, looked up at every point with
  that point's own altitude, local view angles and sun angle; it is integrated with the
  delta-M scaled transmittance for consistency with the solver. Because J_ms / E_sun is
  smooth in wavelength it is solved at a few wavelengths, interpolated, and multiplied
  by the solar spectrum on the full grid;
* E_ground = direct sun (E_sun T_sun V cos) + diffuse sky irradiance from the solver;
* the peak aureole: sunlight scattered two or more times inside the aerosols' truncated
  forward peaks, which delta-M leaves out of the solver, added per point of the ray in
  the small-angle approximation (:mod:`skymodel.render.aureole`,
  ``MarchSettings.peak_aureole``); it is counted in ``multiple``;
* the first scattering's capped phase functions spread by the cut peak's turns on its sun and
  view paths (:func:`peak_spread_table`, ``MarchSettings.peak_spread``), which the delta-M
  first scattering counts as not turned; counted in ``multiple`` with the aureole;
* near a low sun the delta-M beam of the first scattering and the ground below (T_sun with
  the scaled extinction) carries the cut peak's light along its own, bent paths, not the
  straight sun path (:mod:`skymodel.render.peak_paths`, ``MarchSettings.peak_paths``); the
  solver and the peak aureole keep the straight path.

The components of :class:`SkyRadiance`: ``single`` is true single scattering (J_1 seen
through the true extinction, full phase functions: exactly what an ``orders=1`` render
gives) and ``ground`` the directly lit ground seen through the true extinction. The
solver works with delta-M: its first order is the phase function outside the truncated
forward peak seen through the scaled extinction, so the total counts the first
scattering that way (:meth:`SkyMarcher._delta_m_first_scattering`) and the direct sun on
the ground through the scaled extinction as well; the (non-negative) excess of those over
``single`` and ``ground`` is counted in ``multiple``, together with J_ms, the solver's
ground light and the peak aureole. The total does not depend on this split.

With ``exact`` every component is evaluated for every direction at every wavelength.
Otherwise the components are marched once on a grid of view directions (zenith angle x
azimuth from the sun, split at the observer's horizon so the sky/ground edge stays sharp,
crowded toward it) and interpolated bilinearly, except within ``sun_exact_deg`` of the sun
(the aureole), where every direction is marched exactly; :mod:`skymodel.render.skyview`
resamples the same grid to environment images.

The observer stands on the z axis, so a view ray's samples, the medium along them and the
transmittance back to the observer depend only on the ray's zenith angle: the direction
grid's rows (rings of equal zenith angle) share them, and per direction only what depends
on the sun is computed (the transmittance toward the sun at each sample, the phase
functions, the multiple-scattering source, the peak aureole); single scattering is a sum
of column integrals, one per scatterer, times its phase function (:meth:`SkyMarcher._march`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np

from skymodel.errors import SkymodelInputError, check_finite, check_range
from skymodel.numerics import linear_interp_matrix
from skymodel.optics.profile import LayeredProfile, OpticalProfile
from skymodel.render.medium import (delta_m_cone_deg, evaluate_many, factor_medium, march_samples, samples_by_depth,
                                    step_transmittance)
from skymodel.render.multiple_scattering import MultipleScatteringField, solve_multiple_scattering
from skymodel.render.peak_paths import add_peak_paths
from skymodel.render.rays import altitude_along, atmosphere_segment, sun_direction
from skymodel.render.solver_spectrum import SolverSpectrumMap
from skymodel.render.sun_transmittance import SunTransmittance
from skymodel.render.threads import SOLVER_THREADS
from skymodel.render.threads import in_threads as _in_threads
from skymodel.scene import parameter

#: Highest observer altitude, metres (the registry's bound: skymodel.scene).
MAX_OBSERVER_ALTITUDE_M = parameter("observer_altitude").maximum
#: Threads marching the direction grid's pieces of rings (:meth:`SkyMarcher._build_grid`) and
#: other directions' chunks (:meth:`SkyMarcher.exact_in_threads`).
MARCH_THREADS = SOLVER_THREADS  # the same cores (its own name: bench_warm_march.py varies it alone)
#: Directions marched at once by all the threads together: at most ~0.45 GB of working
#: arrays at 81 wavelengths and 64 view steps (MarchSettings.chunk, 2048, would be ~0.9 GB);
#: up to 1.5 times that where :meth:`SkyMarcher._exact` pads rings of equal zenith angle.
MARCH_PIECE = 1024
#: Largest peak optical depth (sun path + view path) the aureole table covers; beyond
#: it the light is spread over tens of degrees and the table's last column is used.
AUREOLE_MAX_PEAK_TAU = 30.0
#: The peak-aureole table's grid (:func:`peak_aureole_table`; the peak-spread table shares it):
#: angles from the sun, 0 to ``aureole.THETA_MAX_RAD``, and peak optical depths, 0 then geometric.
AUREOLE_TABLE_ANGLES = 601
AUREOLE_TABLE_DEPTHS = 48

#: steps of the fine march that places the view rays' steps by optical depth
#: (``MarchSettings.view_depth_share``; 256 and 1024 give the same sky to 0.01 %)
_FINE_VIEW_STEPS = 256


#: Wavelengths (nm) where the colour matching functions are large: a solver with
#: ``MarchSettings.ms_wavelength_outer_step_nm`` keeps its finer step inside them
#: (:func:`solver_wavelengths`; docs/accuracy.md, "The solver's wavelengths").
EYE_BAND_NM = (440.0, 660.0)


@dataclass(frozen=True)
class MarchSettings:
    """Every accuracy knob of the marcher (the quality presets pick values for them)."""

    view_steps: int = 64  # quadrature nodes along each view ray
    # share of the view ray's steps placed by optical depth, the rest by the quadratic map
    # (skymodel.render.medium.samples_by_depth; 0 = the map alone, the steps before 2026-11-27)
    view_depth_share: float = 0.5
    orders: int | None = None  # highest scattering order; None = until `order_tolerance`
    max_orders: int = 20
    order_tolerance: float = 1e-3  # stop when an order adds less than this share
    ms_wavelength_step_nm: float = 20.0  # spacing of the wavelengths the solver uses (inside ms_fine_band_nm)
    # spacing of the solver's wavelengths outside ms_fine_band_nm, where the colour matching
    # functions are small (solver_wavelengths); 0 = ms_wavelength_step_nm everywhere
    ms_wavelength_outer_step_nm: float = 0.0
    ms_fine_band_nm: tuple[float, float] = EYE_BAND_NM
    table_altitudes: int = 24
    table_mu: int = 32
    # of the table_mu / 2 zenith nodes of each hemisphere, this many within table_mu_horizon_deg of
    # the horizon (a composite Gauss-Legendre rule, multiple_scattering.zenith_nodes); 0 = plain
    table_mu_horizon_nodes: int = 0
    table_mu_horizon_deg: float = 4.0
    table_phi: int = 12
    table_mus: int = 24
    table_steps: int = 48
    sun_table_altitudes: int = 96
    sun_table_x: int = 192
    sun_table_steps: int = 160
    exact: bool = False  # True: evaluate every direction (no direction grid)
    grid_zenith: int = 96  # direction grid: zenith nodes above the horizon (crowded toward it)
    grid_zenith_ground: int = 32  # ... and below it
    grid_azimuth: int = 61  # azimuth-from-the-sun nodes over 0..180 degrees
    sun_exact_deg: float = 8.0  # directions this close to the sun are evaluated exactly
    # Half-angle of the forward-peak cone that delta-M cuts from the aerosol phase functions
    # in the multiple-scattering part (the peak aureole puts back what is cut). 12 degrees
    # suits a sharp peak (coarse dust) without peak_spread: a narrower cone then puts the
    # views at its own angle from the sun several % too bright (the first scattering's
    # capped phase, not spread by the peak's turns); with the spread, final and reference
    # cut every peak at 6 degrees (the sunward horizon at a setting sun in dust: 12 degrees
    # leaves it up to 16 % dark; docs/accuracy.md, notebooks/sunward_zero).
    delta_m_cutoff_deg: float = 12.0
    # The narrower cone for a mild forward peak (most aerosol types: skymodel.render.medium.
    # delta_m_cone_deg; with table_phi >= 12 only); 0 = always delta_m_cutoff_deg
    delta_m_mild_cutoff_deg: float = 6.0
    spherical_orders: int = 2  # transports with each point's own sun angle (0 = independent columns)
    spherical_tail: bool = False  # orders after spherical_orders take the last order's spherical correction
    spherical_probe_step_nm: float = 100.0  # wavelength spacing of the spherical correction (orders >= 2)
    # the spherical correction (orders >= 2) formed on every other azimuth node and read back
    # linearly (an even table_phi; multiple_scattering._SphericalTransport)
    spherical_coarse_phi: bool = False
    # the scattering orders from this one on (3 or later), except those spherically corrected
    # (spherical_orders), solved on every other azimuth node and their sum read back linearly
    # (an even table_phi; 0 = none; multiple_scattering.CoarseOrders)
    coarse_phi_from_order: int = 0
    peak_aureole: bool = True  # add the light scattered 2+ times in the cut forward peaks (skymodel.render.aureole)
    # spread the first scattering's capped phase functions by the cut peak's turns on the sun and
    # view paths (marcher.peak_spread_table; with peak_aureole)
    peak_spread: bool = True
    peak_diffuse: bool = False  # scatter the diffuse light near the horizon in the cut peaks (skymodel.render.peak_diffuse)
    peak_paths: bool = True  # delta-M's sun beam near a low sun with the cut peak's light on bent paths (skymodel.render.peak_paths)
    source_by_scattering: bool = True  # read J between altitude nodes as sigma_s(h) J/sigma_s (multiple_scattering.source_at)
    chunk: int = 2048  # directions per batch (memory ~ chunk * view_steps * n_wl * 8 B * 6)
    earth_shadow: bool = True  # False: the planet blocks no sunlight (for measuring the shadow's effect)

    @property
    def halves_azimuths(self) -> bool:
        """Whether some of the solve runs on every other azimuth node (spherical_coarse_phi or
        coarse_phi_from_order): table_phi must then be even."""
        return bool(self.spherical_coarse_phi or self.coarse_phi_from_order)

    def __post_init__(self):
        # checked when the settings are made, before any table or solve
        if not 0.0 <= float(self.view_depth_share) <= 0.95:
            raise SkymodelInputError("view_depth_share", self.view_depth_share, "a number in [0, 0.95]")
        if self.table_mu_horizon_nodes and not 0 < int(self.table_mu_horizon_nodes) < int(self.table_mu) // 2:
            raise SkymodelInputError("table_mu_horizon_nodes", self.table_mu_horizon_nodes,
                                     f"0 or an integer in [1, {int(self.table_mu) // 2 - 1}] (table_mu / 2 - 1)")
        if self.coarse_phi_from_order and not int(self.coarse_phi_from_order) >= 3:
            raise SkymodelInputError("coarse_phi_from_order", self.coarse_phi_from_order,
                                     "0 or a scattering order of 3 or more")
        if self.halves_azimuths and int(self.table_phi) % 2:
            raise SkymodelInputError("table_phi", self.table_phi, "an even count with spherical_coarse_phi or "
                                     "coarse_phi_from_order (work on every other azimuth node)")
        if not float(self.ms_wavelength_outer_step_nm) >= 0.0:
            raise SkymodelInputError("ms_wavelength_outer_step_nm", self.ms_wavelength_outer_step_nm,
                                     "0 (the inner spacing everywhere) or a spacing in nm")
        band = tuple(float(v) for v in self.ms_fine_band_nm)
        if len(band) != 2 or not band[0] < band[1]:
            raise SkymodelInputError("ms_fine_band_nm", self.ms_fine_band_nm,
                                     "(low, high) wavelengths in nm, low < high")
        if self.table_mu_horizon_nodes and not 0.0 < float(self.table_mu_horizon_deg) < 90.0:
            raise SkymodelInputError("table_mu_horizon_deg", self.table_mu_horizon_deg, "degrees in (0, 90)")


@dataclass
class SkyRadiance:
    """Spectral radiance (W m^-2 sr^-1 nm^-1) for each direction, split by origin."""

    wavelengths_nm: np.ndarray
    directions: np.ndarray  # (N, 3)
    single: np.ndarray  # (N, n_wl) light scattered once in the air
    multiple: np.ndarray  # (N, n_wl) light scattered twice or more (incl. via the ground)
    ground: np.ndarray  # (N, n_wl) ground reflection seen directly
    sun_irradiance: np.ndarray  # (n_wl,) direct solar irradiance at the observer, W m^-2 nm^-1
    info: dict = field(default_factory=dict)

    @property
    def radiance(self) -> np.ndarray:
        return self.single + self.multiple + self.ground


def profile_at_wavelengths(profile, wavelengths_nm):
    """The same medium on another wavelength grid (linear interpolation in wavelength)."""
    dst = np.asarray(wavelengths_nm, dtype=float)
    w = linear_interp_matrix(profile.wavelengths_nm, dst)

    def tr(a):
        return np.asarray(a) @ w

    return replace(profile, wavelengths_nm=dst, rayleigh_depolarization=tr(profile.rayleigh_depolarization),
                   aerosol_phase=tr(profile.aerosol_phase), ground_albedo=tr(profile.ground_albedo),
                   solar_irradiance=tr(profile.solar_irradiance), rayleigh_scattering=tr(profile.rayleigh_scattering),
                   ozone_absorption=tr(profile.ozone_absorption),
                   aerosol_scattering_by_regime=tr(profile.aerosol_scattering_by_regime),
                   aerosol_absorption=tr(profile.aerosol_absorption))


def solver_wavelengths(wavelengths_nm, step_nm: float, outer_step_nm: float = 0.0,
                       fine_band_nm: tuple[float, float] = EYE_BAND_NM) -> np.ndarray:
    """Wavelengths for the multiple-scattering solver (nm): about every ``step_nm`` across
    the grid, always including its ends, never more than the grid itself. With an
    ``outer_step_nm`` larger than ``step_nm``, ``step_nm`` holds inside ``fine_band_nm`` (its
    edges among the wavelengths) and ``outer_step_nm`` outside it, where the colour matching
    functions are small (``final``: 10 nm over 440-660 nm and 20 nm beyond, 32 solver
    wavelengths for 380-780 nm instead of 41; docs/accuracy.md, "The solver's wavelengths")."""
    wl = np.asarray(wavelengths_nm, float)
    if wl.size <= 2 or step_nm <= 0:
        return wl
    lo, hi = float(wl.min()), float(wl.max())
    if outer_step_nm > step_nm:
        band_lo, band_hi = max(float(fine_band_nm[0]), lo), min(float(fine_band_nm[1]), hi)
        if band_lo >= band_hi:  # the band outside the grid: the outer spacing throughout
            pieces = [(lo, hi, outer_step_nm)]
        else:
            pieces = [(lo, band_lo, outer_step_nm), (band_lo, band_hi, step_nm), (band_hi, hi, outer_step_nm)]
    else:
        pieces = [(lo, hi, step_nm)]
    out = np.unique(np.concatenate([np.linspace(a, b, int(np.ceil((b - a) / st)) + 1)
                                    for a, b, st in pieces if b > a] or [np.array([lo])]))
    return wl if out.size >= wl.size else out


def settings_solver_wavelengths(wavelengths_nm, settings: MarchSettings) -> np.ndarray:
    """:func:`solver_wavelengths` with the spacings of ``settings`` (nm)."""
    return solver_wavelengths(wavelengths_nm, settings.ms_wavelength_step_nm, settings.ms_wavelength_outer_step_nm,
                              settings.ms_fine_band_nm)


def optics_key(profile, settings: MarchSettings) -> str:
    """A hash (hex SHA-256) of everything a :class:`SkySolution` depends on: every array and
    number of the optical profile except the solar spectrum (the solution is per unit solar
    irradiance, so the Earth-sun distance does not enter) and its metadata, plus the march
    settings. Two profiles with the same key share one multiple-scattering solve."""
    import dataclasses
    import hashlib

    h = hashlib.sha256(type(profile).__name__.encode())
    for f in dataclasses.fields(profile):
        if f.name in ("solar_irradiance", "metadata"):
            continue
        v = getattr(profile, f.name)
        h.update(f.name.encode())
        if isinstance(v, np.ndarray):
            a = np.ascontiguousarray(v)
            h.update(str((a.dtype.str, a.shape)).encode())
            h.update(a.tobytes())
        else:
            h.update(repr(v).encode())
    h.update(repr(settings).encode())
    return h.hexdigest()


@dataclass
class SkySolution:
    """What a sky costs before its sun is placed: the factored media, the sun
    transmittance table, the multiple-scattering field (its table spans every sun
    elevation, :func:`~skymodel.render.multiple_scattering.sun_elevation_nodes`) and the
    peak-aureole table. None of it depends on the sun's elevation or azimuth (the azimuth
    only rotates the sky about the zenith), on the observer's altitude, or on the solar
    spectrum's scale: one solution serves every frame of a sequence whose optical profile
    is the same (:func:`optics_key`). Build it with :func:`solve_sky`; pass it to
    :class:`SkyMarcher` (``solution=``)."""

    key: str
    settings: MarchSettings
    medium: object
    medium_ms: object
    sun_table: SunTransmittance
    field: MultipleScatteringField
    to_full: SolverSpectrumMap  # the solver's spectra -> the profile's wavelengths
    aureole: tuple | None
    timings: dict
    peak_spread: np.ndarray | None = None  # (R, n_theta, n_tau, W) float32: peak_spread_table


def solve_sky(profile, settings: MarchSettings | None = None, progress=None) -> SkySolution:
    """The sun-independent part of a sky (:class:`SkySolution`) for ``profile``: the
    tables and the multiple-scattering solve, about 80 % of a single ``final`` render."""
    if not isinstance(profile, (OpticalProfile, LayeredProfile)):
        raise TypeError("profile must be an OpticalProfile or LayeredProfile")
    s = settings or MarchSettings()
    t_start = time.perf_counter()
    R, top = profile.planet_radius_m, profile.top_altitude_m
    cone = delta_m_cone_deg(profile, s.delta_m_cutoff_deg, s.delta_m_mild_cutoff_deg, table_phi=s.table_phi)
    medium = factor_medium(profile, cone)
    # multiple scattering runs at the solver wavelengths, per unit solar irradiance
    wl_ms = settings_solver_wavelengths(profile.wavelengths_nm, s)
    prof_ms = profile_at_wavelengths(profile, wl_ms)
    prof_ms = replace(prof_ms, solar_irradiance=np.ones_like(wl_ms))
    medium_ms = factor_medium(prof_ms, cone)
    # one table serves all: medium 0 = true extinction on the full grid, medium 1 =
    # delta-M scaled extinction at the solver wavelengths, medium 2 = the same on the full grid
    sun_table = SunTransmittance([medium.extinction, medium_ms.extinction_scaled, medium.extinction_scaled], R,
                                 top, s.sun_table_altitudes, s.sun_table_x, s.sun_table_steps,
                                 earth_shadow=s.earth_shadow)
    if s.peak_paths:
        add_peak_paths(sun_table, profile, medium, cone)
    timings = {"tables_s": time.perf_counter() - t_start}
    t1 = time.perf_counter()
    ms_field: MultipleScatteringField = solve_multiple_scattering(
        prof_ms, medium_ms, sun_table, n_altitudes=s.table_altitudes, n_mu=s.table_mu,
        n_phi=s.table_phi, n_mus=s.table_mus, n_steps=s.table_steps, orders=s.orders,
        max_orders=s.max_orders, tolerance=s.order_tolerance, spherical_orders=s.spherical_orders,
        spherical_tail=s.spherical_tail, spherical_probe_step_nm=s.spherical_probe_step_nm, peak_diffuse=s.peak_diffuse,
        source_by_scattering=s.source_by_scattering, mu_horizon_deg=s.table_mu_horizon_deg,
        mu_horizon_nodes=s.table_mu_horizon_nodes, spherical_coarse_phi=s.spherical_coarse_phi,
        coarse_phi_from_order=s.coarse_phi_from_order, progress=progress)
    to_full = SolverSpectrumMap.for_profile(wl_ms, profile)
    shape = peak_shape(profile, medium, cone, top) if (s.peak_aureole and ms_field.orders > 1) else None
    aureole = peak_aureole_table(profile, medium, cone, top, shape) if shape is not None else None
    spread = (peak_spread_table(profile, medium, cone, top, aureole[0], aureole[1], shape)
              if (aureole is not None and s.peak_spread) else None)
    timings["multiple_scattering_s"] = time.perf_counter() - t1
    return SkySolution(optics_key(profile, s), s, medium, medium_ms, sun_table, ms_field, to_full, aureole, timings,
                       spread)


def peak_aureole_table(profile, medium, delta_m_cutoff_deg: float, top_altitude_m: float, shape=None):
    """Table of the peak light that delta-M leaves out (:mod:`skymodel.render.aureole`):
    (theta grid in radians, peak optical depth grid, table (n_theta, n_tau, n_wl) in
    sr^-1), or None when the aerosols have no truncated peak. ``shape``: the medium's
    :func:`peak_shape`, when the caller has it."""
    from skymodel.render.aureole import THETA_MAX_RAD

    shape = shape or peak_shape(profile, medium, delta_m_cutoff_deg, top_altitude_m)
    if shape is None:
        return None
    machine, q, qk = shape
    theta = np.linspace(0.0, THETA_MAX_RAD, AUREOLE_TABLE_ANGLES)
    tau = np.concatenate([[0.0], np.geomspace(0.005, AUREOLE_MAX_PEAK_TAU, AUREOLE_TABLE_DEPTHS - 1)])
    return theta, tau, machine.correction_table(q, tau, theta, qk=qk)


def peak_shape(profile, medium, delta_m_cutoff_deg: float, top_altitude_m: float):
    """The cut peak the aureole and the peak spread turn light by, once per medium:
    ``(machine, q, qk)``, a :class:`~skymodel.render.aureole.PeakAureole`, the normalised
    shape q (n, W) on its angle grid (the regimes' cut peaks weighted by their column peak
    optical depth) and q's Hankel transform; None when no aerosol has a cut peak."""
    from skymodel.numerics import trapezoid
    from skymodel.render.aureole import PeakAureole, peak_part

    if not np.any(medium.forward_fraction > 0):
        return None
    prof, med = profile, medium
    machine = PeakAureole()
    z = np.linspace(0.0, top_altitude_m, 2001)
    col = np.stack([trapezoid(lr.at(z), z, axis=0) for lr in med.aerosol]) * med.forward_fraction  # (R, W)
    total = col.sum(axis=0)
    peaks = peak_part(prof.aerosol_phase_angles_deg, prof.aerosol_phase, delta_m_cutoff_deg)
    q = np.zeros((machine.theta.size, prof.wavelengths_nm.size))
    for r in range(peaks.shape[0]):
        if np.any(col[r] > 0):
            share = np.where(total > 0, col[r] / np.where(total > 0, total, 1.0), 0.0)
            q += machine.shape_on_grid(prof.aerosol_phase_angles_deg, peaks[r]) * share
    return machine, q, machine.transform(q)


#: Angle from the sun (degrees) out to which :func:`peak_spread_table` spreads the first
#: scattering's capped phase functions; beyond it they vary too slowly for the peak's turns
#: (a few degrees) to change them (the table is 0 there).
PEAK_SPREAD_MAX_DEG = 40.0


def peak_spread_table(profile, medium, delta_m_cutoff_deg: float, top_altitude_m: float, theta_rad, tau_grid,
                      shape=None):
    """What the cut peak's turns do to the first scattering's non-peak part, per aerosol regime:
    (R, n_theta, n_tau, W) float32 in sr^-1 at the angles from the sun ``theta_rad`` and peak
    optical depths ``tau_grid`` (the peak-aureole table's, :func:`peak_aureole_table`: the
    marcher reads both tables at one index), or None when no aerosol has a cut peak.

    The delta-M first scattering (:meth:`SkyMarcher._delta_m_first_scattering`) counts the
    capped phase function p_cap = min(p, p(cutoff)) through the scaled extinction: the light
    the peak turns on the sun path and on the view path is taken to go on along them, as if it
    were not turned. It is turned, by a few degrees each time, so the pattern the observer sees
    is p_cap spread by those turns: p_cap * K_tau, with tau the peak optical depth of the sun
    path plus the view path (:meth:`~skymodel.render.aureole.PeakAureole.spread_table`). Where
    p_cap is smooth on the scale of the turns this changes nothing; at the cone's edge, where
    the flat top meets the steep fall of a sharp peak, it does: a 6-degree cone in desert dust
    (AOD 0.5, sun 5 degrees) puts the view 6 degrees above the sun 4 % above the Monte Carlo
    truth without the spread and 0.3 % with it (notebooks/sunward_zero). The pattern spread is
    g = p_cap - p_cap(:data:`PEAK_SPREAD_MAX_DEG`) within that angle of the sun, 0 beyond
    (:func:`peak_spread_floor`; a constant is not changed by the spread). The table holds the
    light the turns move, g * K_tau - exp(-tau) g; the marcher adds -(1 - exp(-tau)) g with g
    read at the view's own angle as its first scattering reads p_cap, so that where the turns
    take p_cap's Mie ripples away they cancel exactly (a table of angles every 0.1 degree
    cannot carry ripples of coarse dust's phase function 0.1-0.3 degree apart: holding the
    whole difference, it left rings of up to 7 % in the desert's blue, sun 20 degrees).
    ``shape``: the medium's :func:`peak_shape`, when the caller has it."""
    shape = shape or peak_shape(profile, medium, delta_m_cutoff_deg, top_altitude_m)
    if shape is None:
        return None
    machine, q, qk = shape
    angles = profile.aerosol_phase_angles_deg
    capped = medium.capped_phase  # (R, A, W): min(p, p(cutoff))
    floor = peak_spread_floor(profile, medium)
    inside = machine.theta[:, None] < np.radians(PEAK_SPREAD_MAX_DEG)
    out = np.zeros((capped.shape[0], np.size(theta_rad), np.size(tau_grid), capped.shape[2]), dtype=np.float32)
    for r in range(capped.shape[0]):
        if not np.any(medium.forward_fraction[r] > 0):
            continue
        g = np.where(inside, np.maximum(machine.on_grid(angles, capped[r]) - floor[r][None, :], 0.0), 0.0)
        out[r] = machine.spread_table(q, g, tau_grid, theta_rad, qk=qk)
    return out


def peak_spread_floor(profile, medium) -> np.ndarray:
    """Each aerosol regime's capped phase function at :data:`PEAK_SPREAD_MAX_DEG` from the sun,
    (R, W) sr^-1: what :func:`peak_spread_table` leaves unspread."""
    angles = np.asarray(profile.aerosol_phase_angles_deg, float)
    k = int(np.clip(np.searchsorted(angles, PEAK_SPREAD_MAX_DEG, side="right") - 1, 0, angles.size - 2))
    t = (PEAK_SPREAD_MAX_DEG - angles[k]) / (angles[k + 1] - angles[k])
    return medium.capped_phase[:, k] * (1.0 - t) + medium.capped_phase[:, k + 1] * t


class SkyMarcher:
    """Everything that depends on the medium and the sun but not on the view directions:
    build once, then ask for radiance in as many directions as needed.

    ``solution``: a :class:`SkySolution` of the same optical profile and settings (from
    :func:`solve_sky`) to reuse instead of solving again; the profile may differ from the
    solution's only in its solar spectrum (the date's Earth-sun distance)."""

    def __init__(self, profile, sun_elevation_deg: float, sun_azimuth_deg: float = 180.0,
                 observer_altitude_m: float = 0.0, settings: MarchSettings | None = None, progress=None,
                 solution: SkySolution | None = None):
        if not isinstance(profile, (OpticalProfile, LayeredProfile)):
            raise TypeError("profile must be an OpticalProfile or LayeredProfile")
        if solution is not None and settings is None:
            settings = solution.settings
        self.settings = s = settings or MarchSettings()
        self.profile = profile
        self.sun_elevation_deg = check_range("sun_elevation", sun_elevation_deg, -90.0, 90.0, "degrees")
        self.sun_azimuth_deg = float(sun_azimuth_deg) % 360.0
        self.observer_altitude_m = check_range("observer_altitude", observer_altitude_m, 0.0,
                                               MAX_OBSERVER_ALTITUDE_M, "metres")
        self.R = profile.planet_radius_m
        self.top = profile.top_altitude_m
        self.sun = sun_direction(self.sun_elevation_deg, self.sun_azimuth_deg)
        self.origin = np.array([0.0, 0.0, self.R + self.observer_altitude_m])
        if solution is None:
            solution = solve_sky(profile, s, progress=progress)
            self.timings = dict(solution.timings)
        else:
            if solution.key != optics_key(profile, s):
                raise ValueError("the SkySolution was solved for another optical profile or other settings")
            self.timings = {"tables_s": 0.0, "multiple_scattering_s": 0.0, "reused_solution": True}
        self.solution = solution
        self.medium, self.medium_ms, self.sun_table = solution.medium, solution.medium_ms, solution.sun_table
        self.field: MultipleScatteringField = solution.field
        self.to_full = solution.to_full
        self._aureole = solution.aureole
        # the peak-aureole table in float32 (:meth:`_aureole_gather`), made here: the
        # marcher's threads share it
        self._aureole_table32 = None if self._aureole is None else self._aureole[2].astype(np.float32)
        self._spread = solution.peak_spread  # float32 already
        self._spread_floor = None if self._spread is None else peak_spread_floor(profile, self.medium)
        t2 = time.perf_counter()
        self._grid = None if s.exact else self._build_grid()
        self.timings["direction_grid_s"] = time.perf_counter() - t2

    # ---------------------------------------------------------------- helpers
    def horizon_zenith_rad(self) -> float:
        """Zenith angle of the observer's geometric horizon (> pi/2 above the ground)."""
        return np.pi - np.arcsin(min(1.0, self.R / (self.R + self.observer_altitude_m)))

    # ---------------------------------------------------------------- direction grid
    def _grid_axes(self):
        """Zenith nodes on each side of the observer's horizon (crowded toward it) and
        azimuth-from-the-sun nodes in [0, pi]."""
        s = self.settings
        th = self.horizon_zenith_rad()
        eps = 1e-7
        u = np.linspace(0.0, 1.0, s.grid_zenith)
        sky = (th - eps) * (1.0 - (1.0 - u) ** 2)
        ug = np.linspace(0.0, 1.0, s.grid_zenith_ground)
        ground = th + eps + (np.pi - th - eps) * ug**2
        az = np.linspace(0.0, np.pi, s.grid_azimuth)
        return sky, ground, az

    def _dir_from_relative(self, zenith, rel_az):
        """Directions in the observer frame at zenith angle and azimuth relative to the sun
        (broadcast against each other)."""
        zenith, rel_az = np.broadcast_arrays(zenith, rel_az)
        az = np.radians(self.sun_azimuth_deg) + rel_az
        return np.stack([np.sin(zenith) * np.sin(az), np.sin(zenith) * np.cos(az), np.cos(zenith)], axis=-1)

    def _build_grid(self):
        sky, ground, az = self._grid_axes()
        images = []
        n = max(1, int(MARCH_THREADS))
        step = max(1, min(self.settings.chunk, MARCH_PIECE) // n // az.size)  # rings per piece
        for zen in (sky, ground):
            rings = self._dir_from_relative(zen[:, None], az[None, :])  # (n_zen, n_az, 3)
            parts = _in_threads(lambda i, rings=rings: self._march(rings[i:i + step]), range(0, zen.size, step), n)
            images.append(tuple(np.concatenate(c) for c in zip(*parts)))
        return sky, ground, az, images

    def exact_in_threads(self, d, threads: int | None = None):
        """``_exact`` over directions d (N, 3) in chunks, ``threads`` at a time (default
        :data:`MARCH_THREADS`; numpy releases the GIL in its array operations). Each thread
        takes chunks of ``min(settings.chunk, MARCH_PIECE) // threads`` directions, so the
        working memory stays that of one chunk of at most :data:`MARCH_PIECE` directions
        (the result does not depend on the chunks, ``tests/test_marcher.py``). Returns the
        list of the chunks' (single, multiple, ground), in order."""
        n = max(1, int(MARCH_THREADS if threads is None else threads))
        step = max(1, min(self.settings.chunk, MARCH_PIECE) // n)
        return _in_threads(lambda i: self._exact(d[i:i + step]), range(0, d.shape[0], step), n)

    def _grid_cells(self, d):
        """For directions d (N, 3): per side of the horizon (sky, ground) the mask of the
        directions on it and their bilinear cells in the direction grid (i, fz, j, fa)."""
        sky, ground, az, _ = self._grid
        zen = np.arccos(np.clip(d[:, 2], -1.0, 1.0))
        sun_h = self.sun[:2]
        dh = d[:, :2]
        nrm = np.linalg.norm(dh, axis=1) * np.linalg.norm(sun_h)
        c = np.where(nrm > 1e-12, (dh @ sun_h) / np.where(nrm > 1e-12, nrm, 1.0), 1.0)
        rel = np.arccos(np.clip(c, -1.0, 1.0))
        th = self.horizon_zenith_rad()
        cells = []
        for mask, axis in ((zen < th, sky), (zen >= th, ground)):
            z = np.clip(zen[mask], axis[0], axis[-1])
            i = np.clip(np.searchsorted(axis, z, side="right") - 1, 0, axis.size - 2)
            fz = ((z - axis[i]) / (axis[i + 1] - axis[i]))[:, None]
            a = rel[mask]
            j = np.clip(np.searchsorted(az, a, side="right") - 1, 0, az.size - 2)
            fa = ((a - az[j]) / (az[j + 1] - az[j]))[:, None]
            cells.append((mask, i, fz, j, fa))
        return cells

    def _from_grid(self, d, images=None):
        """Each image of ``images`` (per side of the horizon, a tuple of (n_zen, n_az, K)
        arrays; default the grid's (single, multiple, ground)) interpolated bilinearly at
        directions d (N, 3): a list of (N, K) arrays."""
        images = self._grid[3] if images is None else images
        out = [np.empty((d.shape[0], img.shape[-1])) for img in images[0]]
        for (mask, i, fz, j, fa), imgs in zip(self._grid_cells(d), images):
            if not np.any(mask):
                continue
            for k, img in enumerate(imgs):
                out[k][mask] = ((img[i, j] * (1 - fa) + img[i, j + 1] * fa) * (1 - fz)
                                + (img[i + 1, j] * (1 - fa) + img[i + 1, j + 1] * fa) * fz)
        return out

    def _gather_ms(self, rings, D):
        """Integral of T* J_ms along the view rays of directions D (G, B, 3) on ``rings``
        at the solver wavelengths (per unit E_sun), (G, B, W_ms)."""
        mus = self._sun_cosines(rings, D)  # (G, B, S)
        mu = np.broadcast_to(rings.mu[:, None, :], mus.shape)
        vs = (D @ self.sun)[..., None]
        den = np.sqrt(np.clip((1 - mu * mu) * (1 - mus * mus), 0.0, None))
        cphi = np.where(den > 1e-12, (vs - mu * mus) / np.where(den > 1e-12, den, 1.0), 1.0)
        phi = np.arccos(np.clip(cphi, -1.0, 1.0))
        step = self.medium_ms.extinction_scaled.at(rings.h) * rings.dt[..., None]  # (G, S, W_ms)
        weight = step_transmittance(step, dtype=np.float32) * rings.dt[..., None].astype(np.float32)
        scale = None
        if self.field.scattering is not None:  # sigma_s at the samples, once per ring (source_at)
            scale = self.field.scattering.at(rings.h)[:, None]  # (G, 1, S, W_ms)
        src = self.field.source_at(np.broadcast_to(rings.h[:, None, :], mus.shape), mu, phi, mus, scale=scale)
        return _column(weight, src)

    def _capped_aerosol_phase(self, cos_theta):
        """(1 - f) p*: each regime's phase function with its forward peak clipped at the
        delta-M cutoff (not renormalised), (R, ..., W)."""
        prof = self.profile
        theta = np.degrees(np.arccos(np.clip(np.asarray(cos_theta, dtype=float), -1.0, 1.0)))
        grid = prof.aerosol_phase_angles_deg
        idx = np.clip(np.searchsorted(grid, theta, side="right") - 1, 0, grid.size - 2)
        t = ((theta - grid[idx]) / (grid[idx + 1] - grid[idx]))[..., None]
        tab = self.medium.capped_phase
        return tab[:, idx, :] * (1.0 - t) + tab[:, idx + 1, :] * t

    def _spread_patterns(self, cos_theta, p_cap, regimes):
        """Each regime's pattern that :func:`peak_spread_table` spreads, at angles ``cos_theta``
        (G, A): max(p_cap - :func:`peak_spread_floor`, 0) within :data:`PEAK_SPREAD_MAX_DEG` of the
        sun, 0 beyond, ``p_cap`` (R, G, A, n_wl) the capped phase there as
        :meth:`_capped_aerosol_phase` reads it; a list of (G, A, n_wl) float32."""
        near = (cos_theta > np.cos(np.radians(PEAK_SPREAD_MAX_DEG)))[..., None]
        return [np.where(near, np.maximum(p_cap[reg] - self._spread_floor[reg], 0.0), 0.0).astype(np.float32)
                for reg in regimes]

    def _peak_aureole(self):
        """The peak-aureole table of this marcher's medium (:func:`peak_aureole_table`)."""
        return peak_aureole_table(self.profile, self.medium, self.medium.cutoff_deg, self.top)

    def _aureole_gather(self, cos_theta, dt, ext, ext_s, t_sun, t_sun_s, trans_s, block: int = 256, spread=None):
        """Integral along the view rays of directions (G, A) on rings (samples (G, S)) of
        the peak light left out by delta-M: sigma_peak E_sun T*_sun T*_view C(theta,
        tau_peak) dt, (G, A, n_wl); tau_peak is the peak optical depth of the sun path to
        the point plus the view path from it. ``cos_theta`` (G, A); ``dt``, ``ext``,
        ``ext_s``, ``trans_s`` per ring; ``t_sun``, ``t_sun_s`` (G, A, S, n_wl). Directions
        are taken ``block`` at a time (memory ~ block * S * n_wl * 4 B * 8). In float32,
        the precision of the sun's transmittances it reads (:meth:`_march`) and of the
        solver's field; the sum over a ray's samples is good to a few 1e-7.

        ``spread``: also the first scattering's peak spread (:func:`peak_spread_table`), read
        at the same angle and tau: ``(regimes, weights, t_first, patterns)``, the table index of
        each aerosol regime, its sum weight trans_s sigma_r dt per ring (G, S, n_wl), the sun
        transmittance the delta-M first scattering reads (G, A, S, n_wl) and each regime's spread
        pattern g_r at the directions' angles (G, A, n_wl; :meth:`_spread_patterns`); added to the
        result as E_sun sum_r sum_s weight t_first (S_r(theta, tau) - (1 - exp(-tau)) g_r(theta))."""
        theta_g, tau_g, _ = self._aureole
        f32 = np.float32
        table = self._aureole_table32
        tau_g32 = tau_g.astype(f32)
        theta = np.arccos(np.clip(cos_theta, -1.0, 1.0))
        n_wl = ext.shape[-1]
        out = np.zeros(cos_theta.shape + (n_wl,))
        gn, an = np.nonzero(theta < theta_g[-1])
        n_tau = tau_g.size
        w_idx = np.arange(n_wl)
        tiny = np.finfo(f32).tiny
        step = np.maximum(ext - ext_s, 0.0) * dt[..., None]  # peak scattering optical depth of each step
        view = (np.cumsum(step, axis=1) - 0.5 * step).astype(f32)  # peak optical depth of the view path, per ring
        seen = (step * trans_s).astype(f32)
        for k in range(0, gn.size, block):
            g, a = gn[k:k + block], an[k:k + block]
            ts, ts_s = t_sun[g, a].astype(f32, copy=False), t_sun_s[g, a].astype(f32, copy=False)
            tau = np.log(np.maximum(ts_s, tiny))  # sun path: log(T*_sun / T_sun)
            tau -= np.log(np.maximum(ts, tiny))
            tau += view[g]  # + view path
            np.clip(tau, 0.0, tau_g32[-1], out=tau)
            x = theta[g, a] / theta_g[-1] * (theta_g.size - 1)
            i = np.clip(x.astype(int), 0, theta_g.size - 2)
            fi = np.clip(x - i, 0.0, 1.0).astype(f32)[:, None, None]
            rows = (table[i] * (1 - fi) + table[i + 1] * fi).reshape(-1)  # each direction's angle: (n, n_tau, W)
            j = _tau_cells(tau_g, tau)
            fj = (tau - tau_g32[j]) / (tau_g32[j + 1] - tau_g32[j])
            base = (np.arange(g.size)[:, None, None] * n_tau + j) * n_wl + w_idx  # index of (direction, tau_j, wl)
            c = rows[base] * (1 - fj) + rows[base + n_wl] * fj
            out[g, a] = (seen[g] * ts_s * c).sum(axis=1)
            if spread is not None:
                t_first = spread[2][g, a].astype(f32, copy=False)
                turned = -np.expm1(-tau)  # the share of the light the peak turns on the two paths
                for reg, weight, pattern in zip(spread[0], spread[1], spread[3]):
                    tab_r = self._spread[reg]
                    rows = (tab_r[i] * (1 - fi) + tab_r[i + 1] * fi).reshape(-1)
                    c = rows[base] * (1 - fj) + rows[base + n_wl] * fj
                    c -= turned * pattern[g, a][:, None, :]
                    out[g, a] += (weight[g] * t_first * c).sum(axis=1)
        return out * self.profile.solar_irradiance

    def _delta_m_first_scattering(self, cos_theta, dt, ray, regimes, aers, pa, p_cap, c_aer, trans_s, t_sun_s):
        """The first scattering of sunlight as the delta-M solver counts it, (G, A, n_wl)
        for directions on rings as in :meth:`_march`: the part of every phase function
        outside the truncated forward peak, p_cap = min(p, p(cutoff)), seen through the
        scaled extinction (light scattered into the peak on the way counts as undeflected,
        as in the solver's diffuse field), the peak p - p_cap through the true extinction.
        Its excess over true single scattering is light the solver's orders >= 2 leave out
        (the forward-scattered part of the scaled-out extinction), so the total keeps it,
        in ``multiple``. ``pa``, ``p_cap``: each regime's phase function and capped phase function
        (:meth:`_capped_aerosol_phase`) at the directions, (R, G, A, W); ``c_aer``: each regime's
        column sum_s T t_sun sigma_r dt."""
        prof = self.profile
        w_s = trans_s * dt[..., None]
        first = prof.rayleigh_phase(cos_theta) * _column(w_s * ray, t_sun_s)
        for reg, sig, c in zip(regimes, aers, c_aer):
            first = first + p_cap[reg] * _column(w_s * sig, t_sun_s) + np.maximum(pa[reg] - p_cap[reg], 0.0) * c
        return prof.solar_irradiance * first

    # ---------------------------------------------------------------- public
    def direct_sun_irradiance(self) -> np.ndarray:
        """Solar irradiance (W m^-2 nm^-1) on a surface facing the sun at the observer,
        after extinction, times the visible fraction of the disc."""
        prof = self.profile
        if self.observer_altitude_m >= self.top:
            d = self.sun[None, :]
            rings = self._rings(d[:, 2])
            tau = (self.medium.extinction.at(rings.h) * rings.dt[..., None]).sum(axis=1)[0]
            blocked = bool(rings.hits[0])
            return np.zeros_like(prof.solar_irradiance) if blocked else prof.solar_irradiance * np.exp(-tau)
        t_sun = self.sun_table.transmittance(np.array([self.observer_altitude_m]), np.array([self.sun[2]]))[0]
        return prof.solar_irradiance * t_sun

    @staticmethod
    def _unit(directions):
        d = np.asarray(directions, dtype=float).reshape(-1, 3)
        nrm = np.linalg.norm(d, axis=1, keepdims=True)
        if np.any(~np.isfinite(d)) or np.any(nrm < 1e-12):
            raise SkymodelInputError("directions", "non-finite or zero vectors", "unit vectors (N, 3)")
        return d / nrm

    def _near_sun(self, d):
        """Indices of the directions d (N, 3) that are marched exactly with a grid: those
        within ``settings.sun_exact_deg`` of the sun."""
        return np.nonzero(d @ self.sun > np.cos(np.radians(self.settings.sun_exact_deg)))[0]

    def _exact_parts(self, d):
        """(single, multiple, ground) of directions d (N, 3), every one marched
        (:meth:`exact_in_threads`)."""
        if d.shape[0] == 0:
            return tuple(np.zeros((0, self.profile.wavelengths_nm.size)) for _ in range(3))
        return tuple(np.concatenate(c) for c in zip(*self.exact_in_threads(d)))

    def total_radiance(self, directions, matrix=None) -> np.ndarray:
        """The total radiance (single + multiple + ground, without the solar disc) looking
        along ``directions`` (N, 3): (N, n_wl), or times ``matrix`` (n_wl, K), a linear
        reduction such as CIE XYZ. What ``radiance(directions).radiance @ matrix`` gives
        up to rounding, cheaper: on the direction grid the total, reduced once per marcher
        and matrix, is interpolated instead of the three spectral components."""
        d = self._unit(directions)
        if self._grid is None:
            total = sum(self._exact_parts(d))
            return total if matrix is None else total @ matrix
        out = self._from_grid(d, self._grid_total(matrix))[0]
        near = self._near_sun(d)
        if near.size:
            exact = sum(self._exact_parts(d[near]))
            out[near] = exact if matrix is None else exact @ matrix
        check_finite("radiance", out)
        return out

    def _grid_total(self, matrix):
        """The grid's total radiance images times ``matrix`` (None: the spectra), per side of
        the horizon; the last one is kept."""
        cached = getattr(self, "_total_images", None)
        if cached is not None and (cached[0] is matrix or (matrix is not None and cached[0] is not None
                                                           and np.array_equal(cached[0], matrix))):
            return cached[1]
        images = [(sum(imgs) if matrix is None else sum(imgs) @ matrix,) for imgs in self._grid[3]]
        self._total_images = (matrix, images)
        return images

    def radiance(self, directions) -> SkyRadiance:
        """Sky radiance (without the solar disc) looking along ``directions`` (N, 3)."""
        d = self._unit(directions)
        prof = self.profile
        t_start = time.perf_counter()
        if self._grid is None:
            single, multiple, ground = self._exact_parts(d)
        else:
            single, multiple, ground = self._from_grid(d)
            near = self._near_sun(d)
            if near.size:
                single[near], multiple[near], ground[near] = self._exact_parts(d[near])
        info = {"orders": self.field.orders, "order_contributions": list(self.field.order_contributions),
                "timings": dict(self.timings, directions_s=time.perf_counter() - t_start),
                "settings": self.settings}
        res = SkyRadiance(prof.wavelengths_nm, d, single, multiple, ground, self.direct_sun_irradiance(), info)
        check_finite("radiance", res.radiance)
        return res

    # ---------------------------------------------------------------- marching
    def _rings(self, cos_zenith):
        """View-ray samples of rings of directions with the zenith cosines ``cos_zenith``
        (G,). The observer is on the z axis, so they depend only on the zenith angle: one
        set serves every direction of a ring (:class:`_Rings`), computed for the ring's
        direction of azimuth 90 degrees, so it never depends on which directions share it."""
        cz = np.asarray(cos_zenith, dtype=float)
        d0 = np.stack([np.sqrt(np.clip(1.0 - cz * cz, 0.0, None)), np.zeros_like(cz), cz], axis=-1)
        p = np.broadcast_to(self.origin, d0.shape)
        t0, t1, hits = atmosphere_segment(p, d0, self.R, self.R + self.top)
        n, share = self.settings.view_steps, self.settings.view_depth_share
        if share > 0.0:  # placed by the optical depth at the profile's middle wavelength
            tf, dtf = march_samples(p, d0, t0, t1, _FINE_VIEW_STEPS, self.R)
            ext = self.medium.extinction
            middle = ext.weights[:, ext.weights.shape[1] // 2]
            sigma = ext.basis_at(np.maximum(altitude_along(p, d0, tf, self.R), 0.0)) @ middle
            edges = np.concatenate([t0[:, None], t0[:, None] + np.cumsum(dtf, axis=1)], axis=1)
            t, dt = samples_by_depth(edges, sigma, n, share)
        else:
            t, dt = march_samples(p, d0, t0, t1, n, self.R)
        h = altitude_along(p, d0, t, self.R)
        x = p[:, None, :] + t[..., None] * d0[:, None, :]
        r = np.linalg.norm(x, axis=-1)
        mu = np.einsum("gsi,gi->gs", x, d0) / r
        r1 = np.linalg.norm(p + t1[:, None] * d0, axis=-1)
        return _Rings(t, dt, np.maximum(h, 0.0), r, x[..., 2], mu, hits, t1, r1)

    def _sun_cosines(self, rings, D):
        """Cosine of the sun's zenith angle at every sample, (G, A, S), of directions D
        (G, A, 3) on rings (``D[g, :, 2]`` the zenith cosine of ring g): the local
        vertical at distance t is (t d_x, t d_y, z0 + t d_z) / r."""
        hs = D[..., 0] * self.sun[0] + D[..., 1] * self.sun[1]  # (G, A)
        return (rings.t[:, None, :] * hs[..., None] + (rings.xz * self.sun[2])[:, None, :]) / rings.r[:, None, :]

    def _march(self, D):
        """(single, multiple, ground), each (G, A, n_wl), for directions D (G, A, 3) on G
        rings of equal zenith angle (``D[g, :, 2]`` equal; A = 1 for any directions).

        What depends only on the zenith angle (the samples, the medium along them and the
        view transmittances) is computed once per ring; per direction only what depends
        on the sun: the sun transmittance at every sample, the phase functions (constant
        along a ray: the sun is a parallel beam), the multiple-scattering source and the
        peak aureole. Single scattering is then a sum of column integrals
        E_sun [p_R(cos) sum_s T t_sun sigma_R dt + sum_r p_r(cos) sum_s T t_sun sigma_r dt]."""
        prof, med = self.profile, self.medium
        e_sun = prof.solar_irradiance
        rings = self._rings(D[:, 0, 2])
        regimes = [reg for reg, lr in enumerate(med.aerosol) if np.any(lr.weights)]
        lrs = [med.extinction, med.extinction_scaled, med.rayleigh] + [med.aerosol[reg] for reg in regimes]
        ext, ext_s, ray, *aers = evaluate_many(lrs, rings.h)  # each (G, S, W)
        dtw = rings.dt[..., None]
        step_tau = ext * dtw
        trans = step_transmittance(step_tau, dtype=np.float32)  # each step's mean (exact for a source constant over it)
        cos_theta = D @ self.sun  # (G, A)
        mus = self._sun_cosines(rings, D)  # (G, A, S)
        h_b = np.broadcast_to(rings.h[:, None, :], mus.shape)
        ms_on = self.field.orders > 1
        # toward the sun from every sample (G, A, S, W), the shadow included: the true
        # extinction and (with multiple scattering) the delta-M scaled one, one table lookup
        t_sun, *scaled = self.sun_table.transmittances(h_b, mus, (0, 2) if ms_on else (0,), dtype=np.float32,
                                                       straight=(2,) if ms_on and self._aureole is not None else ())
        pa = prof.aerosol_phase_at(cos_theta)  # (R, G, A, W)
        p_ray = prof.rayleigh_phase(cos_theta)  # (G, A, W)
        # single scattering: true extinction, full phase functions (with or without the
        # multiple-scattering part, so ``single`` is what an orders=1 render gives)
        w = trans * dtw
        c_aer = [_column(w * sig, t_sun) for sig in aers]
        scat = p_ray * _column(w * ray, t_sun)
        for reg, c in zip(regimes, c_aer):
            scat = scat + pa[reg] * c
        single = e_sun * scat
        # delta-M bookkeeping (with multiple scattering) that the total needs but single
        # scattering is not: counted in ``multiple`` (see _delta_m_first_scattering)
        rebalance = np.zeros_like(single)
        if ms_on:
            step_tau_s = ext_s * dtw
            trans_s = step_transmittance(step_tau_s, dtype=np.float32)
            t_sun_s = scaled[0]
            p_cap = self._capped_aerosol_phase(cos_theta)  # (R, G, A, W)
            first = self._delta_m_first_scattering(cos_theta, rings.dt, ray, regimes, aers, pa, p_cap, c_aer, trans_s,
                                                   t_sun_s)
            rebalance = first - single
            if self._aureole is not None:
                # the aureole's own small-angle model of the peak light keeps the straight path
                spread = None
                if self._spread is not None:  # the first scattering's capped phase, spread by the peak
                    spread = (regimes, [(trans_s * dtw * sig).astype(np.float32) for sig in aers], t_sun_s,
                              self._spread_patterns(cos_theta, p_cap, regimes))
                aureole = self._aureole_gather(cos_theta, rings.dt, ext, ext_s, t_sun, scaled[1], trans_s,
                                               spread=spread)
        # ground seen directly: direct sun and (from the solver) diffuse sky light
        ground = np.zeros_like(single)
        ms_ground = np.zeros_like(single)
        gi = np.nonzero(rings.hits)[0]
        if gi.size:
            dg = D[gi]
            hs = dg[..., 0] * self.sun[0] + dg[..., 1] * self.sun[1]
            t1 = rings.t1[gi, None]
            mus_g = (t1 * hs + (self.origin[2] + t1 * dg[..., 2]) * self.sun[2]) / rings.r1[gi, None]  # (Gh, A)
            albedo = prof.ground_albedo / np.pi
            cos_g = np.maximum(mus_g, 0.0)[..., None]
            # the directly lit ground through the true extinction (what orders=1 gives)
            t_ground = np.exp(-step_tau[gi].sum(axis=1))[:, None, :]  # (Gh, 1, W)
            t_dir = self.sun_table.transmittances(np.zeros_like(mus_g), mus_g, (0, 2) if ms_on else (0,))
            e_dir = e_sun * t_dir[0] * cos_g
            ground[gi] = t_ground * albedo * e_dir
            if ms_on:
                # the solver's ground light is seen through the delta-M scaled extinction,
                # and so is the direct sun on the ground in the total: the difference to
                # the true extinction goes with ``multiple`` as for the sky
                t_ground_s = np.exp(-step_tau_s[gi].sum(axis=1))[:, None, :]
                e_dir_s = e_sun * t_dir[1] * cos_g
                e_diff = self.to_full(self.field.ground_irradiance_at(mus_g)) * e_sun
                ms_ground[gi] = t_ground_s * albedo * e_diff
                rebalance[gi] += t_ground_s * albedo * e_dir_s - ground[gi]
        multiple = ms_ground + rebalance
        if ms_on and self._aureole is not None:
            multiple = multiple + aureole
        if ms_on:
            multiple = multiple + self.to_full(self._gather_ms(rings, D)) * e_sun
        return single, multiple, ground

    def _exact(self, d):
        """(single, multiple, ground) radiance for directions d (N, 3), every one
        marched: single scattering and direct-sun ground light at every wavelength, the
        multiple-scattering source gathered at the solver wavelengths. Directions with
        the same zenith cosine (a row of an equirectangular image) are marched as one
        ring (:meth:`_march`), padded to the longest ring with repeats of its last
        direction when that adds at most half again; else each is a ring of its own.
        A direction's values never depend on the others (the rings' samples depend
        only on the zenith cosine)."""
        d = np.asarray(d, float)
        n = d.shape[0]
        order = np.argsort(d[:, 2], kind="stable")
        dz = d[order, 2]
        starts = np.flatnonzero(np.r_[True, dz[1:] != dz[:-1]]) if n else np.zeros(0, int)
        counts = np.diff(np.r_[starts, n])
        longest = int(counts.max()) if n else 0
        if longest <= 1 or starts.size * longest > 1.5 * n:
            return tuple(c[:, 0, :] for c in self._march(d[:, None, :]))
        pos = np.arange(longest)
        idx = order[starts[:, None] + np.minimum(pos, counts[:, None] - 1)]  # (G, longest)
        real = pos < counts[:, None]
        out = []
        for c in self._march(d[idx]):
            full = np.empty((n, c.shape[-1]))
            full[idx[real]] = c[real]
            out.append(full)
        return tuple(out)


@dataclass(frozen=True)
class _Rings:
    """View-ray samples shared by every direction of a ring of equal zenith angle, (G, S)
    each: distance t and step dt (m), altitude h (m), radius r (m) and height coordinate
    xz (m, along the observer's vertical) of the points, the cosine mu of the view
    direction's zenith angle there; per ring (G,): whether it ends on the ground, where
    (t1, m) and that point's radius r1 (m)."""

    t: np.ndarray
    dt: np.ndarray
    h: np.ndarray
    r: np.ndarray
    xz: np.ndarray
    mu: np.ndarray
    hits: np.ndarray
    t1: np.ndarray
    r1: np.ndarray


def _column(weight, values):
    """sum_s weight[g, s, w] values[g, a, s, w] -> (G, A, W): a quantity that depends on
    the ring only (``weight``) integrated against one that depends on the direction, in
    the precision of ``values`` (float32 for the sun's transmittances: a sum of S products,
    good to a few 1e-7; a float64 weight would have the einsum convert every value)."""
    return np.einsum("gsw,gasw->gaw", weight.astype(values.dtype, copy=False), values)


def _tau_cells(nodes, tau):
    """np.searchsorted(nodes, tau, side="right") - 1 clipped to [0, nodes.size - 2], for the
    peak-aureole table's optical depth nodes (0, then geometric): found from the logarithm
    (a binary search over millions of values costs 6x more) and corrected by one where
    rounding put it in a neighbouring cell, so the result is the search's."""
    n = nodes.size
    ratio = nodes[2:] / nodes[1:-1] if n > 3 else np.zeros(1)
    if n <= 3 or nodes[0] != 0.0 or not np.allclose(ratio, ratio[0], rtol=1e-9, atol=0.0):
        return np.clip(np.searchsorted(nodes, tau, side="right") - 1, 0, n - 2)
    with np.errstate(divide="ignore"):
        tiny = np.finfo(tau.dtype).tiny if np.issubdtype(np.asarray(tau).dtype, np.floating) else 1e-300
        j = np.floor(np.log(np.maximum(tau, tiny) / nodes[1]) / np.log(ratio[0])).astype(np.intp) + 1
    np.clip(j, 0, n - 2, out=j)
    j += (tau >= nodes[j + 1]) & (j < n - 2)
    j -= (tau < nodes[j]) & (j > 0)
    return j


def render_directions(profile, directions, sun_elevation_deg: float, sun_azimuth_deg: float = 180.0,
                      observer_altitude_m: float = 0.0, settings: MarchSettings | None = None) -> SkyRadiance:
    """Convenience: build a :class:`SkyMarcher` and return the radiance for ``directions``."""
    return SkyMarcher(profile, sun_elevation_deg, sun_azimuth_deg, observer_altitude_m, settings).radiance(directions)
