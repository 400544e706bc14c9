"""Local time (issue #19): time zones, daylight saving, and the ozone's day of the year."""

from __future__ import annotations

import subprocess
import sys
import warnings

import numpy as np
import pytest

from skymodel import scene, sun
from skymodel.errors import SkymodelInputError
from skymodel.optics import ozone

ZARAGOZA = (41.65, -0.88)


def _pvlib(lat, lon, iso):
    pvlib = pytest.importorskip("pvlib")
    import pandas as pd

    t = pd.DatetimeIndex([pd.Timestamp(iso)])
    pos = pvlib.solarposition.spa_python(t, lat, lon, altitude=0, pressure=101325, temperature=12,
                                         delta_t=0.0, atmos_refract=0.0)
    return float(pos["elevation"].iloc[0]), float(pos["azimuth"].iloc[0])


def test_madrid_summer_evening_is_cest_and_matches_pvlib():
    s = scene.place_sun(*ZARAGOZA, "2026-06-21T21:30", timezone="Europe/Madrid")
    assert s.time_utc == "2026-06-21T19:30:00Z"
    assert s.time_local == "2026-06-21T21:30:00+02:00" and s.timezone == "Europe/Madrid"
    assert s.day_of_year == 172 and s.month == 6
    # pvlib's SPA with refraction off evaluates the geometric elevation, as place_sun does
    el, az = _pvlib(*ZARAGOZA, "2026-06-21T19:30:00Z")
    assert abs(s.elevation_deg - el) < 0.05 and abs(s.azimuth_deg - az) < 0.05


def test_madrid_winter_evening_is_cet_and_matches_pvlib():
    inst = scene.resolve_time("2026-12-21T21:30", "Europe/Madrid")
    assert inst.utc_iso == "2026-12-21T20:30:00Z" and inst.local_iso.endswith("+01:00")
    pos = sun.solar_position(*ZARAGOZA, inst.utc_iso)
    el, az = _pvlib(*ZARAGOZA, inst.utc_iso)
    assert abs(float(pos.elevation_deg) - el) < 0.05 and abs(float(pos.azimuth_deg) - az) < 0.05
    # 21:30 in December is night at Zaragoza: place_sun says so, with the UTC instant
    with pytest.raises(SkymodelInputError, match="2026-12-21T20:30:00Z.*night"):
        scene.place_sun(*ZARAGOZA, "2026-12-21T21:30", timezone="Europe/Madrid")
    # a winter afternoon: the same instant however it is written
    a = scene.place_sun(*ZARAGOZA, "2026-12-21T16:00", timezone="Europe/Madrid")
    b = scene.place_sun(*ZARAGOZA, "2026-12-21T15:00:00Z")
    c = scene.place_sun(*ZARAGOZA, "2026-12-21T16:00+01:00")
    d = scene.place_sun(*ZARAGOZA, "2026-12-21T16:00", timezone="+01:00")
    assert a.elevation_deg == b.elevation_deg == c.elevation_deg == d.elevation_deg


def test_dst_gap_and_repeated_hour_are_refused_by_name():
    with pytest.raises(SkymodelInputError, match=r"2026-03-29 02:30 is skipped.*Europe/Madrid|Europe/Madrid.*skipped"):
        scene.place_sun(*ZARAGOZA, "2026-03-29T02:30", timezone="Europe/Madrid")
    with pytest.raises(SkymodelInputError, match="happens twice.*2026-10-25T02:30\\+02:00 or 2026-10-25T02:30\\+01:00"):
        scene.resolve_time("2026-10-25T02:30", "Europe/Madrid")
    # the offset picks one reading of the repeated hour
    assert scene.resolve_time("2026-10-25T02:30+01:00", "Europe/Madrid").utc_iso == "2026-10-25T01:30:00Z"
    assert scene.resolve_time("2026-10-25T02:30+02:00", "Europe/Madrid").utc_iso == "2026-10-25T00:30:00Z"
    with pytest.raises(SkymodelInputError, match="offset of Europe/Madrid"):
        scene.resolve_time("2026-06-21T21:30+05:00", "Europe/Madrid")
    with pytest.raises(SkymodelInputError, match="timezone"):
        scene.resolve_time("2026-06-21T21:30", "Mars/Olympus_Mons")
    with pytest.raises(SkymodelInputError, match="timezone.*only together"):
        scene.place_sun(elevation_deg=10, timezone="Europe/Madrid")


def test_naive_time_is_still_utc_and_offsets_parse_without_warnings():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        a = scene.place_sun(*ZARAGOZA, "2026-06-21T12:00")
        b = scene.place_sun(*ZARAGOZA, "2026-06-21T14:00+02:00")
        assert scene.month_of("2026-06-30T23:30-02:00") == 7
    assert a.time_utc == b.time_utc == "2026-06-21T12:00:00Z" and a.timezone == "UTC"


def test_cli_sun_with_a_zone_and_no_numpy_warning_for_an_offset(tmp_path):
    code = ("from skymodel.cli import main; import sys; sys.exit(main(['sun', '--lat', '41.65', '--lon', '-0.88', "
            "'--time', '2026-06-21T21:30', '--timezone', 'Europe/Madrid', '--json']))")
    out = subprocess.run([sys.executable, "-W", "error", "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert '"time_utc": "2026-06-21T19:30:00Z"' in out.stdout and out.stderr == ""
    code = code.replace("'2026-06-21T21:30', '--timezone', 'Europe/Madrid'", "'2026-03-29T02:30', '--timezone', "
                                                                               "'Europe/Madrid'")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 2 and "skipped" in out.stderr


# ---------------------------------------------------------------------------- --timezone auto


def test_auto_zone_from_the_place_offline():
    pytest.importorskip("timezonefinder")
    assert scene.zone_at(*ZARAGOZA) == "Europe/Madrid"
    s = scene.place_sun(*ZARAGOZA, "2026-06-21T21:30", timezone="auto")
    assert s.timezone == "Europe/Madrid" and s.time_utc == "2026-06-21T19:30:00Z"
    # at sea: the nautical zone Etc/GMT+N (POSIX sign: Etc/GMT+2 is UTC-2), read like any IANA zone
    assert scene.zone_at(0.0, -30.0) == "Etc/GMT+2"
    inst = scene.resolve_time("2026-06-21T12:00", "auto", 0.0, -30.0)
    assert inst.timezone == "Etc/GMT+2" and inst.utc_iso == "2026-06-21T14:00:00Z"


def test_auto_zone_refusals_name_the_parameter(monkeypatch):
    with pytest.raises(SkymodelInputError, match="timezone.*auto together with a latitude"):
        scene.resolve_time("2026-06-21T21:30", "auto")
    with pytest.raises(SkymodelInputError, match="timezone"):
        scene.place_sun(*ZARAGOZA, "2026-06-21T21:30", timezone="Europe/Zaragoza")
    with pytest.raises(SkymodelInputError, match="latitude"):
        scene.zone_at(95.0, 0.0)
    monkeypatch.setitem(sys.modules, "timezonefinder", None)  # the optional package missing
    with pytest.raises(SkymodelInputError, match=r"timezone.*skymodel\[timezone\]"):
        scene.resolve_time("2026-06-21T21:30", "auto", *ZARAGOZA)


def test_cli_sun_reports_the_zone_found():
    pytest.importorskip("timezonefinder")
    code = ("from skymodel.cli import main; import sys; sys.exit(main(['sun', '--lat', '41.65', '--lon', '-0.88', "
            "'--time', '2026-06-21T21:30', '--timezone', 'auto']))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert "2026-06-21T19:30:00Z (2026-06-21T21:30:00+02:00 Europe/Madrid)" in out.stdout
    code = code.replace("'auto'", "'Nowhere/Land'")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 2 and "timezone" in out.stderr


def test_cli_options_resolve_auto_from_a_preset_location():
    pytest.importorskip("timezonefinder")
    import argparse

    from skymodel.cli.options import atmosphere_from_args

    args = argparse.Namespace(location="zaragoza", latitude=None, longitude=None, month=None, aerosol=None,
                              aod550=None, turbidity=None, stratospheric=None, ozone_du=None, albedo=None,
                              n_altitudes=scene.default("n_altitudes"), time_utc="2026-06-21T21:30", timezone="auto")
    atm = atmosphere_from_args(args)
    assert args.timezone == "Europe/Madrid" and atm.day_of_year == 172


# ---------------------------------------------------------------------------- ozone in the year


@pytest.mark.parametrize("latitude", [41.65, -34.6, 70.0])
def test_ozone_is_continuous_across_month_boundaries(latitude):
    days = np.arange(1, 366)
    col = np.array([ozone.climatology_total_du(None, latitude, day_of_year=int(d)) for d in days])
    daily = np.abs(np.diff(np.concatenate([col, col[:1]])))  # periodic: 31 Dec -> 1 Jan too
    first_days = np.cumsum([0, 31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30]) + 1  # day of the 1st of each month
    nodes = np.array([ozone.climatology_total_du(m, latitude) for m in range(1, 13)])
    for k, d in enumerate(first_days):
        i = d - 2  # index of the jump from the last day of the previous month to day d
        # the mean daily change between the two mid-month nodes around the boundary
        gap = ozone.MONTH_NODE_DAYS[k] - ozone.MONTH_NODE_DAYS[k - 1] + (ozone.YEAR_DAYS if k == 0 else 0)
        local_mean = abs(nodes[k] - nodes[k - 1]) / gap
        assert daily[i] <= 2 * local_mean + 1e-9, (k, daily[i], local_mean)
        assert daily[i] < 2 * daily.mean() + 1e-9 or daily[i] <= 2 * local_mean + 1e-9
    # the old monthly step would have jumped by the whole month-to-month difference
    assert np.max(np.abs(np.diff(nodes))) > 10 * daily.max()
    # mid-month days are the monthly means themselves
    assert ozone.climatology_total_du(None, latitude, day_of_year=16) == pytest.approx(nodes[0], rel=1e-12)


def test_atmosphere_takes_a_day_and_month_still_works():
    from skymodel import Atmosphere

    jan = Atmosphere(location="zaragoza", month=1).optical_profile([550.0]).metadata["ozone_du"]
    d16 = Atmosphere(location="zaragoza", month=1, day_of_year=16).optical_profile([550.0]).metadata
    d31 = Atmosphere(location="zaragoza", month=1, day_of_year=31).optical_profile([550.0]).metadata
    d32 = Atmosphere(location="zaragoza", month=2, day_of_year=32).optical_profile([550.0]).metadata
    assert d16["ozone_du"] == pytest.approx(jan, rel=1e-9) and d31["day_of_year"] == 31
    assert 0 < d32["ozone_du"] - d31["ozone_du"] < 1.0
    with pytest.raises(SkymodelInputError, match="day_of_year"):
        Atmosphere(location="zaragoza", day_of_year=400)
