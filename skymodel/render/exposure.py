"""The one exposure rule: how bright a rendered sky is shown, day and night.

Used by the Blender add-on's film exposure (through :mod:`skymodel.render.environment`),
the PNG of ``skymodel render`` and every frame of ``skymodel timelapse``, so the same
instant comes out at the same exposure in all three (docs/night.md "The exposure").

Scale
    Scene-linear Rec.709 (or CIE Y) from spectra with the CIE 1931 observer: a pixel's
    luminance ``Y = integral(L ybar dlambda)`` in W m^-2 sr^-1, **1.0 = 683 cd m^-2**; a
    lamp's strength ``E_Y = integral(E ybar dlambda)`` in W m^-2, 1.0 = 683 lux
    (:mod:`skymodel.render.environment`). An exposure X [stops] multiplies scene values by
    ``2**X`` before the view transform (Blender's film exposure; the PNG's tone curve).

The rule: two meters, the darker wins (:func:`display_exposure`)
    * **incident light** ``log2(pi / E_h)``: ``E_h`` the horizontal illuminance at the
      observer (direct sun ``E_Y sin(elevation)``, the moon's when it is a lamp, plus the
      sky's ``sum(Y cos(zenith) dOmega)`` over the upper hemisphere): a white horizontal
      Lambertian plate shows at 1.0, an 18 % card at 0.18. Right in daylight; at a low sun
      the sky is as bright as the ground it lights and this rule washes it to white;
    * **the sky meter**: the sky's solid-angle weighted log-average luminance ``L`` above
      the horizon is shown at :func:`sky_target` ``(L)``:

      - day and twilight, L >= :data:`NIGHT_KNEE_CD_M2` (3 cd m^-2, the clear sky at a sun
        near -5.3 degrees): ``SKY_KEY_SCALE * key(L)``, the automatic key of Krawczyk,
        Myszkowski & Seidel (2005), ``key = 1.03 - 2 / (2 + log10(L + 1))`` (L in cd m^-2),
        so dusk is shown darker than noon, as a dusk photograph is;
      - below the knee (nautical twilight and the night): ``target(knee) (L / knee)^(1/4)``
        (:data:`NIGHT_SLOPE`): the exposure opens up by only 3/4 of the stops the light
        falls, so a dimmer night is shown darker and a moonlit night brighter than a
        moonless one. Krawczyk's key instead flattens to 0.03 as L -> 0 and would show
        every night at the same level whatever the moon does.

    Both branches meet at the knee and ``sky_target`` rises more slowly than L (its
    log-slope is 0.03-0.37 above the knee, 0.25 below), so the exposure is continuous and
    strictly decreasing in the light, never by more stops than the light: a sequence whose
    light changes smoothly gets a smooth exposure (no jump at the knee, at -18 degrees or at
    moonrise). Measured figures (docs/night.md): the day
    sky shown at 0.18-0.19, a full moon high up at 0.015 (3.6 stops under the day's), a
    moonless night at 0.0073 (4.7 stops under).

A user offset is added by the caller (the add-on's Exposure Offset, ``--exposure``).

References
----------
G. Krawczyk, K. Myszkowski, H.-P. Seidel, "Lightness perception in tone reproduction for
high dynamic range images", Computer Graphics Forum 24(3), 2005, eq. 11.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["LUMA_709", "CANDELA_PER_UNIT", "SKY_KEY_SCALE", "NIGHT_KNEE_CD_M2", "NIGHT_SLOPE", "sky_key",
           "sky_target", "exposure_from_illuminance", "exposure_from_sky", "horizontal_illuminance",
           "sky_log_average", "display_exposure"]

#: Rec.709 luminance weights (Blender's scene-linear luminance).
LUMA_709 = np.array([0.2126, 0.7152, 0.0722])
#: One unit of the colour scale in cd m^-2 (Y = 1 <=> 683 cd m^-2).
CANDELA_PER_UNIT = 683.0
#: Scene value at which the sky's log-average luminance is shown, per unit of key
#: (:func:`sky_key`). The clear rural June sky at sun 30 degrees (log-average 4.55 units,
#: key 0.666) is shown at 0.172 by the incident rule and at 0.28 * 0.666 = 0.186 by the sky
#: meter, so the incident rule still sets the daylight exposure there (and above); the sky
#: meter takes over between sun 30 and 15 degrees and shows the sky at sun 0 degrees at
#: 0.28 * 0.59 = 0.166, no brighter than at 30 (measured figures in docs/blender.md).
SKY_KEY_SCALE = 0.28
#: Sky log-average luminance [cd m^-2] below which the night branch of :func:`sky_target`
#: holds: the clear sky at a sun near -5.3 degrees, toward the end of civil dusk (Zaragoza,
#: June evening: 17.6 cd m^-2 at -3.7 degrees, 0.52 at -6.6; docs/time.md).
NIGHT_KNEE_CD_M2 = 3.0
#: Log-slope of :func:`sky_target` below the knee: the exposure opens up by ``1 - NIGHT_SLOPE``
#: of the stops the light falls.
NIGHT_SLOPE = 0.25
#: Exposures are clamped to +-this many stops (a black image gets the bright end).
EXPOSURE_LIMIT_EV = 32.0


def _clamp(ev: float) -> float:
    return float(min(max(ev, -EXPOSURE_LIMIT_EV), EXPOSURE_LIMIT_EV))


def sky_key(log_average_y: float) -> float:
    """Key value of Krawczyk, Myszkowski & Seidel (2005) for a log-average luminance in the
    colour scale's units: ``1.03 - 2 / (2 + log10(683 L + 1))`` (0.16 at 1 cd m^-2, 0.67 at
    3000 cd m^-2), floored at 0.02."""
    lum = max(float(log_average_y), 0.0) * CANDELA_PER_UNIT
    return max(1.03 - 2.0 / (2.0 + math.log10(lum + 1.0)), 0.02)


def sky_target(log_average_y: float) -> float:
    """Scene value at which the sky meter shows a sky of log-average ``log_average_y``
    (colour-scale units): ``SKY_KEY_SCALE * sky_key(L)`` at and above
    :data:`NIGHT_KNEE_CD_M2`, ``target(knee) * (L / knee) ** NIGHT_SLOPE`` below (module doc).
    0 for no light."""
    y = max(float(log_average_y), 0.0)
    knee = NIGHT_KNEE_CD_M2 / CANDELA_PER_UNIT
    if y >= knee:
        return SKY_KEY_SCALE * sky_key(y)
    return SKY_KEY_SCALE * sky_key(knee) * (y / knee) ** NIGHT_SLOPE


def exposure_from_illuminance(e_h: float) -> float:
    """Exposure (stops) of the incident-light rule: ``log2(pi / E_h)``, in [-32, 32]; 0 when
    ``E_h`` is not a positive number."""
    if not e_h > 0.0 or not math.isfinite(e_h):
        return 0.0
    return _clamp(math.log2(math.pi / e_h))


def exposure_from_sky(log_average_y: float) -> float:
    """Exposure (stops) of the sky meter: shows ``log_average_y`` at :func:`sky_target`; in
    [-32, 32], the bright end for a black sky."""
    if not log_average_y > 0.0 or not math.isfinite(log_average_y):
        return EXPOSURE_LIMIT_EV
    return _clamp(math.log2(sky_target(log_average_y) / log_average_y))


#: Rows of pixels whose directions the meters hold at once (a 16384-px panorama's directions
#: would be 3 GiB).
BAND_PIXELS = 1 << 20


def _readings(image, camera) -> tuple[float, float]:
    """``(sum(Y cos(zenith) dOmega), log-average Y)`` over the pixels above the horizon (the
    second over those with Y > 0; 0 when there are none), by bands of rows. ``image``: (H, W)
    luminance or (H, W, 3) scene-linear Rec.709."""
    a = np.asarray(image)
    rgb = a.shape != tuple(camera.shape)
    omega = camera.pixel_solid_angles()
    rows = max(1, BAND_PIXELS // max(camera.width, 1))
    diffuse = log_sum = weight = 0.0
    for r0 in range(0, camera.height, rows):
        d, valid = camera.directions_rows(r0, min(r0 + rows, camera.height))
        y = np.asarray(a[r0:r0 + rows], dtype=float)
        if rgb:
            y = y @ LUMA_709
        w = omega[r0:r0 + rows]
        cos_z = d[..., 2]
        up = valid & (cos_z > 0)
        diffuse += float(np.sum(np.where(up, y * cos_z * w, 0.0)))
        lit = up & (y > 0)
        log_sum += float(np.sum(w[lit] * np.log(y[lit])))
        weight += float(np.sum(w[lit]))
    return diffuse, (math.exp(log_sum / weight) if weight > 0 else 0.0)


def _direct(strength: float, elevation_deg: float) -> float:
    """A lamp of ``strength`` at ``elevation_deg`` on a horizontal plane (0 below the horizon)."""
    return float(strength) * max(math.sin(math.radians(elevation_deg)), 0.0)


def horizontal_illuminance(image, camera, sun_strength: float, sun_elevation_deg: float) -> float:
    """E_h [colour-scale units]: the direct sun ``sun_strength sin(elevation)`` on a
    horizontal plane plus the sky's diffuse part ``sum(Y cos(zenith) dOmega)`` over the
    pixels above the horizon. ``image``: scene-linear Rec.709 (H, W, 3) or its luminance
    (H, W) in ``camera``'s pixels (a camera that sees the whole upper hemisphere); a sun
    disc drawn into it counts as diffuse light, so pass ``sun_strength`` 0 then."""
    return _readings(image, camera)[0] + _direct(sun_strength, sun_elevation_deg)


def sky_log_average(image, camera) -> float:
    """Solid-angle weighted log-average luminance of the sky above the horizon (units of the
    colour scale; 0 when there is none). ``image`` as for :func:`horizontal_illuminance`."""
    return _readings(image, camera)[1]


def display_exposure(image, camera, sun_strength: float, sun_elevation_deg: float,
                     extra_horizontal_illuminance: float = 0.0) -> dict:
    """The exposure of the module doc: the darker of the incident-light rule and the sky
    meter. ``image``: scene-linear Rec.709 (H, W, 3) or its luminance (H, W) in ``camera``'s
    pixels; ``sun_strength`` [colour-scale units]: the direct sun when it is a lamp (0 when
    its disc is drawn into the image); ``extra_horizontal_illuminance`` [colour-scale
    units]: light on the horizontal plane from another lamp not in the image (the moon's).
    Returns ``{"exposure", "exposure_incident", "exposure_sky", "horizontal_illuminance_Y",
    "sky_log_average_Y"}`` (stops and colour-scale units)."""
    diffuse, l_sky = _readings(image, camera)
    e_h = diffuse + _direct(sun_strength, sun_elevation_deg) + float(extra_horizontal_illuminance)
    incident, sky = exposure_from_illuminance(e_h), exposure_from_sky(l_sky)
    return {"exposure": min(incident, sky), "exposure_incident": incident, "exposure_sky": sky,
            "horizontal_illuminance_Y": e_h, "sky_log_average_Y": l_sky}
