"""The panel's time zone, the sun's path in the viewport (issue #19) and the moon lamp
(issue #24), headless bpy, tiny images."""

import math

import pytest

bpy = pytest.importorskip("bpy")
import numpy as np  # noqa: E402

pytestmark = pytest.mark.blender


@pytest.fixture
def dated(new_sky_scene, small_preview, monkeypatch, tmp_path):
    monkeypatch.setenv("SKYMODEL_CACHE_DIR", str(tmp_path / "cache"))
    sc = new_sky_scene(image_width=32, location="zaragoza")
    s = sc.world.skymodel
    s.sun_source = "TIME"
    s.year, s.month, s.day, s.hour, s.minute = 2026, 6, 21, 21, 30
    s.timezone = "Europe/Madrid"
    return sc, s


def _direction(obj):
    """Where a sun lamp shines from: its local +Z (Blender lamps emit along -Z)."""
    m = obj.rotation_euler.to_matrix()
    return np.array(m.col[2])


def _enu(elevation_deg, azimuth_deg):
    el, az = math.radians(elevation_deg), math.radians(azimuth_deg)
    return np.array([math.cos(el) * math.sin(az), math.cos(el) * math.cos(az), math.sin(el)])


def test_time_zone_field_reads_local_time_as_the_core_does(dated):
    from blender_addon import physics
    from skymodel import scene

    sc, s = dated
    lat, lon = 41.65, -0.88
    sky = physics.resolve(s.to_params())
    ref = scene.place_sun(sky.atmosphere.latitude, sky.atmosphere.longitude, "2026-06-21T21:30",
                          timezone="Europe/Madrid")
    assert sky.time_iso == ref.time_utc == "2026-06-21T19:30:00Z"  # CEST = UTC+2
    assert sky.sun_elevation_deg == pytest.approx(ref.elevation_deg, abs=1e-9)
    assert sky.time_local == "2026-06-21T21:30:00+02:00" and sky.timezone == "Europe/Madrid"
    s.timezone = "auto"  # the zone at the place (timezonefinder)
    pytest.importorskip("timezonefinder")
    assert physics.resolve(s.to_params()).time_iso == "2026-06-21T19:30:00Z"
    assert abs(sky.atmosphere.latitude - lat) < 0.1 and abs(sky.atmosphere.longitude - lon) < 0.1
    # a local time skipped by the clocks: the core's message, naming time_utc; Build Sky changes nothing
    s.timezone = "Europe/Madrid"
    s.month, s.day, s.hour, s.minute = 3, 29, 2, 30
    with pytest.raises(Exception) as err:
        physics.resolve(s.to_params())
    assert err.value.parameter == "time_utc" and "skipped there" in str(err.value)
    before = sorted(o.name for o in bpy.data.objects)
    with pytest.raises(RuntimeError, match="time_utc.*skipped there"):  # the operator's ERROR report
        bpy.ops.skymodel.build_sky()
    assert sorted(o.name for o in bpy.data.objects) == before
    s.timezone = "Mars/Olympus"
    with pytest.raises(Exception) as err:
        physics.resolve(s.to_params())
    assert err.value.parameter == "timezone"


def test_sun_path_follows_the_day_and_is_removed_when_off(dated):
    from blender_addon import sunpath
    from skymodel.sun import solar_position

    sc, s = dated
    s.sun_path_radius = 5.0
    s.show_sun_path = True
    path = bpy.data.objects[sunpath.PATH_NAME]
    coll = sunpath.find_collection(sc)
    assert coll is not None and path.name in coll.objects
    assert len(path.data.splines[0].points) == 24 * 6 + 1  # midnight to midnight every 10 min
    markers = sorted(o.name for o in coll.objects if o.type == "EMPTY")
    assert len(markers) == 24 and markers[0] == "Sun 00:00" and markers[-1] == "Sun 23:00"
    m = bpy.data.objects["Sun 14:00"]  # 14:00 CEST = 12:00 UTC
    pos = solar_position(41.65, -0.88, "2026-06-21T12:00:00")
    loc = np.array(m.location)  # the path object sits at the origin, unrotated
    np.testing.assert_allclose(loc / 5.0, _enu(float(pos.elevation_deg), float(pos.azimuth_deg)), atol=2e-3)
    assert abs(np.linalg.norm(loc) - 5.0) < 1e-4
    # the day the clocks go forward has 23 hours; changing the date redraws the path
    s.month, s.day = 3, 29
    path = bpy.data.objects[sunpath.PATH_NAME]
    assert len(path.data.splines[0].points) == 23 * 6 + 1
    assert len([o for o in sunpath.find_collection(sc).objects if o.type == "EMPTY"]) == 23
    assert "Sun 02:00" not in bpy.data.objects
    # a bad zone: named in the panel's error, the path stays as it was
    s.timezone = "Europe/Zaragoza"
    assert "timezone" in sunpath.ERROR[sc.name]
    assert len(bpy.data.objects[sunpath.PATH_NAME].data.splines[0].points) == 23 * 6 + 1
    s.timezone = "Europe/Madrid"
    assert sc.name not in sunpath.ERROR
    s.show_sun_path = False
    assert sunpath.find_collection(sc) is None
    assert not [o for o in bpy.data.objects if sunpath.TAG in o.keys()]
    assert sunpath.PATH_NAME not in bpy.data.curves


def test_moon_lamp_from_the_core_and_a_failed_build_leaves_the_scene(dated):
    from blender_addon import builder, physics
    from skymodel.astro.moon import moon_position

    sc, s = dated
    s.year, s.month, s.day, s.hour, s.minute = 2026, 6, 21, 20, 0
    s.timezone = "UTC"  # sun -3.7 degrees (twilight), moon 37.6 degrees up, half lit
    assert bpy.ops.skymodel.build_sky() == {"FINISHED"}
    moon = bpy.data.objects["Skymodel Moon"]
    atm = physics.resolve(s.to_params()).atmosphere
    pos = moon_position(atm.latitude, atm.longitude, "2026-06-21T20:00:00")
    np.testing.assert_allclose(_direction(moon), _enu(float(pos.elevation_deg), float(pos.azimuth_deg)), atol=1e-5)
    ref = physics.moon_lamp(physics.resolve(s.to_params()))
    assert moon.data.energy == pytest.approx(ref["strength"], rel=1e-6)
    assert 1e-6 < moon.data.energy < 1e-3  # a half moon: ~0.02 lux against the sun's ~1e5
    assert math.degrees(moon.data.angle) == pytest.approx(2 * float(pos.angular_radius_deg), rel=1e-5)
    assert tuple(moon.data.color) == pytest.approx(ref["colour"], rel=1e-5)
    assert "Moon 37.6° el" in s.last_info
    # a rebuild replaces the lamp (one moon), a failing one leaves it and everything else
    assert bpy.ops.skymodel.build_sky() == {"FINISHED"}
    assert [o.name for o in bpy.data.objects if o.name.startswith("Skymodel Moon")] == ["Skymodel Moon"]
    before = sorted(o.name for o in bpy.data.objects), sorted(li.name for li in bpy.data.lights)
    builder.FAIL_AT = "after_swap"
    try:
        with pytest.raises(RuntimeError, match="simulated failure"):
            bpy.ops.skymodel.build_sky()
    finally:
        builder.FAIL_AT = None
    assert (sorted(o.name for o in bpy.data.objects), sorted(li.name for li in bpy.data.lights)) == before
    # Volumetric mode: the volumes attenuate the lamp, so it carries the irradiance above the atmosphere
    from skymodel.astro.lunar_irradiance import moon_irradiance
    from skymodel.render.environment import sun_lamp
    from skymodel.wavelengths import default_wavelengths

    s.mode, s.n_layers = "VOLUMETRIC", 2
    assert bpy.ops.skymodel.build_sky() == {"FINISHED"}
    wl = default_wavelengths(physics.MOON_WAVELENGTH_STEP_NM)
    top, _ = sun_lamp(moon_irradiance(pos, wl), wl)
    assert bpy.data.objects["Skymodel Moon"].data.energy == pytest.approx(top, rel=1e-6)
    assert top > ref["strength"]
    s.mode = "ENVIRONMENT"
    # switched off, or the moon below the horizon: no moon lamp
    s.moon_lamp = False
    assert bpy.ops.skymodel.build_sky() == {"FINISHED"}
    assert "Skymodel Moon" not in bpy.data.objects
    s.moon_lamp = True
    s.year, s.month, s.day, s.hour, s.minute = 2026, 1, 3, 12, 0  # full moon, below the horizon at noon
    assert bpy.ops.skymodel.build_sky() == {"FINISHED"}
    assert "Skymodel Moon" not in bpy.data.objects


def test_headless_time_zone_options(dated, tmp_path):
    from blender_addon import physics, render
    from skymodel.errors import SkymodelInputError

    sc, s = dated
    out = str(tmp_path / "x.png")
    o = render.parse_args(["--location", "zaragoza", "--timezone", "Europe/Madrid", "--out", out])
    with pytest.raises(SkymodelInputError, match="--timezone"):
        render.check_options(o)
    for argv, zone in ((["--time", "2026-06-21T21:30", "--timezone", "Europe/Madrid"], "Europe/Madrid"),
                       (["--time", "2026-06-21T21:30+02:00"], "UTC")):
        o = render.parse_args(["--location", "zaragoza", *argv, "--out", out])
        render.check_options(o)
        render._apply_options(s, o)
        assert s.timezone == zone
        assert physics.resolve(s.to_params()).time_iso == "2026-06-21T19:30:00Z"
    o = render.parse_args(["--location", "zaragoza", "--time", "2026-06-21T21:30+01:00", "--timezone",
                           "Europe/Madrid", "--out", out])
    with pytest.raises(SkymodelInputError, match="offset of Europe/Madrid"):
        render._apply_options(s, o)


def test_sun_path_is_kept_when_only_the_hour_changes(dated):
    from blender_addon import sunpath

    sc, s = dated
    s.show_sun_path = True
    path = bpy.data.objects[sunpath.PATH_NAME]
    s.hour = 10  # the path depends on the day only
    assert bpy.data.objects[sunpath.PATH_NAME] == path
    s.day = 22
    new = bpy.data.objects[sunpath.PATH_NAME]
    assert new["skymodel_day"].startswith("2026-06-22")
    s.show_sun_path = False


def test_panel_draws_the_zone_moon_sun_path_and_live_rows(dated, monkeypatch, recording_layout):
    from blender_addon import live, ui

    sc, s = dated
    s.show_sun_path = True
    s.live_update = True
    live.stop()
    monkeypatch.setattr(live.STATE, "error", "timezone='x' is not allowed")
    log = []
    ui.draw_settings(recording_layout(log), bpy.context)
    props = {n for kind, n in log if kind == "prop"}
    assert {"timezone", "moon_lamp", "show_sun_path", "sun_path_radius", "live_update"} <= props
    assert ("label", "Live: timezone='x' is not allowed") in log
    s.mode = "VOLUMETRIC"
    log.clear()
    ui.draw_settings(recording_layout(log), bpy.context)
    assert any(kind == "label" and text.startswith("Live: Live Update works in Environment mode") for kind, text in log)
    s.live_update = False
    s.show_sun_path = False
    live.reset()
