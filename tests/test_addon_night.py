"""The night in the add-on (issue 24): a date/time with the sun below -18 builds the core's
night (moonlit sky, stars, glow) in Environment mode, the sun lamp dark and the moon lamp from
the core's numbers; a bake runs through dusk into the night; Volumetric mode refuses a night
and Auto builds it in Environment mode. Headless bpy, 32x16 images, the preview preset with
small tables."""

import math
import os

import pytest

bpy = pytest.importorskip("bpy")
import numpy as np  # noqa: E402

pytestmark = pytest.mark.blender

#: rural (48 N, 11 E), 2026-12-21 20:00 UTC: sun -44.6 deg, moon 64 deg up, 93 % lit
MOONLIT = (2026, 12, 21, 20, 0)
#: 2026-01-20 00:00 UTC: sun -61 deg, moon -61 deg (new moon)
MOONLESS = (2026, 1, 20, 0, 0)


@pytest.fixture
def night(new_sky_scene, small_preview, monkeypatch, tmp_path):
    from blender_addon import builder

    monkeypatch.setenv("SKYMODEL_CACHE_DIR", str(tmp_path / "cache"))
    builder.FAIL_AT = None
    sc = new_sky_scene(image_width=32, location="rural")
    s = sc.world.skymodel
    s.sun_source, s.timezone, s.moon_lamp = "TIME", "UTC", True
    yield sc
    builder.FAIL_AT = None


def _set_time(s, t):
    s.year, s.month, s.day, s.hour, s.minute = t


def _image(world):
    img = next(n.image for n in world.node_tree.nodes if n.bl_idname == "ShaderNodeTexEnvironment")
    w, h = img.size
    px = np.empty(w * h * 4, np.float32)
    img.pixels.foreach_get(px)
    return px.reshape(h, w, 4)[::-1, :, :3]  # Blender's rows start at the bottom


def _lamps():
    lights = [o for o in bpy.data.objects if o.type == "LIGHT"]
    sun = next(o for o in lights if "skymodel_sun_elevation_deg" in o.keys())
    moon = next((o for o in lights if "skymodel_moon_elevation_deg" in o.keys()), None)
    return sun, moon


def test_a_moonlit_night_builds_the_cores_night_with_its_moon_lamp(night, tmp_path):
    from blender_addon import physics
    from skymodel.render import environment

    s = night.world.skymodel
    _set_time(s, MOONLIT)
    assert bpy.ops.skymodel.build_sky() == {"FINISHED"}
    sky = physics.resolve(s.to_params())
    assert sky.sun_elevation_deg < -40.0 and physics.is_night(sky.sun_elevation_deg)
    # the core's image of the same parameters, rendered afresh in another cache
    rgb, env = environment.render_environment(
        sky.atmosphere, sky.sun_elevation_deg, sky.sun_azimuth_deg, earth_sun_distance_au=sky.earth_sun_distance_au,
        quality="preview", width=32, time_iso=sky.time_iso, night="auto", cache_dir=tmp_path / "other-cache")
    img = _image(night.world)
    assert img.shape == rgb.shape == (16, 32, 3)
    assert np.isfinite(img).all() and img.min() >= 0.0
    np.testing.assert_allclose(img, rgb, rtol=1e-6, atol=0)
    # the stars are in it: the night's light without them differs (the core puts the stars)
    assert env.info["night"]["stars_drawn"] > 0
    sun, moon = _lamps()
    assert sun.data.energy == 0.0
    core_moon = env.info["moon"]
    assert moon is not None and core_moon["strength"] > 0.0
    assert moon.data.energy == pytest.approx(core_moon["strength"], rel=1e-6)
    assert tuple(moon.data.color) == pytest.approx(tuple(core_moon["colour"]), rel=1e-5)
    assert moon["skymodel_moon_elevation_deg"] == pytest.approx(core_moon["elevation_deg"], abs=1e-6)
    assert math.degrees(moon.data.angle) == pytest.approx(core_moon["angle_deg"], rel=1e-5)
    assert night.view_settings.exposure == pytest.approx(env.exposure, abs=1e-5)
    assert "Night (no sunlit sky below -18°): moonlit sky, " in s.last_info and "Moon 6" in s.last_info


def test_a_moonless_night_has_no_moon_light_and_its_brightest_star_where_the_catalogue_puts_it(night):
    """256x128 (a moonless night needs no solve): the brightest star more than 30 deg up is a
    bright pixel at the catalogue's place (its 2x2 splat at least 10x the image's median)."""
    from blender_addon import physics
    from skymodel.astro.stars import catalogue, star_positions
    from skymodel.render import environment

    s = night.world.skymodel
    s.image_width = 256
    _set_time(s, MOONLESS)
    assert bpy.ops.skymodel.build_sky() == {"FINISHED"}
    img = _image(night.world)
    assert img.shape == (128, 256, 3)
    assert np.isfinite(img).all() and img.min() >= 0.0 and img.max() > 0.0  # glow and stars: not black
    sun, moon = _lamps()
    assert sun.data.energy == 0.0
    assert moon is None or moon.data.energy == 0.0
    sky = physics.resolve(s.to_params())
    places = star_positions(sky.atmosphere.latitude, sky.atmosphere.longitude, sky.time_iso)
    v = np.where(places.elevation_deg > 30.0, catalogue().v_mag, np.inf)
    k = int(np.argmin(v))
    assert v[k] < 1.0  # a first-magnitude star
    (col, row), visible = environment.environment_camera(256).project(places.direction_enu()[k])
    assert visible
    y = img @ np.array([0.2126, 0.7152, 0.0722])
    r0, c0 = int(np.floor(row)), int(np.floor(col))
    splat = y[r0:r0 + 2, c0:c0 + 2]
    assert splat.max() > 10.0 * np.median(y[: 64])


def _snapshot():
    bpy.context.view_layer.update()
    d = {kind: sorted(db.name for db in getattr(bpy.data, kind))
         for kind in ("objects", "lights", "images", "materials", "collections", "meshes")}
    d["lamps"] = sorted((lt.name, round(lt.energy, 9), tuple(lt.color)) for lt in bpy.data.lights)
    d["nodes"] = sorted((n.name, n.bl_idname) for n in bpy.context.scene.world.node_tree.nodes)
    d["exposure"] = bpy.context.scene.view_settings.exposure
    d["engine"] = bpy.context.scene.render.engine
    return d


def test_a_failed_or_refused_night_build_leaves_the_scene_unchanged(night):
    from blender_addon import builder

    s = night.world.skymodel
    s.sun_source = "ANGLES"
    s.sun_elevation = math.radians(10.0)
    assert bpy.ops.skymodel.build_sky() == {"FINISHED"}  # a day sky first
    s.sun_source = "TIME"
    _set_time(s, MOONLIT)
    before = _snapshot()
    builder.FAIL_AT = "after_swap"
    with pytest.raises(Exception):
        bpy.ops.skymodel.build_sky()
    builder.FAIL_AT = None
    assert _snapshot() == before
    # Volumetric at night: refused naming the mode, before any work
    s.mode = "VOLUMETRIC"
    with pytest.raises(RuntimeError, match="mode="):
        bpy.ops.skymodel.build_sky()
    assert _snapshot() == before
    # another sky model has no night
    s.mode, s.sky_model = "ENVIRONMENT", "preetham"
    with pytest.raises(RuntimeError, match="sky_model="):
        bpy.ops.skymodel.build_sky()
    assert _snapshot() == before


def test_auto_mode_builds_a_night_in_environment_mode(night):
    s = night.world.skymodel
    _set_time(s, MOONLIT)
    s.mode = "AUTO"
    s.override_aerial_perspective = "ON"  # in daytime this plan is Volumetric
    assert bpy.ops.skymodel.build_sky() == {"FINISHED"}
    assert "Skymodel Atmosphere 00" not in bpy.data.objects
    assert _image(night.world).shape == (16, 32, 3)
    assert "night (sun at -44.6°" in s.last_info and "Environment" in s.last_info
    # the panel's plan box says so too
    from blender_addon import ui

    labels = []

    class Layout:
        def __getattr__(self, name):  # column, row, box, prop, ...: record labels, ignore the rest
            if name == "label":
                return lambda text="", **kw: labels.append(text)
            return lambda *a, **kw: self

    ui.draw_plan(Layout(), bpy.context, s)
    assert labels[0].startswith("Volumetric:") and labels[1].startswith("Night (sun at -44.6°")


def test_a_baked_evening_runs_into_the_night(night, tmp_path):
    """16:30, 17:30, 18:30 UTC: sun -10.3, -19.8, -29.7 deg (the last two below -18)."""
    from blender_addon import animation
    from skymodel.render import environment, exposure

    sc = night
    s = sc.world.skymodel
    _set_time(s, MOONLIT)
    frames = animation.animate_day(sc, s, "2026-12-21", "16:30", "18:30", "60min", "UTC")
    assert [round(f.elevation_deg) for f in frames] == [-10, -20, -30]
    r = animation.bake(bpy.context, folder=str(tmp_path / "bake"))
    assert r["frames"] == 3
    record = animation.bake_record(sc)
    sun, moon = _lamps()
    cam = environment.environment_camera(32)
    shown = []
    for f in (1, 2, 3):
        sc.frame_set(f)
        img = bpy.data.images.load(os.path.join(record["folder"], record["frames"][str(f)]["file"]),
                                   check_existing=False)
        px = np.empty(32 * 16 * 4, np.float32)
        img.pixels.foreach_get(px)
        bpy.data.images.remove(img)
        rgb = px.reshape(16, 32, 4)[::-1, :, :3]
        assert np.isfinite(rgb).all() and rgb.min() >= 0.0 and rgb.max() > 0.0
        assert sun.data.energy == 0.0  # below the horizon
        assert moon is not None and moon.data.energy > 0.0  # the moon is up all evening
        assert moon.data.energy == pytest.approx(record["frames"][str(f)]["moon_strength"], rel=1e-6)
        assert sc.view_settings.exposure == pytest.approx(record["frames"][str(f)]["exposure"], abs=1e-5)
        shown.append(exposure.sky_log_average(rgb, cam) * 2.0 ** sc.view_settings.exposure)
    # one rule for every frame (the core's, as Build Sky's): the night is shown darker than dusk
    assert shown[1] < shown[0] and shown[2] < shown[0]


def test_the_headless_day_and_a_night_time_are_accepted_and_volumetric_named(addon, tmp_path, capsys):
    from blender_addon import render

    day = ["--location", "rural", "--date", "2026-12-21", "--from", "16:00", "--to", "23:59", "--every", "1h",
           "--timezone", "UTC", "--out", str(tmp_path / "frames")]
    render.check_options(render.parse_args(day))  # through the night: no refusal (the frames are baked as above)
    assert render.main(["--location", "rural", "--time", "2026-12-21T20:00", "--mode", "volumetric",
                        "--out", str(tmp_path / "v.png")]) == 2
    assert "mode=" in capsys.readouterr().err and not (tmp_path / "v.png").exists()
