"""Rays in a spherical-shell atmosphere.

Positions are metres relative to the planet centre, directions unit vectors. The two
spheres that matter are the ground (radius R) and the top of the atmosphere (R + 100 km).
Intersections use the numerically stable quadratic form: with b = p.d and
c = |p|^2 - r^2 computed as (|p| - r)(|p| + r) (no cancellation at |p| ~ r ~ 6.4e6 m),
the roots of t^2 + 2 b t + c = 0 are q = -b - sign(b) sqrt(b^2 - c), t1 = q, t2 = c / q.
A ray exactly tangent to a sphere (b^2 == c) touches it once: we count it as a hit of
the ground (it does not pass below it) and as inside the atmosphere for the top.
"""

from __future__ import annotations

import numpy as np


def sphere_intersections(p, d, radius):
    """Distances (t_near, t_far) along rays ``p + t d`` to a sphere of ``radius`` centred
    at the origin; NaN where the line misses. Shapes: p, d (..., 3) -> (...,) each."""
    p = np.asarray(p, dtype=float)
    d = np.asarray(d, dtype=float)
    r = np.linalg.norm(p, axis=-1)
    b = np.einsum("...i,...i->...", p, d)
    c = (r - radius) * (r + radius)
    disc = b * b - c
    miss = disc < 0
    s = np.sqrt(np.where(miss, 0.0, disc))
    q = -b - np.copysign(s, b)
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = q
        t2 = np.where(q != 0, c / np.where(q != 0, q, 1.0), 0.0)
    t_near = np.minimum(t1, t2)
    t_far = np.maximum(t1, t2)
    return np.where(miss, np.nan, t_near), np.where(miss, np.nan, t_far)


def atmosphere_segment(p, d, ground_radius, top_radius):
    """The part of each ray inside the atmosphere, from the ray origin forward.

    Returns ``(t_start, t_end, hits_ground)``: distances in metres (t_start = t_end = 0
    for rays that never enter the atmosphere) and whether the segment ends on the ground.
    Origins may be inside the atmosphere, or outside (observers in space).
    """
    gn, gf = sphere_intersections(p, d, ground_radius)
    tn, tf = sphere_intersections(p, d, top_radius)
    top_hit = np.isfinite(tn) & (tf > 0)
    t_start = np.where(top_hit, np.maximum(tn, 0.0), 0.0)
    t_end = np.where(top_hit, tf, 0.0)
    ground_ahead = np.isfinite(gn) & (gn >= 0) & (gn < t_end)
    # an origin just below the ground (numerical noise) that looks up still sees the sky
    t_end = np.where(ground_ahead, gn, t_end)
    return t_start, t_end, ground_ahead


def altitude_along(p, d, t, ground_radius):
    """Altitude above the ground (m) of points ``p + t d``; t broadcast against p[..., :1].

    Uses r(t) = sqrt(|p|^2 + 2 t b + t^2) with |p|^2 - R^2 factored to stay accurate."""
    p = np.asarray(p, dtype=float)
    r0 = np.linalg.norm(p, axis=-1)
    b = np.einsum("...i,...i->...", p, d)
    t = np.asarray(t, dtype=float)
    r0 = r0[..., None] if t.ndim > r0.ndim else r0
    b = b[..., None] if t.ndim > b.ndim else b
    r2_minus_R2 = (r0 - ground_radius) * (r0 + ground_radius) + t * (2.0 * b + t)
    r = np.sqrt(np.maximum(r2_minus_R2 + ground_radius**2, 0.0))
    return r2_minus_R2 / (r + ground_radius)


def local_basis(up):
    """An orthonormal basis (east-like, north-like, up) for unit 'up' vectors (..., 3)."""
    up = np.asarray(up, dtype=float)
    helper = np.where(np.abs(up[..., 2:3]) < 0.999, np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]))
    e = np.cross(helper, up)
    e /= np.linalg.norm(e, axis=-1, keepdims=True)
    n = np.cross(up, e)
    return e, n, up


def direction_from_angles(zenith_deg, azimuth_deg):
    """Unit vectors in the observer's frame (x east, y north, z up) from zenith angle and
    azimuth clockwise from north (degrees)."""
    z = np.radians(np.asarray(zenith_deg, dtype=float))
    a = np.radians(np.asarray(azimuth_deg, dtype=float))
    # the sines and cosines before broadcasting: a panorama's rows share a zenith angle and
    # its columns an azimuth (a 4096x2048 map: 6144 of each instead of 8.4 million)
    sz, cz, sa, ca = np.sin(z), np.cos(z), np.sin(a), np.cos(a)
    shape = np.broadcast_shapes(z.shape, a.shape)
    out = np.empty(shape + (3,))
    np.multiply(sz, sa, out=out[..., 0])
    np.multiply(sz, ca, out=out[..., 1])
    out[..., 2] = cz
    return out


def sun_direction(elevation_deg, azimuth_deg):
    """Unit vector toward the sun in the observer's frame (x east, y north, z up)."""
    return direction_from_angles(90.0 - np.asarray(elevation_deg, dtype=float), azimuth_deg)
