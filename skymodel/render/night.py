"""The night in the renderer: the moonlit sky, the stars, the moon's disc and the natural glow.

What is added to the sunlit sky, for one place and time (docs/night.md):

* **Sunlit sky** (not here): the renderer's own, computed only while the sun is at or above the
  registry's lowest ``sun_elevation`` (:func:`sunlit`; -18 degrees, the end of astronomical
  dusk). Below it the sunlit sky is taken as zero (measured: at -18 its zenith is about 1 % of
  the natural glow's; docs/night.md "Sun to -18").
* **Moonlit sky**: the radiative transfer is linear in its source and the multiple-scattering
  solution is per unit solar irradiance (:class:`~skymodel.render.marcher.SkySolution`), so the
  moonlit sky is the same marcher with the sun placed at the moon's direction and the profile's
  solar spectrum replaced by the moon's irradiance above the atmosphere
  (:func:`skymodel.astro.lunar_irradiance.moon_irradiance`, ROLO): :func:`moon_profile`. The
  optical key leaves the solar spectrum out, so the sunlit and moonlit skies share one solve.
  It is marched while the moon is at or above the same lowest elevation as the sun and the sun
  is below :data:`NIGHT_SUN_BELOW_DEG`.
* **Night sources** (:func:`night_light`): the catalogue stars and the moon's disc as point
  sources of their irradiance (kept per pixel: ``sum(L Omega)`` grows by exactly ``E T``), and
  the natural glow of a dark site (Krisciunas & Schaefer 1991 eq. 2 with the atmosphere's own
  T(Z)/T(0)); all dimmed by the direct transmittance of the same atmosphere along each line of
  sight (:func:`slant_transmittance`). The moon's irradiance is weighted by the fraction of its
  disc above the horizon, so it sets over the two minutes its disc takes. The ground below the
  horizon is lit by the glow and the stars (Lambertian, the profile's albedo).

Day and night: while the sun is at or above :data:`NIGHT_SUN_BELOW_DEG` (the horizon) only the
moon's disc is drawn (the daytime moon is visible); the moonlit sky (under 2e-4 of the sunlit
sky at sun 0 in its darkest pixel, a full moon overhead), the stars and the glow (under 2e-6)
are left out (docs/night.md), so a daytime image differs
from the sunlit sky alone only in the moon's pixels.

Everything is computed in the caller's channels: a linear ``matrix`` (n_wl, K) applied to every
spectrum (CIE XYZ, Rec.709, or None for the spectra themselves), so a night frame never holds a
spectral cube it does not need; the caller adds the channels to its sunlit image and then applies
its per-pixel finish (a gamut fit), as :func:`skymodel.render.sky.render_sky_reduced` does.

:func:`moon_lamp` gives the numbers of a moon lamp (direction, strength in the sun lamp's scale,
colour, angular diameter) for renderers that light a scene with it (the Blender add-on).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace

import numpy as np

from skymodel import scene
from skymodel.colorimetry import K_M
from skymodel.astro.lunar_irradiance import illuminance_lux, moon_irradiance
from skymodel.astro.moon import MoonPosition, moon_position
from skymodel.astro.night_background import DARK_SKY_ZENITH_MAG_ARCSEC2, dark_sky_radiance
from skymodel.astro.night_sky import disc_fraction_above_horizon
from skymodel.astro.stars import star_irradiance, star_positions
from skymodel.numerics import trapezoid
from skymodel.render.cameras import Camera

__all__ = ["sunlit", "lowest_elevation_deg", "moonlit", "NIGHT_SUN_BELOW_DEG", "slant_transmittance",
           "TransmittanceTable", "moon_profile", "MoonLamp", "moon_lamp", "splat_points", "NightInfo",
           "night_light", "NIGHT_MODES", "night_active"]

#: The sun elevation [deg] below which the moonlit sky, the stars and the glow are drawn (above
#: it they are under 2e-4 of the sunlit sky; the moon's disc is drawn at any sun elevation).
NIGHT_SUN_BELOW_DEG = 0.0
#: Zenith-angle step [deg] of the transmittance table of the lines of sight.
TRANSMITTANCE_STEP_DEG = 0.25
#: Samples along each line of sight of :func:`slant_transmittance` (denser near the observer).
SLANT_STEPS = 256
#: The values of the ``night`` parameter (the registry's; :func:`night_active`).
NIGHT_MODES = ("auto", "off")


def lowest_elevation_deg() -> float:
    """The registry's lowest sun elevation [deg] (-18): the sunlit sky's bound, and the moon's."""
    return float(scene.parameter("sun_elevation").minimum)


def sunlit(sun_elevation_deg) -> bool:
    """Whether the sunlit sky is rendered: the sun at or above :func:`lowest_elevation_deg`."""
    return float(sun_elevation_deg) >= lowest_elevation_deg()


def moonlit(moon_elevation_deg, sun_elevation_deg) -> bool:
    """Whether the moonlit sky is marched: the moon at or above :func:`lowest_elevation_deg`
    and the sun below :data:`NIGHT_SUN_BELOW_DEG`."""
    return float(moon_elevation_deg) >= lowest_elevation_deg() and float(sun_elevation_deg) < NIGHT_SUN_BELOW_DEG


def night_active(mode, time_utc) -> bool:
    """Whether the night's light is drawn: ``mode`` ``auto`` (the registry's ``night``) with a
    date-time to place the moon and stars; never with ``off`` or without a time."""
    return scene.check("night", mode) == "auto" and time_utc is not None


# ----------------------------------------------------------------------------- transmittance


def slant_transmittance(profile, zenith_deg, observer_altitude_m: float = 0.0, n_steps: int = SLANT_STEPS):
    """Direct transmittance exp(-tau) (n, n_wl) from the top of the atmosphere to an observer
    ``observer_altitude_m`` [m] above the ground along zenith angles ``zenith_deg`` (n,) in
    0..90 [deg], through the spherical shells of ``profile`` (its extinction, linear between
    altitude nodes; a layered profile's own shells): ``n_steps`` samples along each line,
    spaced as the square of an even parameter (dense near the observer, where the air is),
    trapezoid rule. No refraction. Agrees with the marcher's sun-transmittance table to 0.3 %
    at the horizon and 0.03 % at the zenith (``tests/test_night.py``)."""
    z = np.radians(np.clip(np.atleast_1d(np.asarray(zenith_deg, float)), 0.0, 90.0))
    R, top = float(profile.planet_radius_m), float(profile.top_altitude_m)
    h0 = min(max(float(observer_altitude_m), 0.0), top)
    r0, r_top = R + h0, R + top
    mu = np.cos(z)
    d = -r0 * mu + np.sqrt(np.maximum(r0 * r0 * (mu * mu - 1.0) + r_top * r_top, 0.0))
    u = np.linspace(0.0, 1.0, int(n_steps))
    s = d[:, None] * u[None, :] ** 2  # (n, m) metres along each line
    h = np.minimum(np.sqrt(r0 * r0 + s * s + 2.0 * r0 * s * mu[:, None]) - R, top)
    wt = np.zeros_like(s)  # trapezoid weights of the samples
    ds = np.diff(s, axis=1)
    wt[:, 1:] += 0.5 * ds
    wt[:, :-1] += 0.5 * ds
    nodes = getattr(profile, "altitudes_m", None)
    if nodes is None:  # a layered profile: its own piecewise-constant sample
        tau = np.einsum("zm,zmw->zw", wt, profile.sample(h).extinction)
    else:  # linear between the altitude nodes: tau = W @ extinction, W the weights on the nodes
        nodes = np.asarray(nodes, float)
        hc = np.clip(h, nodes[0], nodes[-1])
        i = np.clip(np.searchsorted(nodes, hc, side="right") - 1, 0, nodes.size - 2)
        f = (hc - nodes[i]) / (nodes[i + 1] - nodes[i])
        rows = np.repeat(np.arange(z.size), u.size).reshape(z.size, u.size)
        weights = np.zeros((z.size, nodes.size))
        np.add.at(weights, (rows, i), wt * (1.0 - f))
        np.add.at(weights, (rows, i + 1), wt * f)
        tau = weights @ profile.extinction
    return np.exp(-tau)


class TransmittanceTable:
    """:func:`slant_transmittance` on a zenith grid 0..90 deg (:data:`TRANSMITTANCE_STEP_DEG`),
    read back by linear interpolation of the optical depth: ``table(zenith_deg (n,)) -> (n, n_wl)``."""

    def __init__(self, profile, observer_altitude_m: float = 0.0, step_deg: float = TRANSMITTANCE_STEP_DEG):
        self.zenith_deg = np.linspace(0.0, 90.0, int(round(90.0 / step_deg)) + 1)
        self.tau = -np.log(np.maximum(slant_transmittance(profile, self.zenith_deg, observer_altitude_m), 1e-300))

    def __call__(self, zenith_deg) -> np.ndarray:
        z = np.clip(np.atleast_1d(np.asarray(zenith_deg, float)), 0.0, 90.0)
        x = z / (self.zenith_deg[1] - self.zenith_deg[0])
        i = np.clip(x.astype(np.int64), 0, self.zenith_deg.size - 2)
        f = (x - i)[:, None]
        return np.exp(-(self.tau[i] * (1.0 - f) + self.tau[i + 1] * f))


# ----------------------------------------------------------------------------- the moon


def moon_profile(profile, moon: MoonPosition):
    """``profile`` with its solar spectrum replaced by the moon's irradiance above the
    atmosphere (W m^-2 nm^-1, ROLO): marched with the sun at the moon's place it gives the
    moonlit sky (same multiple-scattering solution: the optical key leaves the spectrum out)."""
    return replace(profile, solar_irradiance=np.asarray(moon_irradiance(moon, profile.wavelengths_nm), float))


@dataclass(frozen=True)
class MoonLamp:
    """A moon lamp in the scale of :mod:`skymodel.render.environment`'s sun lamp.

    ``strength`` [W m^-2, ybar-weighted; 1.0 = 683 lux] on a surface facing the moon at the
    observer: ROLO irradiance x direct transmittance x the fraction of the disc above the
    horizon (0 when set); ``colour`` scene-linear Rec.709 with luminance 1; ``angle_deg`` the
    disc's apparent diameter; azimuth clockwise from north."""

    elevation_deg: float
    azimuth_deg: float
    strength: float
    colour: tuple
    angle_deg: float
    illuminance_lux: float
    phase_angle_deg: float
    illuminated_fraction: float
    visible_fraction: float

    def lamp(self) -> dict:
        """The numbers as a JSON-friendly dict."""
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in self.__dict__.items()}


def _moon(latitude_deg, longitude_deg, time_utc, observer_altitude_m) -> MoonPosition:
    mp = moon_position(latitude_deg, longitude_deg, time_utc, altitude_m=float(observer_altitude_m))
    if np.ndim(mp.elevation_deg) != 0:
        from skymodel.errors import SkymodelInputError

        raise SkymodelInputError("time_utc", time_utc, "one date-time")
    return mp


def _ground_irradiance(profile, moon: MoonPosition, table=None) -> tuple[np.ndarray, float]:
    """``(E (n_wl,), disc fraction)``: the moon's irradiance at the observer (facing it)."""
    frac = float(disc_fraction_above_horizon(moon.elevation_deg, moon.angular_radius_deg))
    e = np.zeros(profile.wavelengths_nm.size)
    if frac > 0.0:
        zen = min(90.0 - float(moon.elevation_deg), 90.0)
        t = table([zen])[0] if table is not None else slant_transmittance(profile, [zen])[0]
        e = frac * t * np.asarray(moon_irradiance(moon, profile.wavelengths_nm), float)
    return e, frac


def moon_lamp(profile, latitude_deg, longitude_deg, time_utc, observer_altitude_m: float = 0.0, *,
              table: TransmittanceTable | None = None) -> MoonLamp:
    """The moon as a lamp for ``profile`` (an optical profile on any wavelength grid) at a
    place [deg] and UTC time: :class:`MoonLamp`. ``table``: a :class:`TransmittanceTable` of
    the profile and observer to reuse (None: the line of sight is integrated here)."""
    from skymodel.render.environment import sun_lamp  # the sun lamp's own colour rule

    mp = _moon(latitude_deg, longitude_deg, time_utc, observer_altitude_m)
    if table is None and observer_altitude_m:
        table = TransmittanceTable(profile, observer_altitude_m)
    e, frac = _ground_irradiance(profile, mp, table)
    strength, colour = sun_lamp(e, profile.wavelengths_nm)
    if strength <= 0.0:  # below the horizon: the colour of the moonlight above the atmosphere
        colour = sun_lamp(moon_irradiance(mp, profile.wavelengths_nm), profile.wavelengths_nm)[1]
    return MoonLamp(float(mp.elevation_deg), float(mp.azimuth_deg), float(strength), tuple(float(c) for c in colour),
                    2.0 * float(mp.angular_radius_deg), float(illuminance_lux(e, profile.wavelengths_nm)),
                    float(mp.phase_angle_deg), float(mp.illuminated_fraction), frac)


# ----------------------------------------------------------------------------- point sources


def splat_points(camera: Camera, directions, values, image, valid=None, solid_angles=None) -> np.ndarray:
    """Add point sources to ``image`` (H, W, K) of ``camera`` in place, keeping their energy:
    each source (unit vector ``directions`` (n, 3), irradiance ``values`` (n, K)) lands on the
    four pixels around :meth:`Camera.project`'s continuous position with bilinear weights
    (columns wrap for the panoramas; rows and fisheye columns clamp; weights of pixels outside
    ``valid`` go to the others), each pixel getting ``E w / Omega``: ``sum(L Omega)`` grows by
    exactly ``sum(E)`` for every source inside the image. Returns ``image``."""
    from skymodel.render.cameras import _PanoramaCamera

    d = np.asarray(directions, float).reshape(-1, 3)
    v = np.asarray(values, float).reshape(d.shape[0], -1)
    if d.shape[0] == 0:
        return image
    h, w = camera.shape
    valid = camera.valid_mask() if valid is None else valid
    omega = camera.pixel_solid_angles() if solid_angles is None else solid_angles
    xy, visible = camera.project(d)
    keep = visible & np.all(np.isfinite(xy), axis=-1)
    xy, v = xy[keep], v[keep]
    if xy.shape[0] == 0:
        return image
    wrap = isinstance(camera, _PanoramaCamera)
    x = xy[:, 0] if wrap else np.clip(xy[:, 0], 0.0, w - 1.0)
    y = np.clip(xy[:, 1], 0.0, h - 1.0)
    x0 = np.floor(x)
    fx = x - x0
    x0 = x0.astype(np.int64)
    x1 = x0 + 1
    if wrap:
        x0, x1 = x0 % w, x1 % w
    else:
        x0, x1 = np.minimum(x0, w - 1), np.minimum(x1, w - 1)
    y0 = np.minimum(np.floor(y).astype(np.int64), h - 1)
    fy = y - y0
    y1 = np.minimum(y0 + 1, h - 1)
    corners = [(y0, x0, (1 - fx) * (1 - fy)), (y0, x1, fx * (1 - fy)), (y1, x0, (1 - fx) * fy), (y1, x1, fx * fy)]
    ok = [valid[yy, xx] & (omega[yy, xx] > 0) for yy, xx, _ in corners]
    total = sum(np.where(o, wt, 0.0) for (_, _, wt), o in zip(corners, ok))
    for (yy, xx, wt), o in zip(corners, ok):
        share = np.where(o & (total > 0), wt / np.where(total > 0, total, 1.0), 0.0)
        np.add.at(image, (yy, xx), v * (share / np.where(o, omega[yy, xx], 1.0))[:, None])
    return image


def _add_disc(dirs, valid, omega, centre, values, radius_rad, image) -> None:
    """A uniform disc of angular radius ``radius_rad`` and total irradiance ``values`` (K,) into
    ``image``: :func:`skymodel.render.sky.add_sun_disc` without limb darkening, on the pixels
    near the disc (the nearest valid pixel when the disc falls between pixel centres)."""
    from skymodel.render.sky import add_sun_disc

    reach = 4 * radius_rad + 2.0 * float(np.sqrt(np.max(omega)))
    near = valid & (dirs @ centre > math.cos(min(reach, math.pi)))
    rows, cols = np.nonzero(near.any(axis=1))[0], np.nonzero(near.any(axis=0))[0]
    if rows.size == 0:
        return
    r0, r1, c0, c1 = rows[0], rows[-1] + 1, cols[0], cols[-1] + 1
    sub = np.zeros((r1 - r0, c1 - c0, values.size))
    add_sun_disc(sub, dirs[r0:r1, c0:c1], valid[r0:r1, c0:c1], omega[r0:r1, c0:c1], centre, values,
                 np.zeros(values.size), radius_rad)
    image[r0:r1, c0:c1] += sub


# ----------------------------------------------------------------------------- the night's light


@dataclass
class NightInfo:
    """What :func:`night_light` drew: the moon's place and phase, its illuminance at the
    observer [lux, facing it], whether the moonlit sky was marched, the stars drawn (above the
    horizon; 0 in daytime), timings [s]."""

    moon_elevation_deg: float
    moon_azimuth_deg: float
    moon_phase_angle_deg: float
    moon_illuminated_fraction: float
    moon_illuminance_lux: float
    moonlit_sky: bool
    stars_drawn: int
    timings: dict = field(default_factory=dict)

    def as_dict(self) -> dict:
        return dict(self.__dict__)

    def moon_horizontal_illuminance_y(self) -> float:
        """The moon's direct light on a horizontal plane at the observer [colour-scale units,
        683 lux = 1]: what a renderer that lights the scene with a moon lamp (the disc not in
        the image) adds to the incident meter of :mod:`skymodel.render.exposure`."""
        return self.moon_illuminance_lux / K_M * max(math.sin(math.radians(self.moon_elevation_deg)), 0.0)


def night_light(profile, camera: Camera, latitude_deg, longitude_deg, time_utc, matrix=None, *,
                sun_elevation_deg: float, observer_altitude_m: float = 0.0, quality=None, solution=None,
                solutions=None, include_moon_disc: bool = True,
                zenith_v_mag: float = DARK_SKY_ZENITH_MAG_ARCSEC2["V"], band_pixels: int = 1 << 20,
                progress=None) -> tuple[np.ndarray, NightInfo]:
    """The night's light in ``camera``'s pixels, in the channels of ``matrix`` (n_wl, K) (None:
    the spectra): the moonlit sky (when :func:`moonlit`), the glow, the stars and the ground
    they light (sun below :data:`NIGHT_SUN_BELOW_DEG`) and, with ``include_moon_disc``, the
    moon's disc (any sun elevation), each dimmed by the direct transmittance of ``profile``
    along its line of sight (module docstring). ``solution`` / ``solutions``: where the moonlit
    sky's multiple-scattering solution comes from, as in
    :func:`skymodel.render.sky.render_sky_reduced` (None, None: the process's shared cache; the
    sunlit render of the same profile fills it). Returns ``(image (H, W, K) linear, not
    finished; NightInfo)``; pixels with nothing to add are exactly 0."""
    from skymodel.render.sky import render_sky_reduced
    from skymodel.render.skyview import Reduction

    t0 = time.perf_counter()
    wl = profile.wavelengths_nm
    mat = None if matrix is None else np.asarray(matrix, float)
    k = wl.size if mat is None else mat.shape[1]

    def reduce(spectra):
        return spectra if mat is None else spectra @ mat

    mp = _moon(latitude_deg, longitude_deg, time_utc, observer_altitude_m)
    table = TransmittanceTable(profile, observer_altitude_m)
    timings = {"transmittance_s": time.perf_counter() - t0}
    dirs, valid = camera.directions()
    omega = camera.pixel_solid_angles()
    image = np.zeros(camera.shape + (k,))

    # the moonlit sky: the marcher with the moon for a sun (one solve serves both)
    lit = moonlit(mp.elevation_deg, sun_elevation_deg)
    if lit:
        t1 = time.perf_counter()
        moon_sky, _, _ = render_sky_reduced(moon_profile(profile, mp), camera, float(mp.elevation_deg),
                                            Reduction(mat, k), k, float(mp.azimuth_deg), observer_altitude_m,
                                            quality, band_pixels=band_pixels, progress=progress, solution=solution,
                                            solutions=solutions)
        image += moon_sky
        timings["moonlit_sky_s"] = time.perf_counter() - t1

    n_stars = 0
    if float(sun_elevation_deg) < NIGHT_SUN_BELOW_DEG:
        n_stars = _glow_stars_ground(profile, camera, latitude_deg, longitude_deg, time_utc, table, dirs, valid, omega,
                                     image, reduce, zenith_v_mag, timings)

    # the moon's disc: its irradiance at the observer (disc fraction above the horizon included)
    e_moon, _ = _ground_irradiance(profile, mp, table)
    if include_moon_disc and np.any(e_moon > 0):
        el, az = math.radians(max(float(mp.elevation_deg), 0.0)), math.radians(float(mp.azimuth_deg))
        centre = np.array([math.cos(el) * math.sin(az), math.cos(el) * math.cos(az), math.sin(el)])
        up = valid & (dirs[..., 2] >= 0.0)
        _add_disc(dirs, up, omega, centre, reduce(e_moon[None, :])[0], math.radians(float(mp.angular_radius_deg)),
                  image)
    timings["total_s"] = time.perf_counter() - t0
    info = NightInfo(float(mp.elevation_deg), float(mp.azimuth_deg), float(mp.phase_angle_deg),
                     float(mp.illuminated_fraction), float(illuminance_lux(e_moon, wl)), bool(lit), n_stars,
                     {name: round(v, 4) for name, v in timings.items()})
    return image, info


def _glow_stars_ground(profile, camera, latitude_deg, longitude_deg, time_utc, table, dirs, valid, omega, image, reduce,
                       zenith_v_mag, timings) -> int:
    """The glow, the stars and the ground they light, added to ``image`` (H, W, K); returns
    the number of stars above the horizon."""
    wl = profile.wavelengths_nm
    k = image.shape[-1]
    # the natural glow, per zenith angle, dimmed as the atmosphere dims
    t2 = time.perf_counter()
    up = valid & (dirs[..., 2] >= 0.0)
    zen_nodes = table.zenith_deg
    t_nodes = table(zen_nodes)
    glow_spec = dark_sky_radiance(wl, zen_nodes, zenith_v_mag=zenith_v_mag,
                                  transmittance_ratio=t_nodes / np.maximum(t_nodes[:1], 1e-300))  # (n_z, n_wl)
    glow = reduce(glow_spec)  # (n_z, K)
    zen_px = np.degrees(np.arccos(np.clip(dirs[up][:, 2], -1.0, 1.0)))
    image[up] += np.stack([np.interp(zen_px, zen_nodes, glow[:, c]) for c in range(k)], axis=-1)
    timings["glow_s"] = time.perf_counter() - t2

    # the stars: points above the horizon, their irradiance times the line of sight's transmittance
    t3 = time.perf_counter()
    sp = star_positions(latitude_deg, longitude_deg, time_utc)
    above = sp.elevation_deg >= 0.0
    el, az = np.radians(sp.elevation_deg[above]), np.radians(sp.azimuth_deg[above])
    e_star = star_irradiance(wl)[above] * table(90.0 - sp.elevation_deg[above])
    star_dirs = np.stack([np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el)], axis=-1)
    splat_points(camera, star_dirs, reduce(e_star), image, valid=up, solid_angles=omega)
    timings["stars_s"] = time.perf_counter() - t3

    # the ground lit by the glow and the stars (Lambertian, the profile's albedo): L = a E_h / pi,
    # E_h = 2 pi int glow(Z) cos Z sin Z dZ + sum E_star T sin(el); the air between the observer
    # and the ground is left out (the moonlit sky's own march lights the ground by the moon)
    down = valid & (dirs[..., 2] < 0.0)
    if np.any(down):
        zr = np.radians(zen_nodes)
        e_h = 2.0 * math.pi * trapezoid(glow_spec * (np.cos(zr) * np.sin(zr))[:, None], zr, axis=0)
        e_h = e_h + np.sum(e_star * np.sin(el)[:, None], axis=0)
        image[down] += reduce((np.asarray(profile.ground_albedo, float) * e_h / math.pi)[None, :])[0]
    return int(above.sum())
