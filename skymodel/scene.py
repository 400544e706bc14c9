"""Every user-facing parameter once, and the one function that places the sun.

A :class:`Parameter` holds what a user may set: its name, unit, default, allowed range or
names (with aliases), and one sentence of help. :data:`PARAMETERS` is the registry of all
of them; the command line (:mod:`skymodel.cli.options`), the Python signatures
(:class:`skymodel.optics.atmosphere.Atmosphere`, :func:`skymodel.render.sky.render_sky`),
the Blender add-on's properties (``blender_addon/props.py``) and the quality registry
(:mod:`skymodel.render.quality`) read their defaults, bounds and help from here, so a
number is typed in exactly one place.

>>> from skymodel import scene
>>> scene.parameter("sun_elevation").range_text()
'-18..90 deg'
>>> scene.check("month", 13)
Traceback (most recent call last):
...
skymodel.errors.SkymodelInputError: month=13 is not allowed: expected an integer in 1..12

The registry is read at call time everywhere (never copied at import), so replacing an
entry (``PARAMETERS["month"] = dataclasses.replace(...)``) changes the CLI, the Python
API and the add-on together; ``tests/test_scene.py`` checks that.

:func:`place_sun` is the single place where the sun is put in the sky, from a UTC date and
time at a place (through :func:`skymodel.sun.solar_position`) or from elevation/azimuth
angles; the CLI and the add-on both call it.

This is a base module: it imports only :mod:`skymodel.errors`, :mod:`skymodel.sun`,
:mod:`skymodel.data`, numpy and the standard library.
"""

from __future__ import annotations

import calendar
import datetime as _dt
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from skymodel import sun as _sun
from skymodel.data import load_toml
from skymodel.errors import SkymodelInputError

__all__ = ["Parameter", "PARAMETERS", "parameter", "default", "check", "SunPlacement", "place_sun",
           "time_iso", "month_of", "Instant", "resolve_time", "day_of_year"]


@dataclass(frozen=True)
class Parameter:
    """One user-facing parameter.

    Attributes
    ----------
    name : the name used in Python keywords, error messages and JSON (``"sun_elevation"``).
    unit : unit of the value (``"deg"``, ``"m"``, ``"DU"``, ``"nm"``, ``"px"``; ``""`` if none).
    help : one sentence saying what the parameter is.
    default : the value used when the user gives none; ``None`` means "derived", and
        ``default_note`` says from what (e.g. "the location's").
    minimum, maximum : inclusive bounds of a number (None: unbounded on that side).
    exclusive_minimum : the minimum itself is refused (``ozone_du`` > 0).
    integer : the value must be a whole number.
    choices : the canonical names a text value may take (case-insensitive).
    aliases : alternative names, as ``(alias, canonical)`` pairs.
    flag : the command-line option (``"--sun-elevation"``).
    default_note : what a ``None`` default stands for.
    suggested : a typical value, for interfaces that need a number in a field that is
        switched off by default (Blender's AOD field); not a default of the physics.
    soft_minimum, soft_maximum : the range a slider offers (Blender); the hard bounds apply.
    """

    name: str
    unit: str
    help: str
    default: Any = None
    minimum: float | None = None
    maximum: float | None = None
    exclusive_minimum: bool = False
    integer: bool = False
    choices: tuple = ()
    aliases: tuple = ()
    flag: str | None = None
    default_note: str = ""
    suggested: Any = None
    soft_minimum: float | None = None
    soft_maximum: float | None = None
    extra: dict = field(default_factory=dict, compare=False, hash=False)

    # ------------------------------------------------------------------ text
    @property
    def alias_map(self) -> dict[str, str]:
        """``{alias: canonical}``."""
        return dict(self.aliases)

    @property
    def is_number(self) -> bool:
        return not self.choices and (self.minimum is not None or self.maximum is not None)

    def range_text(self) -> str:
        """What is allowed, short: ``'-18..90 deg'``, ``'one of: preview, final, reference'``."""
        if self.choices:
            return "one of: " + ", ".join(self.choices)
        if self.minimum is None and self.maximum is None:
            return self.unit
        lo = "" if self.minimum is None else f"{self.minimum:g}"
        hi = "" if self.maximum is None else f"{self.maximum:g}"
        text = f"({lo}, {hi}]" if self.exclusive_minimum else f"{lo}..{hi}"
        return text + (f" {self.unit}" if self.unit else "")

    def allowed_text(self) -> str:
        """What is allowed, as an error message says it."""
        if self.choices:
            text = "one of: " + ", ".join(self.choices) + " (case-insensitive)"
            if self.aliases:
                text += "; aliases: " + ", ".join(sorted(self.alias_map))
            return text
        kind = "an integer" if self.integer else "a number"
        return f"{kind} in {self.range_text()}"

    def default_text(self) -> str:
        if self.default is None:
            return self.default_note or "none"
        return f"{self.default:g}" if isinstance(self.default, float) else str(self.default)

    def help_text(self) -> str:
        """The help of a command-line option: the sentence, the range and the default."""
        allowed = self.range_text()
        return f"{self.help} ({allowed + '; ' if allowed else ''}default {self.default_text()})"

    # ------------------------------------------------------------------ checking
    def check(self, value):
        """Return ``value`` validated (a float, an int or the canonical name); ``None``
        passes when the default is ``None`` (derived). Raises
        :class:`~skymodel.errors.SkymodelInputError` naming the parameter and the range."""
        if value is None and self.default is None:
            return None
        if self.choices:
            key = str(value).strip().lower()
            key = self.alias_map.get(key, key)
            for c in self.choices:
                if key == str(c).lower():
                    return c
            raise SkymodelInputError(self.name, value, self.allowed_text())
        if isinstance(value, bool):
            raise SkymodelInputError(self.name, value, self.allowed_text())
        try:
            v = float(value)
        except (TypeError, ValueError):
            raise SkymodelInputError(self.name, value, self.allowed_text()) from None
        ok = math.isfinite(v) or (self.maximum is None and v == math.inf)
        if self.minimum is not None:
            ok = ok and (v > self.minimum if self.exclusive_minimum else v >= self.minimum)
        if self.maximum is not None:
            ok = ok and v <= self.maximum
        if self.integer:
            ok = ok and v == int(v)
        if not ok:
            raise SkymodelInputError(self.name, value, self.allowed_text())
        return int(v) if self.integer else v


# ---------------------------------------------------------------------------- the registry


def _location_names() -> tuple:
    return tuple(load_toml("presets/locations.toml")["locations"])


#: The aerosol models' type files (their meaning: :mod:`skymodel.optics.aerosols`); the first is the default.
_AEROSOL_MODEL_FILES = {"guimera2018": "presets/aerosols/paper.toml", "opac": "presets/aerosols/types.toml"}


def _aerosol_names() -> tuple:
    """Tropospheric types of every aerosol model (each model checks its own)."""
    names: list[str] = []
    for f in _AEROSOL_MODEL_FILES.values():
        names += [n for n, t in load_toml(f)["types"].items() if t["regime"] == "troposphere" and n not in names]
    return tuple(names) + ("none",)


def _aerosol_aliases() -> tuple:
    al: dict[str, str] = {}
    for f in _AEROSOL_MODEL_FILES.values():
        for k, v in load_toml(f).get("aliases", {}).items():
            al.setdefault(k, v)
    return tuple(sorted(al.items()))


def _surface_names() -> tuple:
    return tuple(load_toml("presets/surfaces.toml")["surfaces"])


#: The names of the quality presets (their meaning: :mod:`skymodel.render.quality`).
QUALITY_NAMES = ("preview", "final", "reference")

_P = Parameter
_ALL = [
    # ---- where
    _P("location", "", "location preset: latitude, longitude, aerosol type and ground (`skymodel presets`)",
       default="rural", choices=_location_names(), flag="--location"),
    _P("latitude", "deg", "latitude, degrees north", minimum=-90.0, maximum=90.0, flag="--lat",
       default_note="the location's", suggested=45.0),
    _P("longitude", "deg", "longitude, degrees east", minimum=-180.0, maximum=180.0, flag="--lon",
       default_note="the location's", suggested=0.0),
    # ---- when
    _P("month", "", "month of the year (selects the ozone climatology)", default=6, minimum=1, maximum=12,
       integer=True, flag="--month"),
    _P("time_utc", "", "UTC date-time, ISO 8601 (2026-06-21T12:00:00Z): places the sun at the location and "
       f"sets the month; years {_sun.SUPPORTED_YEARS[0]}..{_sun.SUPPORTED_YEARS[1]}", flag="--time",
       default_note="none (the sun from its elevation and azimuth)"),
    _P("day_of_year", "", "day of the year, 1 = 1 January (selects the ozone climatology, interpolated "
       "between mid-month values; with --time, the date's)", minimum=1, maximum=366,
       default_note="the month's mean"),
    _P("timezone", "", "time zone of --time when it has no offset: an IANA name (Europe/Madrid, daylight "
       "saving applied; data from the tzdata package), UTC, an offset such as +02:00, or auto (the zone at "
       "the latitude/longitude, found offline; needs the optional timezonefinder package; at sea the "
       "nautical zone Etc/GMT+N)", flag="--timezone",
       default_note="UTC (a --time without an offset is UTC)"),
    _P("year", "", "year of the date (UTC)", default=2026, minimum=_sun.SUPPORTED_YEARS[0],
       maximum=_sun.SUPPORTED_YEARS[1], integer=True),
    _P("day", "", "day of the month (UTC)", default=21, minimum=1, maximum=31, integer=True),
    _P("hour", "h", "hour of the day, UTC", default=12, minimum=0, maximum=23, integer=True),
    _P("minute", "min", "minute of the hour", default=0, minimum=0, maximum=59, integer=True),
    # ---- sequences (skymodel timelapse, the add-on's animation)
    _P("date", "", "local date of a day sequence, ISO 8601 (2026-06-21), read in --timezone", flag="--date",
       default_note="none (give --date with --from/--to, or --dates)"),
    _P("time_from", "", "local time of a day sequence's first frame (19:00)", flag="--from",
       default_note="none (required with --date)"),
    _P("time_to", "", "local time of a day sequence's last frame (22:30; included when the step lands on it)",
       flag="--to", default_note="none (required with --date)"),
    _P("every", "", "step between frames: a whole number and a unit (30s, 10min, 1h; 1day, 1week, 1month "
       "for --dates)", flag="--every", default_note="none (required)"),
    _P("dates", "", "first and last date of a sequence of days at one sun elevation, FIRST:LAST "
       "(2026-01-15:2026-12-15)", flag="--dates", default_note="none (a day sequence: --date)"),
    _P("max_frames", "", "largest number of frames a sequence may have (checked before any work)", default=2000,
       minimum=1, maximum=100_000, integer=True, flag="--max-frames"),
    _P("frame_rate", "fps", "frames per second of the sequence's video", default=12, minimum=1, maximum=120,
       integer=True, flag="--fps"),
    _P("exposure_curve", "", "exposure of a sequence's previews: follow = each frame's own display exposure "
       "(skymodel.render.exposure, the add-on's: the night darker than the day), fixed = one exposure for every "
       "frame (a year at one sun elevation: the colours compare)", default="follow", choices=("follow", "fixed"),
       flag="--exposure-curve"),
    _P("dusk_or_dawn", "", "which crossing of --sun-elevation a sequence of days uses", default="dusk",
       choices=("dusk", "dawn"), flag="--crossing"),
    # ---- air
    _P("site_altitude", "m", "height of the ground above sea level: the atmosphere starts there (Rayleigh "
       "and ozone from the standard atmosphere at that height, aerosols from their ground concentration; "
       "-430 m: the Dead Sea shore, 9000 m: above Everest's summit)",
       minimum=-430.0, maximum=9_000.0, flag="--site-altitude", default_note="the location's (0 without a preset)",
       suggested=0.0, soft_maximum=5_000.0),
    _P("aerosol_model", "", "aerosol model: guimera2018 = the paper's (Table 1 mixtures, Jaenicke sizes, "
       "Eq. 12 profile), opac = OPAC mixtures (Hess et al. 1998)", default=tuple(_AEROSOL_MODEL_FILES)[0],
       choices=tuple(_AEROSOL_MODEL_FILES), aliases=(("paper", "guimera2018"),), flag="--aerosol-model"),
    _P("aerosol", "", "tropospheric aerosol type, or none for clean air", choices=_aerosol_names(),
       aliases=_aerosol_aliases(), flag="--aerosol", default_note="the location's"),
    _P("aod550", "", "aerosol optical depth of the tropospheric aerosol at 550 nm (exclusive with turbidity)",
       minimum=0.0, maximum=10.0, flag="--aod550", default_note="the aerosol type's", suggested=0.2,
       soft_maximum=2.0),
    _P("turbidity", "", "turbidity: Preetham et al.'s (1999) ratio (tau_Rayleigh + tau_aerosol) / "
       "tau_Rayleigh at 550 nm (not the Linke turbidity factor)", minimum=1.0,
       maximum=64.0, flag="--turbidity", default_note="the aerosol type's", suggested=2.5, soft_maximum=10.0),
    _P("stratospheric", "", "stratospheric aerosol", default="background",
       choices=("background", "volcanic", "none"), flag="--stratospheric"),
    _P("stratospheric_aod550", "", "optical depth of the stratospheric aerosol at 550 nm", minimum=0.0,
       maximum=2.0, default_note="the stratospheric type's"),
    _P("ozone_du", "DU", "total ozone column", minimum=0.0, maximum=1000.0, exclusive_minimum=True,
       flag="--ozone-du", default_note="the monthly climatology at the latitude", suggested=300.0,
       soft_minimum=100.0, soft_maximum=500.0),
    _P("albedo", "", "ground albedo (Lambertian, grey)", minimum=0.0, maximum=1.0, flag="--albedo",
       default_note="the location's surface", suggested=0.2),
    _P("surface", "", "ground surface whose albedo is used", choices=_surface_names(),
       default_note="the location's"),
    _P("n_altitudes", "", "points of the altitude grid (0..100 km, denser near the ground)", default=401,
       minimum=16, maximum=100_000, integer=True, flag="--altitudes"),
    _P("layers", "", "piecewise-constant layers of the atmosphere to print", minimum=1, maximum=64,
       integer=True, flag="--layers", default_note="none"),
    # ---- sun and observer
    _P("sun_elevation", "deg", "elevation of the sun's centre above the horizon (below -18, the end of "
       "astronomical dusk, the sunlit sky is zero: only the night's sources remain, given a --time)",
       default=25.0, minimum=-18.0, maximum=90.0, flag="--sun-elevation"),
    _P("night", "", "the night's own light with a --time: auto = the moon's disc at any sun elevation, and the "
       "moonlit sky, the stars and the natural glow while the sun is below the horizon; below -18 the sunlit sky "
       "is skipped (docs/night.md); off = the sunlit sky only", default="auto", choices=("auto", "off"),
       flag="--night"),
    _P("sun_azimuth", "deg", "azimuth of the sun, clockwise from north (east 90)", default=180.0,
       minimum=-360.0, maximum=360.0, flag="--sun-azimuth"),
    _P("observer_altitude", "m", "height of the viewpoint above the ground", default=0.0, minimum=0.0,
       maximum=120_000.0, flag="--observer-altitude", soft_maximum=20_000.0),
    # ---- rendering
    _P("quality", "", "accuracy preset of the renderer (skymodel.render.quality); the default, preview, "
       "is the interactive one (seconds at 512x256, at worst about 1 % median radiance error against a "
       "Monte Carlo truth) and is the same for "
       "the Python API, every command and the Blender add-on", default="preview", choices=QUALITY_NAMES,
       flag="--quality"),
    _P("camera", "", "projection of the image", default="equirectangular",
       choices=("equirectangular", "fisheye", "dome"), flag="--camera"),
    _P("image_width", "px", "image width (height from the camera: equirectangular width / 2)", default=512,
       minimum=1, maximum=16384, integer=True, flag="--size"),
    _P("environment_width", "px", "Blender environment image width, 0 = the quality's", default=0, minimum=0,
       maximum=8192, integer=True, soft_maximum=4096),
    _P("wavelength_step", "nm", "spectral sampling of the render", default=5.0, minimum=1.0, maximum=50.0,
       flag="--wavelength-step"),
    _P("volume_layers", "", "nested atmosphere volumes of Blender's Volumetric mode", default=8, minimum=1,
       maximum=24, integer=True, soft_maximum=16),
    _P("exposure_ev", "EV", "exposure of the PNG preview in stops added to the display exposure "
       "(skymodel.render.exposure)", minimum=-64.0, maximum=64.0, flag="--exposure",
       default_note="0 (the display exposure)"),
    _P("max_memory", "GiB", "largest estimated peak memory a render may need (skymodel.render.memory: the "
       "quality's tables, the marching bands and the image); a render over it is refused before it starts",
       default=4.0, minimum=0.0, maximum=4096.0, exclusive_minimum=True, flag="--max-memory"),
    _P("view_zenith", "deg", "zenith angle of a view direction", minimum=0.0, maximum=180.0,
       flag="--view-zenith"),
    _P("compare_size", "px", "panel size of `skymodel compare` (fisheye)", default=128, minimum=16,
       maximum=1024, integer=True, flag="--size"),
    _P("compare_wavelength_step", "nm", "spectral sampling of `skymodel compare`", default=10.0, minimum=1.0,
       maximum=50.0, flag="--wavelength-step"),
]

#: The registry: parameter name -> :class:`Parameter`.
PARAMETERS: dict[str, Parameter] = {p.name: p for p in _ALL}
del _P, _ALL


def parameter(name: str) -> Parameter:
    """The registry's entry ``name`` (raises ``KeyError`` listing the names)."""
    try:
        return PARAMETERS[name]
    except KeyError:
        raise KeyError(f"unknown parameter {name!r}; known: {', '.join(PARAMETERS)}") from None


def default(name: str):
    """The default of parameter ``name`` (``None``: derived, see its ``default_note``)."""
    return parameter(name).default


def check(name: str, value):
    """Validate ``value`` against the registry entry ``name``; returns it as a float, an
    int or the canonical name. Raises :class:`~skymodel.errors.SkymodelInputError` naming
    the parameter and its allowed range."""
    return parameter(name).check(value)


# ---------------------------------------------------------------------------- the sun


@dataclass(frozen=True)
class SunPlacement:
    """Where the sun is: elevation [deg] above the horizon, azimuth [deg] clockwise from
    north in [0, 360), the Earth-sun distance [AU] (1 without a date), the date as ISO 8601
    UTC text, its month and day of the year (UTC), and the local time and zone it was
    given in (None without a date)."""

    elevation_deg: float
    azimuth_deg: float
    earth_sun_distance_au: float = 1.0
    time_utc: str | None = None
    month: int | None = None
    time_local: str | None = None  #: the wall-clock time with its offset (``2026-06-21T21:30:00+02:00``)
    timezone: str | None = None  #: the zone it was read in (``Europe/Madrid``, ``UTC``, ``+02:00``)
    day_of_year: int | None = None  #: the UTC date's day of the year, 1..366 (selects the ozone)


def _datetime_from_fields(fields) -> _dt.datetime:
    """``(year, month, day, hour, minute)`` as a naive :class:`datetime.datetime`, each field
    checked against the registry (a bad one raises naming ``year``, ``month``, ``day``, ...; a
    day past the month's last names the month's days)."""
    try:
        year, month, day, hour, minute = fields
    except ValueError:
        raise SkymodelInputError("time_utc", fields, "(year, month, day, hour, minute)") from None
    year, month = check("year", year), check("month", month)
    last = calendar.monthrange(year, month)[1]
    day = check("day", day)
    if day > last:
        raise SkymodelInputError("day", day, f"a day 1..{last} for {year}-{month:02d}")
    return _dt.datetime(year, month, day, check("hour", hour), check("minute", minute))


def time_iso(time_utc) -> str:
    """``time_utc`` as ISO 8601 UTC text (``2026-06-21T12:00:00Z``).

    Parameters
    ----------
    time_utc : ISO 8601 text, a :class:`datetime.datetime` / numpy ``datetime64`` (UTC),
        or the fields ``(year, month, day, hour, minute)`` [UTC], each checked against
        the registry (a bad field raises naming ``year``, ``month``, ``day``, ...).
    """
    if isinstance(time_utc, (tuple, list)):
        return _datetime_from_fields(time_utc).strftime("%Y-%m-%dT%H:%M:00Z")
    t = _sun.as_utc_datetime64(str(time_utc).strip() if isinstance(time_utc, str) else time_utc)
    if t.ndim:
        raise SkymodelInputError("time_utc", time_utc, "one date-time")
    return str(np.datetime_as_string(t, unit="s")) + "Z"


def month_of(time_utc) -> int | None:
    """The month (1..12) of a date-time accepted by :func:`time_iso`; None for None."""
    if time_utc is None:
        return None
    return int(time_iso(time_utc)[5:7])


@dataclass(frozen=True)
class Instant:
    """A moment: ``utc`` (aware, UTC) and ``local`` (aware, in ``timezone``) datetimes;
    ``timezone`` is the zone's name (``Europe/Madrid``, ``UTC`` or an offset ``+02:00``)."""

    utc: _dt.datetime
    local: _dt.datetime
    timezone: str

    @property
    def utc_iso(self) -> str:
        """``2026-06-21T19:30:00Z``."""
        return self.utc.strftime("%Y-%m-%dT%H:%M:%SZ")

    @property
    def local_iso(self) -> str:
        """``2026-06-21T21:30:00+02:00``."""
        return self.local.isoformat(timespec="seconds")


_OFFSET_TEXT = "an IANA time zone name (Europe/Madrid), UTC, or an offset such as +02:00"


def time_zone(name) -> _dt.tzinfo | None:
    """The zone named ``name``: an IANA name (read with :mod:`zoneinfo`, data from the
    system or the ``tzdata`` package), ``UTC``/``Z``, or a fixed offset (``+02:00``,
    ``-0530``, ``UTC+2``). None for None. Raises naming ``timezone``."""
    if name is None or isinstance(name, _dt.tzinfo):
        return name
    text = str(name).strip()
    if not text:
        raise SkymodelInputError("timezone", name, _OFFSET_TEXT)
    if text.lower() == AUTO_ZONE:
        raise SkymodelInputError("timezone", name, "an explicit zone here; auto needs the place (latitude and "
                                                   "longitude, resolved with place_zone)")
    if text.upper() in ("UTC", "Z", "GMT"):
        return _dt.timezone.utc
    offset = text[3:] if text.upper().startswith(("UTC", "GMT")) else text
    if offset[:1] in "+-" and offset[1:2].isdigit():
        sign = -1 if offset[0] == "-" else 1
        body = offset[1:].replace(":", "")
        try:
            hours, minutes = (int(body[:-2] or 0), int(body[-2:])) if len(body) > 2 else (int(body), 0)
        except ValueError:
            raise SkymodelInputError("timezone", name, _OFFSET_TEXT) from None
        if hours > 14 or minutes > 59:
            raise SkymodelInputError("timezone", name, "an offset within -14:00..+14:00")
        return _dt.timezone(sign * _dt.timedelta(hours=hours, minutes=minutes))
    import zoneinfo

    try:
        return zoneinfo.ZoneInfo(text)
    except (zoneinfo.ZoneInfoNotFoundError, ValueError):
        raise SkymodelInputError("timezone", name, _OFFSET_TEXT + " (not found in the IANA database)") from None


AUTO_ZONE = "auto"  #: the ``timezone`` value that means "the zone at the place"


def zone_at(latitude_deg, longitude_deg) -> str:
    """The IANA time zone at a place [deg north, deg east], found offline with the
    optional ``timezonefinder`` package (its bundled boundary data): ``Europe/Madrid`` for
    Zaragoza; at sea the nautical zone ``Etc/GMT+N`` (POSIX sign: ``Etc/GMT+2`` is UTC-2).
    Raises naming ``timezone`` when the package is missing or finds no zone, and naming
    ``latitude``/``longitude`` for a place out of range."""
    lat, lon = check("latitude", latitude_deg), check("longitude", longitude_deg)
    try:
        from timezonefinder import TimezoneFinder
    except ImportError:
        raise SkymodelInputError("timezone", AUTO_ZONE, "an explicit zone (Europe/Madrid, UTC, +02:00): 'auto' "
                                                        "needs the optional package timezonefinder "
                                                        "(pip install 'skymodel[timezone]')") from None
    global _FINDER
    if _FINDER is None:
        _FINDER = TimezoneFinder()
    name = _FINDER.timezone_at(lat=float(lat), lng=float(((lon + 180.0) % 360.0) - 180.0))
    if not name:
        raise SkymodelInputError("timezone", AUTO_ZONE, f"an explicit zone: none found at {lat:g}, {lon:g}")
    return str(name)


_FINDER = None


def place_zone(timezone, latitude_deg=None, longitude_deg=None):
    """``timezone`` with ``auto`` replaced by :func:`zone_at` of the place (other values
    unchanged). Raises naming ``timezone`` for ``auto`` without a latitude and longitude."""
    if not (isinstance(timezone, str) and timezone.strip().lower() == AUTO_ZONE):
        return timezone
    if latitude_deg is None or longitude_deg is None:
        raise SkymodelInputError("timezone", timezone, "an explicit zone, or auto together with a latitude and "
                                                       "longitude")
    return zone_at(latitude_deg, longitude_deg)


def _zone_name(tz) -> str:
    if tz is _dt.timezone.utc:
        return "UTC"
    key = getattr(tz, "key", None)
    if key:
        return key
    off = tz.utcoffset(None)
    total = int(off.total_seconds() // 60)
    return f"{'-' if total < 0 else '+'}{abs(total) // 60:02d}:{abs(total) % 60:02d}"


def _parse_datetime(value) -> _dt.datetime:
    """A date-time as a :class:`datetime.datetime` (naive, or aware when it has an offset)."""
    if isinstance(value, (tuple, list)):
        return _datetime_from_fields(value)
    if isinstance(value, _dt.datetime):
        return value
    if isinstance(value, _dt.date):
        return _dt.datetime(value.year, value.month, value.day)
    if isinstance(value, np.datetime64):
        value = np.datetime_as_string(value.astype("datetime64[us]"), unit="us")
    if isinstance(value, str):
        try:
            return _dt.datetime.fromisoformat(value.strip())
        except ValueError:
            pass
    raise SkymodelInputError("time_utc", value, "an ISO 8601 date-time (2026-06-21T21:30, with an optional "
                                                "offset +02:00 or Z)")


def resolve_time(time, timezone=None, latitude_deg=None, longitude_deg=None) -> Instant:
    """The instant a date-time names, read in ``timezone``.

    Parameters
    ----------
    time : ISO 8601 text (``2026-06-21T21:30``, ``2026-06-21T21:30+02:00``, ``...Z``), a
        :class:`datetime.datetime`, numpy ``datetime64`` (naive), or the fields ``(year,
        month, day, hour, minute)``.
    timezone : where a time without an offset is read (:func:`time_zone`: IANA name,
        ``UTC`` or a fixed offset; ``auto``: the zone at ``latitude_deg``/``longitude_deg``,
        :func:`zone_at`); None: such a time is UTC. A time with an offset and
        a zone must agree (the offset then picks one of the two readings of a repeated hour).
    latitude_deg, longitude_deg : the place [deg], only used by ``timezone="auto"``.

    Raises
    ------
    SkymodelInputError
        naming ``time_utc`` for a local time that does not exist (skipped when the clocks
        go forward) or happens twice (when they go back; give the offset to choose), for
        an offset that is not the zone's at that moment, and for years outside the range
        :func:`skymodel.sun.solar_position` supports; naming ``timezone`` for an unknown zone.
    """
    tz = time_zone(place_zone(timezone, latitude_deg, longitude_deg))
    dt = _parse_datetime(time)
    text = time if isinstance(time, str) else dt.isoformat()
    if dt.tzinfo is not None and dt.utcoffset() is not None:
        if tz is None:
            tz = _dt.timezone(dt.utcoffset())
        elif dt.astimezone(tz).utcoffset() != dt.utcoffset():
            raise SkymodelInputError("time_utc", text, f"the offset of {_zone_name(tz)} at that moment "
                                                       f"({dt.astimezone(tz).isoformat(timespec='minutes')[-6:]}), "
                                                       "or no offset")
        local = dt.astimezone(tz)
    else:
        tz = tz or _dt.timezone.utc
        first, second = dt.replace(tzinfo=tz, fold=0), dt.replace(tzinfo=tz, fold=1)
        if first.utcoffset() != second.utcoffset():
            back = first.astimezone(_dt.timezone.utc).astimezone(tz).replace(tzinfo=None)
            name = _zone_name(tz)
            if back != dt:
                raise SkymodelInputError(
                    "time_utc", text, f"a local time that exists in {name}: {dt:%Y-%m-%d %H:%M} is skipped there "
                                      "(the clocks go forward for daylight saving)")
            raise SkymodelInputError(
                "time_utc", text, f"an unambiguous local time in {name}: {dt:%Y-%m-%d %H:%M} happens twice there "
                                  f"(the clocks go back); give the offset: {first.isoformat(timespec='minutes')} or "
                                  f"{second.isoformat(timespec='minutes')}")
        local = first
    utc = local.astimezone(_dt.timezone.utc)
    time_iso(utc.replace(tzinfo=None))  # the supported years
    return Instant(utc, local, _zone_name(tz))


def day_of_year(time_utc) -> int | None:
    """The day of the year (1..366) of a UTC date-time accepted by :func:`time_iso`; None for None."""
    if time_utc is None:
        return None
    return int(_dt.date.fromisoformat(time_iso(time_utc)[:10]).timetuple().tm_yday)


def place_sun(latitude_deg=None, longitude_deg=None, time_utc=None, elevation_deg=None,
              azimuth_deg=None, timezone=None, allow_night: bool = False) -> SunPlacement:
    """Place the sun: from a date-time at a place, or from elevation and azimuth.

    Parameters
    ----------
    latitude_deg, longitude_deg : the place [deg north, deg east]; needed with ``time_utc``.
    time_utc : a date-time accepted by :func:`resolve_time` (text with or without an
        offset, datetime, or ``(year, month, day, hour, minute)``), or None to use the angles.
    timezone : the zone a time without an offset is read in (IANA name such as
        ``Europe/Madrid``, ``UTC``, ``+02:00``, or ``auto``: the zone at the place,
        :func:`zone_at`, reported in the result's ``timezone``); None: UTC. Daylight saving applies;
        a skipped or repeated local time is refused (:func:`resolve_time`).
    allow_night : with ``time_utc``: False (default) refuses a time when the sun is below the
        registry's lowest ``sun_elevation`` (-18 deg: night); True returns it with the sun's
        true elevation (down to -90), for renderers that skip the sunlit sky there and draw
        the night's own light (:func:`skymodel.render.night.sunlit`). Angles given directly
        are always checked against the registry.
    elevation_deg : sun elevation [deg]; default the registry's ``sun_elevation``.
    azimuth_deg : sun azimuth [deg] clockwise from north; default the registry's
        ``sun_azimuth``; returned modulo 360.

    Returns
    -------
    SunPlacement

    Raises
    ------
    SkymodelInputError
        naming ``timezone`` for a zone given without a time; naming ``time_utc`` when
        both a time and angles are given, for a local time that is skipped or repeated in
        its zone, or when the date puts
        the sun below the lowest elevation allowed (night); naming ``sun_elevation`` /
        ``sun_azimuth`` for angles out of range.

    References
    ----------
    The position: :func:`skymodel.sun.solar_position` (NOAA / Meeus), without refraction.
    """
    lowest = parameter("sun_elevation").minimum
    if time_utc is not None:
        if elevation_deg is not None or azimuth_deg is not None:
            raise SkymodelInputError("time_utc", time_utc,
                                     "either a time or a sun elevation/azimuth, not both")
        instant = resolve_time(time_utc, timezone, latitude_deg, longitude_deg)
        iso = instant.utc_iso
        pos = _sun.solar_position(latitude_deg, longitude_deg, iso)
        elev = float(np.asarray(pos.elevation_deg))
        az = float(np.asarray(pos.azimuth_deg))
        dist = float(np.asarray(pos.earth_sun_distance_au))
        if elev < lowest and allow_night:  # night: the true elevation, below the sunlit sky's bound
            return SunPlacement(elev, check("sun_azimuth", az) % 360.0, dist, iso, int(iso[5:7]), instant.local_iso,
                                instant.timezone, day_of_year(iso))
        if elev < lowest:
            raise SkymodelInputError("time_utc", iso, f"a time when the sun is above {lowest:g} degrees "
                                                      f"(it is at {elev:.1f} degrees: night)")
        return SunPlacement(check("sun_elevation", elev), check("sun_azimuth", az) % 360.0, dist, iso,
                            int(iso[5:7]), instant.local_iso, instant.timezone, day_of_year(iso))
    if timezone is not None:
        raise SkymodelInputError("timezone", timezone, "a time zone only together with a date-time (--time)")
    elev = check("sun_elevation", default("sun_elevation") if elevation_deg is None else elevation_deg)
    az = check("sun_azimuth", default("sun_azimuth") if azimuth_deg is None else azimuth_deg)
    return SunPlacement(elev, az % 360.0)
