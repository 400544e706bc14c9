"""The argument groups several commands share, built from the parameter registry.

:func:`add_option` turns a :class:`skymodel.scene.Parameter` into an argparse option: its
flag, type, default and help (the sentence, the allowed range and the default) all come
from :mod:`skymodel.scene`, so a bound or default is written once. Values are converted
here but checked where they are used (``Atmosphere``, :func:`skymodel.scene.place_sun`,
:func:`skymodel.scene.check`), so bad input is reported in one line naming the parameter
(exit status 2) instead of argparse's usage message.
"""

from __future__ import annotations

import argparse
import math
import sys

from skymodel import scene

#: ``add_option(..., default=REGISTRY)``: take the registry's default.
REGISTRY = object()


def floats(text: str) -> list[float]:
    """Comma-separated numbers (``"400,550,700"``) as a list of floats."""
    try:
        return [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated numbers, got {text!r}") from None


def number_list(parameter: str, values, *, check: str | None = None) -> list[float]:
    """The numbers of a comma-separated option (text, or a list already parsed), each one
    finite and, with ``check``, inside the registry's range of parameter ``check``.

    Raises :class:`~skymodel.errors.SkymodelInputError` naming ``parameter`` for an empty
    list, text that is not a number, NaN or infinity, before any work starts."""
    from skymodel.errors import SkymodelInputError

    entry = scene.parameter(check) if check else None
    allowed = ("comma-separated numbers" + (f" in {entry.range_text()}" if entry else ""))
    items = str(values).split(",") if isinstance(values, str) else list(values)
    out = []
    for item in items:
        if isinstance(item, str) and not item.strip():
            continue
        try:
            v = float(item)
        except (TypeError, ValueError):
            raise SkymodelInputError(parameter, values, allowed) from None
        if not math.isfinite(v):
            raise SkymodelInputError(parameter, values, allowed)
        if entry is not None:
            try:
                entry.check(v)
            except SkymodelInputError:
                raise SkymodelInputError(parameter, values, allowed) from None
        out.append(v)
    if not out:
        raise SkymodelInputError(parameter, values, "at least one number: " + allowed)
    return out


def size(text: str):
    """``WIDTH`` or ``WIDTHxHEIGHT`` [px] as ``(width, height or None)``."""
    try:
        parts = [int(v) for v in str(text).lower().split("x")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected WIDTH or WIDTHxHEIGHT, got {text!r}") from None
    if len(parts) not in (1, 2):
        raise argparse.ArgumentTypeError(f"expected WIDTH or WIDTHxHEIGHT, got {text!r}")
    return parts[0], (parts[1] if len(parts) == 2 else None)


def add_option(parser, name: str, *, flag: str | None = None, default=REGISTRY, type=None, note: str = "",
               **kwargs):
    """Add the registry's parameter ``name`` as an option of ``parser`` (a parser or group).

    Parameters
    ----------
    name : a key of :data:`skymodel.scene.PARAMETERS`.
    flag : the option string; default the parameter's ``flag``.
    default : the parsed value when the option is absent; default the registry's. Pass
        ``None`` to resolve it later (the help still states the registry's default).
    type : the conversion; default int, float or str from the parameter.
    note : a sentence appended to the help.
    kwargs : passed on to ``add_argument`` (``dest``, ``required``, ...).
    """
    p = scene.parameter(name)
    if type is None:
        type = str if (p.choices or not p.is_number) else (int if p.integer else float)
    allowed = p.range_text()
    text = f"{p.help} ({allowed + '; ' if allowed else ''}required)" if kwargs.get("required") else p.help_text()
    text += f"; {note}" if note else ""
    flag = flag or p.flag
    kwargs.setdefault("dest", name)
    kwargs.setdefault("metavar", flag.lstrip("-").replace("-", "_").upper())
    return parser.add_argument(flag, type=type, default=p.default if default is REGISTRY else default,
                               help=text.replace("%", "%%"), **kwargs)


def add_wavelengths_argument(p: argparse.ArgumentParser) -> None:
    """``--wavelengths``: the point queries' wavelengths (``profile``, ``radiance``), read by
    :func:`wavelengths_from_args`."""
    p.add_argument("--wavelengths", default=None,
                   help="nm, comma-separated, in any order (answered in that order; no duplicates; "
                        "default 380..780 by 5)")


def wavelengths_from_args(args):
    """``--wavelengths`` as ``(ascending, back)`` (:func:`skymodel.wavelengths.ascending_order`):
    the grid the core computes on and the index array that answers in the user's order; every
    value checked (finite, no duplicates, in the wavelengths' range) before any work starts."""
    from skymodel.wavelengths import ascending_order

    return ascending_order(None if args.wavelengths is None else number_list("wavelengths", args.wavelengths))


def add_atmosphere_arguments(p: argparse.ArgumentParser) -> None:
    """Options shared by every command that builds an atmosphere."""
    g = p.add_argument_group("atmosphere")
    add_option(g, "location", default=None, note="custom: give --lat and --lon instead (the location rule chooses the aerosol type and ground "
               "unless --aerosol / --albedo are given, and says which rule chose them)")
    add_option(g, "latitude")
    add_option(g, "longitude")
    add_option(g, "month", default=None, note="with --time, the month of the date")
    add_option(g, "aerosol_model", default=None,
               note="a type only the opac model has (continental_polluted, maritime_mineral) selects opac")
    add_option(g, "aerosol", note="without --location, chosen from --lat/--lon by the location rule")
    add_option(g, "site_altitude")
    add_option(g, "aod550")
    add_option(g, "turbidity")
    add_option(g, "stratospheric")
    add_option(g, "ozone_du")
    add_option(g, "albedo")
    add_option(g, "n_altitudes")


def atmosphere_from_args(args):
    """The :class:`~skymodel.optics.atmosphere.Atmosphere` of the parsed atmosphere options
    (the month and day of the year from ``--time``, read in ``--timezone``, when ``--month``
    is not given: the ozone of that UTC date)."""
    from skymodel.optics.atmosphere import Atmosphere

    location = args.location
    if location is None and (args.latitude is None or args.longitude is None):
        location = scene.default("location")
    month, day = args.month, None
    if getattr(args, "timezone", None) is not None:  # auto: the zone at the place, reported by name from here on
        from skymodel.optics.atmosphere import locations

        preset = locations().get(location, {}) if location is not None else {}
        lat = args.latitude if args.latitude is not None else preset.get("latitude")
        lon = args.longitude if args.longitude is not None else preset.get("longitude")
        args.timezone = scene.place_zone(args.timezone, lat, lon)
    if month is None and getattr(args, "time_utc", None) is not None:
        iso = scene.resolve_time(args.time_utc, getattr(args, "timezone", None)).utc_iso
        month, day = scene.month_of(iso), scene.day_of_year(iso)
    atm = Atmosphere(
        location=location, month=month or scene.default("month"), day_of_year=day,
        latitude=args.latitude, longitude=args.longitude, aerosol=args.aerosol,
        aod550=args.aod550, turbidity=args.turbidity, stratospheric=args.stratospheric,
        ozone_du=args.ozone_du, albedo=args.albedo, n_altitudes=args.n_altitudes,
        aerosol_model=getattr(args, "aerosol_model", None),
        site_altitude_m=getattr(args, "site_altitude", None),
    )
    for rule in atm.location_rules:  # which rule chose the aerosol type and the surface
        print(f"skymodel: {rule}", file=sys.stderr)
    return atm


def add_sun_arguments(p: argparse.ArgumentParser, observer: bool = True) -> None:
    """The sun (``--sun-elevation``/``--sun-azimuth`` or ``--time``) and the observer's altitude."""
    g = p.add_argument_group("sun and observer")
    add_option(g, "sun_elevation", default=None)
    add_option(g, "sun_azimuth", default=None)
    add_option(g, "time_utc", note="not with --sun-elevation/--sun-azimuth; local time with --timezone")
    add_option(g, "timezone")
    if observer:
        add_option(g, "observer_altitude")


def sun_from_args(args, atm, allow_night: bool = False) -> scene.SunPlacement:
    """The sun of the parsed sun options at the atmosphere's place (:func:`skymodel.scene.place_sun`;
    ``allow_night``: a time with the sun below the registry's bound is returned, not refused)."""
    return scene.place_sun(atm.latitude, atm.longitude, args.time_utc, args.sun_elevation, args.sun_azimuth,
                           timezone=getattr(args, "timezone", None), allow_night=allow_night)


def profile_for_sun(atm, wavelengths_nm, sun: scene.SunPlacement):
    """The atmosphere's optical profile with the solar spectrum scaled to the date's
    Earth-sun distance (1 AU without a date)."""
    from dataclasses import replace

    profile = atm.optical_profile(wavelengths_nm)
    if sun.earth_sun_distance_au != 1.0:
        profile = replace(profile, solar_irradiance=profile.solar_irradiance / sun.earth_sun_distance_au**2)
    return profile
