"""The quality presets against an independent truth: the Monte Carlo path tracer.

What ``benchmarks/bench_truth.py`` measures (issue 23): for a scene (atmosphere, sun
elevation) the marcher at each quality preset and :func:`~skymodel.validation.montecarlo.trace_radiance`
see the same optical profile and the same sky directions; this module holds the pieces
that are not the tracing itself, so they can be tested fast:

* :func:`view_set`: the sky directions of a scene (zenith, principal plane both ways,
  almucantars, the side, near the horizon, a few around the sun), those within
  :data:`EXCLUDE_DEG` of the sun's centre left out;
* :func:`truth_statistics`: per wavelength the median and the worst relative error over
  the directions, each with the Monte Carlo noise it carries;
* :func:`which_is_closer`: of two marchers (two presets), which is closer to the truth
  where the truth's noise lets one tell;
* :func:`paths_for_noise`: paths per direction for a target standard error, from a pilot.

Statistics (``rel = marcher / MC - 1`` per direction and wavelength; ``s = MC stderr /
MC``, the relative standard error of that direction's truth):

* *median* = median over the directions of ``|rel|``; its noise ``1.2533 * rms(s) /
  sqrt(N)`` (the standard error of a sample median of N values with noise s, normal
  approximation);
* *mean* = the mean of ``rel`` (signed: an overall bias); its noise ``rms(s) / sqrt(N)``;
* *worst* = the largest ``|rel|`` over the directions outside the sun's disc and the
  aureole's first 2 degrees (angle to the sun's centre > :data:`EXCLUDE_DEG`); its noise
  the ``s`` of that direction.

The noise of both is an estimate of how far the statistic can move because the truth is
noisy; the benchmark asks for a noise at least 3x below the tolerance (0.5 % median:
<= 0.17 %; 1.5 % worst: every direction's ``s`` <= 0.5 %).
"""

from __future__ import annotations

import numpy as np

from skymodel.errors import SkymodelInputError
from skymodel.render.rays import direction_from_angles, sun_direction
from skymodel.sun import SUN_ANGULAR_RADIUS_DEG

#: The aureole's first degrees left out of the worst case (beyond the disc's edge), deg.
AUREOLE_EXCLUDED_DEG = 2.0
#: Directions closer than this to the sun's centre are not compared at all, deg.
EXCLUDE_DEG = SUN_ANGULAR_RADIUS_DEG + AUREOLE_EXCLUDED_DEG
#: Relative standard error of a sample median over that of one value, per 1/sqrt(N) (sqrt(pi/2)).
MEDIAN_NOISE_FACTOR = float(np.sqrt(np.pi / 2.0))

#: Fixed views (view zenith deg, azimuth from the sun's deg): zenith, principal plane toward
#: and away from the sun, the side, the diagonals, near the horizon.
FIXED_VIEWS = ((0.0, 0.0),
               (30.0, 0.0), (60.0, 0.0), (75.0, 0.0), (85.0, 0.0), (89.0, 0.0),
               (30.0, 180.0), (60.0, 180.0), (75.0, 180.0), (85.0, 180.0), (89.0, 180.0),
               (30.0, 90.0), (60.0, 90.0), (85.0, 90.0), (89.0, 90.0),
               (70.0, 45.0), (88.0, 45.0), (70.0, 135.0), (88.0, 135.0))
#: Views on the sun's almucantar (view zenith = the sun's, at most 89 deg), at these
#: angular distances from the sun's centre (deg), and on the principal plane this far
#: above the sun (deg).
ALMUCANTAR_DISTANCES_DEG = (5.0, 10.0, 20.0, 45.0, 90.0, 135.0)
ABOVE_SUN_DEG = (3.0, 6.0, 15.0)
#: Highest view zenith of the almucantar (the horizon itself is left out), deg.
MAX_VIEW_ZENITH_DEG = 89.0


def angle_to_sun_deg(directions, sun):
    """Angles (deg) between unit ``directions`` (N, 3) and the unit vector ``sun`` (3,)."""
    d = np.asarray(directions, dtype=float)
    s = np.asarray(sun, dtype=float).reshape(3)
    # atan2 of |d x s| and d.s: accurate at small angles too
    return np.degrees(np.arctan2(np.linalg.norm(np.cross(d, s), axis=-1), d @ s))


def _almucantar_azimuth_deg(zenith_deg, sun_zenith_deg, distance_deg):
    """Azimuth from the sun (deg) of the point at ``zenith_deg`` that lies ``distance_deg``
    from the sun (spherical law of cosines); NaN where none does."""
    z, zs, d = np.radians(zenith_deg), np.radians(sun_zenith_deg), np.radians(distance_deg)
    den = np.sin(z) * np.sin(zs)
    c = (np.cos(d) - np.cos(z) * np.cos(zs)) / den if den > 0 else np.nan
    return float(np.degrees(np.arccos(c))) if np.isfinite(c) and abs(c) <= 1.0 else float("nan")


def view_set(sun_elevation_deg):
    """The views of a scene: (zenith deg, azimuth from the sun deg) pairs (N, 2), every
    one above the horizon and farther than :data:`EXCLUDE_DEG` from the sun's centre,
    without repeats. The fixed views plus the sun's almucantar and points above the sun."""
    el = float(sun_elevation_deg)
    if not -90.0 <= el <= 90.0:
        raise SkymodelInputError("sun_elevation", el, "-90..90 degrees")
    sz = 90.0 - el
    views = list(FIXED_VIEWS)
    z_alm = min(sz, MAX_VIEW_ZENITH_DEG)
    for dist in ALMUCANTAR_DISTANCES_DEG:
        az = _almucantar_azimuth_deg(z_alm, sz, dist)
        if np.isfinite(az):
            views.append((round(z_alm, 3), round(az, 3)))
    for up in ABOVE_SUN_DEG:
        z = sz - up
        if 0.0 < z <= MAX_VIEW_ZENITH_DEG:
            views.append((round(z, 3), 0.0))
    v = np.array(views, dtype=float)
    _, first = np.unique(np.round(v, 3), axis=0, return_index=True)
    v = v[np.sort(first)]
    d = direction_from_angles(v[:, 0], 180.0 + v[:, 1])
    keep = angle_to_sun_deg(d, sun_direction(el, 180.0)) > EXCLUDE_DEG
    return v[keep]


def view_directions(views, sun_azimuth_deg=180.0):
    """Unit vectors (N, 3) of ``views`` (zenith, azimuth from the sun, deg) for a sun at
    ``sun_azimuth_deg``."""
    v = np.asarray(views, dtype=float)
    return direction_from_angles(v[:, 0], sun_azimuth_deg + v[:, 1])


def truth_statistics(marcher, mc, mc_stderr, angle_to_sun=None, exclude_deg=EXCLUDE_DEG):
    """Errors of ``marcher`` against the Monte Carlo truth ``mc`` (both (N, W), the same
    directions and wavelengths) with its standard error ``mc_stderr`` (N, W).

    Directions whose ``angle_to_sun`` (deg, (N,); None: all count) is at most
    ``exclude_deg`` are left out of every statistic. Returns a dict of (W,) arrays:
    ``median`` (median |rel|), ``median_signed``, ``median_noise``, ``mean_signed``
    (the mean rel: an overall bias) and ``mean_noise`` (rms(s) / sqrt(N)), ``worst`` (largest
    |rel|, signed as it is), ``worst_noise`` (that direction's relative MC stderr),
    ``worst_index`` (its row in the inputs), ``noise_max`` (the largest relative MC
    stderr of any direction), and ``n`` (directions counted)."""
    m = np.asarray(marcher, dtype=float)
    t = np.asarray(mc, dtype=float)
    se = np.asarray(mc_stderr, dtype=float)
    if m.shape != t.shape or se.shape != t.shape or t.ndim != 2:
        raise SkymodelInputError("marcher, mc, mc_stderr", f"shapes {m.shape}, {t.shape}, {se.shape}",
                                 "equal (N, W) arrays")
    if np.any(~(t > 0)):
        raise SkymodelInputError("mc", "a radiance <= 0 or NaN", "positive Monte Carlo radiances")
    keep = np.ones(t.shape[0], dtype=bool)
    if angle_to_sun is not None:
        keep = np.asarray(angle_to_sun, dtype=float) > exclude_deg
    if not np.any(keep):
        raise SkymodelInputError("angle_to_sun", "every direction excluded", f"some direction > {exclude_deg} deg")
    rows = np.flatnonzero(keep)
    rel = m[rows] / t[rows] - 1.0
    s = se[rows] / t[rows]
    n = rows.size
    wi = np.argmax(np.abs(rel), axis=0)
    cols = np.arange(t.shape[1])
    return dict(median=np.median(np.abs(rel), axis=0), median_signed=np.median(rel, axis=0),
                mean_signed=rel.mean(axis=0), mean_noise=np.sqrt(np.mean(s * s, axis=0) / n),
                median_noise=MEDIAN_NOISE_FACTOR * np.sqrt(np.mean(s * s, axis=0) / n),
                worst=rel[wi, cols], worst_noise=s[wi, cols], worst_index=rows[wi],
                noise_max=s.max(axis=0), n=np.full(t.shape[1], n))


#: How many standard errors the truth must lie from the midpoint of two marchers before
#: :func:`which_is_closer` counts the nearer one as closer.
CLOSER_SIGMAS = 2.0


def which_is_closer(a, b, mc, mc_stderr, angle_to_sun=None, exclude_deg=EXCLUDE_DEG, sigmas=CLOSER_SIGMAS):
    """Which of two marchers ``a`` and ``b`` (both (N, W), e.g. ``final`` and ``reference``)
    is closer to the Monte Carlo truth ``mc``, counted only where the truth's noise decides it.

    ``b`` is closer than ``a`` exactly where the true radiance lies on ``b``'s side of their
    midpoint ``(a + b) / 2``; the estimate ``mc`` tells that side with confidence where it lies
    more than ``sigmas`` standard errors ``mc_stderr`` from the midpoint (where ``a`` and ``b``
    are equal neither is closer). Directions within ``exclude_deg`` of the sun (``angle_to_sun``,
    deg) are left out, as in :func:`truth_statistics`. A worst or median over the directions
    cannot make this call when the two presets differ by less than the truth's noise; counting
    the direction-wavelengths the truth resolves can.

    Returns a dict: ``compared`` (direction-wavelengths counted), ``resolved`` (those whose
    side the truth decides), ``b_closer`` (of the resolved, where ``b`` is the closer) and
    ``a_closer``."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    t, se = np.asarray(mc, dtype=float), np.asarray(mc_stderr, dtype=float)
    if not (a.shape == b.shape == t.shape == se.shape) or t.ndim != 2:
        raise SkymodelInputError("a, b, mc, mc_stderr", f"shapes {a.shape}, {b.shape}, {t.shape}, {se.shape}",
                                 "equal (N, W) arrays")
    if not sigmas > 0:
        raise SkymodelInputError("sigmas", sigmas, "a number of standard errors > 0")
    keep = np.ones(t.shape[0], dtype=bool)
    if angle_to_sun is not None:
        keep = np.asarray(angle_to_sun, dtype=float) > exclude_deg
    keep = np.broadcast_to(keep[:, None], t.shape)
    resolved = keep & (a != b) & (np.abs(t - 0.5 * (a + b)) > sigmas * se)
    b_closer = resolved & (np.abs(b - t) < np.abs(a - t))
    return dict(compared=int(keep.sum()), resolved=int(resolved.sum()), b_closer=int(b_closer.sum()),
                a_closer=int(resolved.sum() - b_closer.sum()))


def paths_for_noise(pilot_stderr_rel, pilot_paths, target_rel, min_paths=1000, max_paths=None):
    """Paths per direction (N,) for a relative standard error ``target_rel``, from a pilot's
    relative standard errors (N, W) at ``pilot_paths`` paths: the worst wavelength of each
    direction, se scaling as 1 / sqrt(paths), rounded up to a multiple of 1000 and clipped
    to [min_paths, max_paths]."""
    s = np.asarray(pilot_stderr_rel, dtype=float)
    if s.ndim == 2:
        s = s.max(axis=1)
    if not target_rel > 0:
        raise SkymodelInputError("target_rel", target_rel, "> 0")
    n = pilot_paths * (s / target_rel) ** 2
    n = np.ceil(np.nan_to_num(n, nan=float(max_paths or min_paths)) / 1000.0) * 1000.0
    n = np.maximum(n, min_paths)
    if max_paths is not None:
        n = np.minimum(n, max_paths)
    return n.astype(int)
