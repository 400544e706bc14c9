"""The instants of a sequence of skies: a day (local times at a step) or a run of days
at one sun elevation (a year of dusks).

A day sequence (:func:`day_frames`) starts at ``time_from`` on ``date`` in ``timezone``
and steps in real (UTC) time by ``every`` up to ``time_to`` on the same date, as a
time-lapse camera does: across a daylight-saving change the local clock jumps but the
frames stay evenly spaced. A start or end that does not exist on that date (the hour the
clocks skip) or that happens twice is refused by :func:`skymodel.scene.resolve_time`.

A sequence of days (:func:`days_frames`) takes the dates ``first``, ``first + every``,
... up to ``last`` (``every`` in days, weeks or calendar months: a month step keeps the
day of the month, the 31st falling back to the month's last day) and, on each date, the
instant the sun crosses ``sun_elevation_deg`` going down (``dusk``) or up (``dawn``),
found on a 2-minute grid around the date's mean solar noon and refined by two secant
steps, then rounded to the second: the sun is then within about 0.005 degrees of the
elevation asked for (it moves at most 0.25 degrees a minute), and every frame is exactly
what ``skymodel render --time <that UTC instant>`` gives.

Every frame is a :class:`~skymodel.scene.SunPlacement` (UTC instant, local time and zone,
elevation, azimuth, Earth-sun distance, the UTC date's day of the year). Everything is
checked here, before any rendering: the step, the dates, the number of frames against the
registry's ``max_frames``, and every frame's sun above the sunlit sky's lowest elevation
(a frame below it is refused naming its local time, unless the sequence draws the night:
``allow_night``).
"""

from __future__ import annotations

import calendar
import datetime as _dt
import re

import numpy as np

from skymodel import scene
from skymodel import sun as _sun
from skymodel.errors import SkymodelInputError

__all__ = ["parse_every", "day_frames", "days_frames", "SECOND_UNITS", "CALENDAR_UNITS"]

#: Units of a step in real time, in seconds.
SECOND_UNITS = {"s": 1, "sec": 1, "min": 60, "m": 60, "h": 3600, "hour": 3600}
#: Units of a step between dates: days, or calendar months.
CALENDAR_UNITS = {"day": ("days", 1), "d": ("days", 1), "week": ("days", 7), "w": ("days", 7),
                  "month": ("months", 1), "mon": ("months", 1)}

_EVERY_ALLOWED = "a whole number and a unit: 30s, 10min, 1h (a day) or 1day, 1week, 1month (--dates)"


def parse_every(text) -> tuple[str, int]:
    """``"10min"`` -> ``("seconds", 600)``, ``"1month"`` -> ``("months", 1)``, ``"2week"``
    -> ``("days", 14)``; plural units and a space are accepted. Raises naming ``every``."""
    if text is None:
        raise SkymodelInputError("every", text, "a step between frames (required): " + _EVERY_ALLOWED)
    m = re.fullmatch(r"\s*(\d+)\s*([a-zA-Z]+?)s?\s*", str(text))
    if not m or int(m.group(1)) <= 0:
        raise SkymodelInputError("every", text, _EVERY_ALLOWED)
    n, unit = int(m.group(1)), m.group(2).lower()
    if unit in SECOND_UNITS:
        return "seconds", n * SECOND_UNITS[unit]
    if unit + "s" in SECOND_UNITS:  # "mins" stripped to "min"; "s" itself
        return "seconds", n * SECOND_UNITS[unit + "s"]
    if unit in CALENDAR_UNITS:
        kind, k = CALENDAR_UNITS[unit]
        return kind, n * k
    raise SkymodelInputError("every", text, _EVERY_ALLOWED)


def _date(parameter: str, text) -> _dt.date:
    try:
        d = _dt.date.fromisoformat(str(text).strip())
    except ValueError:
        raise SkymodelInputError(parameter, text, "an ISO 8601 date such as 2026-06-21") from None
    scene.check("year", d.year)
    return d


def _clock(parameter: str, text) -> _dt.time:
    if text is None:
        raise SkymodelInputError(parameter, text, "a local time HH:MM such as 19:00 (required with --date)")
    try:
        t = _dt.time.fromisoformat(str(text).strip())
    except ValueError:
        raise SkymodelInputError(parameter, text, "a local time HH:MM or HH:MM:SS such as 19:00") from None
    if t.tzinfo is not None:
        raise SkymodelInputError(parameter, text, "a local time without an offset (the zone is --timezone)")
    return t


def _resolve(parameter: str, when: _dt.datetime, timezone) -> scene.Instant:
    """:func:`skymodel.scene.resolve_time`, its errors naming ``parameter`` (``--from``/``--to``)."""
    try:
        return scene.resolve_time(when, timezone)
    except SkymodelInputError as exc:
        if exc.parameter != "time_utc":
            raise
        raise SkymodelInputError(parameter, exc.value, exc.allowed) from None


def _count_check(n: int, max_frames) -> None:
    limit = scene.check("max_frames", scene.default("max_frames") if max_frames is None else max_frames)
    if n > limit:
        raise SkymodelInputError("every", f"{n} frames", f"at most max_frames={limit} frames (a longer step, "
                                                         "a shorter span, or --max-frames)")


def _place(latitude_deg, longitude_deg, instant: scene.Instant, timezone, k: int, n: int,
           allow_night: bool = False) -> scene.SunPlacement:
    try:
        return scene.place_sun(latitude_deg, longitude_deg, instant.local_iso, timezone=timezone or "UTC",
                               allow_night=allow_night)
    except SkymodelInputError as exc:
        if exc.parameter != "time_utc":
            raise
        raise SkymodelInputError("time_to", f"frame {k + 1} of {n} at {instant.local_iso}",
                                 f"{exc.allowed}; end the sequence earlier") from None


def day_frames(latitude_deg, longitude_deg, date, time_from, time_to, every, timezone=None,
               max_frames=None, allow_night: bool = False) -> list[scene.SunPlacement]:
    """The frames of one day: ``date`` (ISO text) from ``time_from`` to ``time_to`` (local
    ``HH:MM`` in ``timezone``; None: UTC) every ``every`` (``10min``). ``time_to`` is
    included when the step lands on it. ``allow_night``: frames with the sun below the
    registry's lowest elevation are kept (their true elevation; the renderer skips the sunlit
    sky and draws the night's light, :mod:`skymodel.render.night`) instead of refused. Raises
    naming the parameter at fault."""
    timezone = scene.place_zone(timezone, latitude_deg, longitude_deg)
    kind, step = parse_every(every)
    if kind != "seconds":
        raise SkymodelInputError("every", every, "a step in seconds, minutes or hours for a day (--date); "
                                                 "days, weeks and months go with --dates")
    day = _date("date", date)
    t0, t1 = _clock("time_from", time_from), _clock("time_to", time_to)
    start = _resolve("time_from", _dt.datetime.combine(day, t0), timezone)
    end = _resolve("time_to", _dt.datetime.combine(day, t1), timezone)
    if end.utc < start.utc:
        raise SkymodelInputError("time_to", time_to, f"a time on {day} after --from {time_from}")
    n = int((end.utc - start.utc).total_seconds() // step) + 1
    _count_check(n, max_frames)
    tz = scene.time_zone(timezone) or _dt.timezone.utc
    out = []
    for k in range(n):
        utc = start.utc + _dt.timedelta(seconds=k * step)
        instant = scene.Instant(utc, utc.astimezone(tz), start.timezone)
        out.append(_place(latitude_deg, longitude_deg, instant, timezone, k, n, allow_night))
    return out


def _add_months(d: _dt.date, months: int) -> _dt.date:
    y, m = divmod(d.month - 1 + months, 12)
    year, month = d.year + y, m + 1
    return _dt.date(year, month, min(d.day, calendar.monthrange(year, month)[1]))


def _dates(first: _dt.date, last: _dt.date, kind: str, step: int) -> list[_dt.date]:
    out, k = [], 0
    while True:
        d = first + _dt.timedelta(days=k * step) if kind == "days" else _add_months(first, k * step)
        if d > last:
            return out
        out.append(d)
        k += 1


def _elevation(latitude_deg, longitude_deg, t: np.ndarray) -> np.ndarray:
    """Sun elevation [deg] at UTC instants ``t`` (datetime64[s] array)."""
    iso = np.datetime_as_string(t.astype("datetime64[s]"), unit="s")
    return np.asarray(_sun.solar_position(latitude_deg, longitude_deg, iso).elevation_deg, dtype=float)


def crossing(latitude_deg, longitude_deg, date: _dt.date, sun_elevation_deg: float, which: str = "dusk"):
    """The UTC instant (``datetime64[s]``) on ``date`` at which the sun crosses
    ``sun_elevation_deg`` going down (``dusk``) or up (``dawn``), within 12 hours after
    (dusk) or before (dawn) the date's mean solar noon at ``longitude_deg``; None when it
    does not cross (polar day or night)."""
    noon = np.datetime64(date.isoformat() + "T12:00:00") - np.timedelta64(int(round(longitude_deg * 240.0)), "s")
    offsets = np.arange(0, 12 * 3600 + 1, 120)
    t = noon + (offsets if which == "dusk" else -offsets[::-1]).astype("timedelta64[s]")
    el = _elevation(latitude_deg, longitude_deg, t) - sun_elevation_deg
    hit = np.nonzero((el[:-1] >= 0) & (el[1:] < 0))[0] if which == "dusk" else \
        np.nonzero((el[:-1] < 0) & (el[1:] >= 0))[0]
    if hit.size == 0:
        return None
    i = hit[0] if which == "dusk" else hit[-1]
    a, b = t[i], t[i + 1]
    fa, fb = el[i], el[i + 1]
    for _ in range(2):  # secant steps inside the bracket
        x = a + np.timedelta64(int(round(float(fa / (fa - fb)) * (b - a).astype(float))), "s")
        fx = float(_elevation(latitude_deg, longitude_deg, np.array([x]))[0] - sun_elevation_deg)
        if (fx >= 0) == (fa >= 0):
            a, fa = x, fx
        else:
            b, fb = x, fx
    return a if abs(fa) <= abs(fb) else b


def days_frames(latitude_deg, longitude_deg, dates, every, sun_elevation_deg, timezone=None, which="dusk",
                max_frames=None) -> list[scene.SunPlacement]:
    """The frames of a run of days at one sun elevation: ``dates`` ``"FIRST:LAST"`` (ISO
    dates) every ``every`` (``1month``, ``7day``, ``1week``), each at the instant the sun
    crosses ``sun_elevation_deg`` [deg] at dusk or dawn (``which``); local times reported
    in ``timezone``. Raises naming the parameter at fault (``dates`` for a date on which
    the sun does not cross that elevation)."""
    timezone = scene.place_zone(timezone, latitude_deg, longitude_deg)
    text = str(dates)
    if text.count(":") != 1:
        raise SkymodelInputError("dates", dates, "FIRST:LAST, two ISO dates (2026-01-15:2026-12-15)")
    first, last = (_date("dates", part) for part in text.split(":"))
    if last < first:
        raise SkymodelInputError("dates", dates, "FIRST:LAST with LAST on or after FIRST")
    kind, step = parse_every(every)
    if kind == "seconds":
        raise SkymodelInputError("every", every, "a step in days, weeks or months for --dates (1month, 7day)")
    elevation = scene.check("sun_elevation", sun_elevation_deg)
    which = scene.check("dusk_or_dawn", which)
    days = _dates(first, last, kind, step)
    _count_check(len(days), max_frames)
    tz = scene.time_zone(timezone) or _dt.timezone.utc
    out = []
    for k, d in enumerate(days):
        t = crossing(latitude_deg, longitude_deg, d, elevation, which)
        if t is None:
            raise SkymodelInputError("dates", d.isoformat(), f"dates on which the sun crosses {elevation:g} deg "
                                                             f"at latitude {latitude_deg:g} ({which}); it does "
                                                             "not on this one")
        utc = _dt.datetime.fromisoformat(str(t)).replace(tzinfo=_dt.timezone.utc)
        instant = scene.Instant(utc, utc.astimezone(tz), scene.resolve_time("2000-01-01T00:00", timezone).timezone)
        out.append(_place(latitude_deg, longitude_deg, instant, timezone, k, len(days)))
    return out
