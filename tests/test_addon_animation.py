"""Animated time of day in Blender (issue #19): Animate Day, Bake Time of Day (headless bpy).

Tiny images (environment 32x16, renders 32x16) and the preview preset with small tables,
so the file runs in about a minute on 2 cores."""

import math
import os

import pytest

bpy = pytest.importorskip("bpy")
import numpy as np  # noqa: E402


pytestmark = pytest.mark.blender

LUMA = np.array([0.2126, 0.7152, 0.0722])
ZARAGOZA = (41.65, -0.88)


@pytest.fixture
def day(new_sky_scene, small_preview, monkeypatch, tmp_path):
    """Zaragoza, 2026-06-21, 20:00 .. 21:30 CEST every 45 min keyframed (3 frames)."""
    from blender_addon import animation

    monkeypatch.setenv("SKYMODEL_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setattr(animation, "CANCEL_AT", None)
    sc = new_sky_scene(image_width=32, location="zaragoza")
    frames = animation.animate_day(sc, sc.world.skymodel, "2026-06-21", "20:00", "21:30", "45min", "Europe/Madrid")
    return sc, frames


def _pixels(path):
    img = bpy.data.images.load(str(path), check_existing=False)
    try:
        w, h = img.size
        px = np.empty(w * h * 4, np.float32)
        img.pixels.foreach_get(px)
        return px.reshape(h, w, 4)[::-1, :, :3].copy()  # Blender's rows start at the bottom
    finally:
        bpy.data.images.remove(img)


def test_animate_day_keyframes_local_times_as_utc(day):
    sc, frames = day
    s = sc.world.skymodel
    assert (sc.frame_start, sc.frame_end) == (1, 3)
    assert [f.time_local[11:16] for f in frames] == ["20:00", "20:45", "21:30"]
    sc.frame_set(2)
    assert (s.year, s.month, s.day, s.hour, s.minute) == (2026, 6, 21, 18, 45)  # 20:45 CEST
    sc.frame_set(1)
    # keyframed but never baked: the panel and a render say so
    from blender_addon import animation

    assert animation.bake_warning(sc) == "Animated but not baked: renders show one sky"
    assert "Bake Time of Day was not run" in animation.render_frame_warning(sc)


def test_baked_day_follows_the_frame_and_matches_the_core(day, tmp_path, capsys):
    from blender_addon import animation, physics
    from skymodel.render import environment

    sc, frames = day
    s = sc.world.skymodel
    result = animation.bake(bpy.context, folder=str(tmp_path / "bake"))
    assert result["frames"] == 3
    folder = tmp_path / "bake" / os.path.basename(result["folder"])
    assert sorted(p.name for p in folder.iterdir()) == ["sky_0001.exr", "sky_0002.exr", "sky_0003.exr"]
    # each baked image equals the core's environment image of its instant, rendered alone
    for k, f in enumerate(frames, start=1):
        sc.frame_set(k)
        sky = physics.resolve(s.to_params())
        assert sky.time_iso == f.time_utc
        _, alone = environment.render_environment(
            sky.atmosphere, sky.sun_elevation_deg, sky.sun_azimuth_deg,
            earth_sun_distance_au=sky.earth_sun_distance_au, quality="preview", width=32,
            time_iso=sky.time_iso, cache_dir=tmp_path / f"alone{k}")
        assert np.array_equal(_pixels(folder / f"sky_{k:04d}.exr"), _pixels(alone.image_path)), k
    # the lamp at the middle frame points where the core puts the sun
    sc.frame_set(2)
    lamp = bpy.data.objects["Skymodel Sun"]
    bpy.context.view_layer.update()
    to_sun = np.array(lamp.matrix_world.to_3x3().col[2][:])
    el, az = math.radians(frames[1].elevation_deg), math.radians(frames[1].azimuth_deg)
    want = np.array([math.cos(el) * math.sin(az), math.cos(el) * math.cos(az), math.sin(el)])
    assert math.degrees(math.acos(np.clip(to_sun @ want, -1.0, 1.0))) < 1e-3
    # the moon (up all evening, half lit) is a second lamp keyframed per frame, from the core
    from skymodel.astro.moon import moon_position

    moon = bpy.data.objects["Skymodel Moon"]
    atm = physics.resolve(s.to_params()).atmosphere
    pos = moon_position(atm.latitude, atm.longitude, frames[1].time_utc.rstrip("Z"))
    to_moon = np.array(moon.matrix_world.to_3x3().col[2][:])
    el, az = math.radians(float(pos.elevation_deg)), math.radians(float(pos.azimuth_deg))
    want = np.array([math.cos(el) * math.sin(az), math.cos(el) * math.cos(az), math.sin(el)])
    assert math.degrees(math.atan2(np.linalg.norm(np.cross(to_moon, want)), to_moon @ want)) < 1e-3  # float32
    assert moon.data.energy == pytest.approx(physics.moon_lamp(physics.resolve(s.to_params()))["strength"], rel=1e-5)
    moon_energy = moon.data.energy
    sc.frame_set(1)
    assert moon.data.energy != moon_energy  # keyframed, not constant
    # the exposure and the lamp follow the frames
    exposures, strengths = [], []
    for k in (1, 3):
        sc.frame_set(k)
        exposures.append(sc.view_settings.exposure)
        strengths.append(lamp.data.energy)
    assert exposures[1] > exposures[0] + 0.5 and strengths[1] < strengths[0] / 2
    # F12 at frame 1 and frame 3: the world shows each frame's own image
    renders = {k: _render(sc, k) for k in (1, 3)}
    for k, img in renders.items():
        baked = _pixels(folder / f"sky_{k:04d}.exr")
        ratio = (img[:8] @ LUMA).mean() / (baked[:8] @ LUMA).mean()
        assert abs(ratio - 1.0) < 0.05, (k, ratio)
    assert (renders[3][:8] @ LUMA).mean() < 0.5 * (renders[1][:8] @ LUMA).mean()
    assert animation.stale_frames(sc) == []
    assert animation.bake_warning(sc) is None and animation.render_frame_warning(sc) is None
    sc.frame_set(2)
    s.minute = 50
    s.keyframe_insert("minute", frame=2)
    assert animation.stale_frames(sc) == [2]
    # the panel sees the changed keyframes; an F12 render of frame 2 warns in one line, frame 1 does not
    assert animation.bake_warning(sc) == "Bake is stale: keyframes changed; bake again"
    capsys.readouterr()
    _render(sc, 2)
    err = [line for line in capsys.readouterr().err.splitlines() if line.startswith("skymodel: WARNING")]
    assert len(err) == 1 and "frame 2 renders the sky baked for" in err[0] and "18:50:00Z" in err[0], err
    _render(sc, 1)
    assert "skymodel: WARNING" not in capsys.readouterr().err
    # a setting changed without a keyframe (the place): the current frame no longer matches its image
    sc.frame_set(2)
    s.minute = 45
    s.keyframe_insert("minute", frame=2)  # the keyframes as baked again (18:45 UTC)
    sc.frame_set(1)
    assert animation.bake_warning(sc) is None
    s.location = "rural"
    assert animation.bake_warning(sc) == "Frame 1 differs from its bake; bake again"
    sc.frame_end = 5
    assert animation.bake_warning(sc).startswith("Frames outside the bake (1..3)")


def _render(sc, frame):
    from blender_addon.render import render_linear

    cd = bpy.data.cameras.get("Test Camera") or bpy.data.cameras.new("Test Camera")
    cd.type = "PANO"
    cd.panorama_type = "EQUIRECTANGULAR"
    cam = bpy.data.objects.get("Test Camera") or bpy.data.objects.new("Test Camera", cd)
    if cam.name not in sc.collection.objects:
        sc.collection.objects.link(cam)
    sc.camera = cam
    cam.rotation_euler = (math.radians(90.0), 0.0, -math.radians(90.0))  # centred on east, as the image
    sc.render.engine = "CYCLES"
    sc.cycles.device = "CPU"
    sc.cycles.samples = 4
    sc.cycles.use_denoising = False
    sc.render.resolution_x, sc.render.resolution_y = 32, 16
    sc.render.resolution_percentage = 100
    sc.frame_set(frame)
    return render_linear(sc)


def _snapshot(sc):
    d = {kind: sorted(db.name for db in getattr(bpy.data, kind)) for kind in ("objects", "lights", "images", "actions")}
    d["nodes"] = sorted(n.name for n in sc.world.node_tree.nodes)
    d["keys"] = sorted(sc.keys())
    d["exposure"] = sc.view_settings.exposure
    d["frame"] = sc.frame_current
    return d


def test_a_cancelled_or_refused_bake_leaves_the_scene_unchanged(day, tmp_path, monkeypatch):
    from blender_addon import animation
    from skymodel.errors import SkymodelInputError

    sc, _ = day
    before = _snapshot(sc)
    monkeypatch.setattr(animation, "CANCEL_AT", 2)
    with pytest.raises(animation.BakeCancelled):
        animation.bake(bpy.context, folder=str(tmp_path / "bake"))
    assert _snapshot(sc) == before
    assert not (tmp_path / "bake").exists() or not any((tmp_path / "bake").iterdir())
    # a bad frame is refused before any rendering, naming the frame (a night frame is built since
    # issue 24: tests/test_addon_night.py)
    monkeypatch.setattr(animation, "CANCEL_AT", None)
    sc.frame_end = 4
    s = sc.world.skymodel
    s.month, s.day = 2, 30  # no such day
    s.keyframe_insert("month", frame=4)
    s.keyframe_insert("day", frame=4)
    with pytest.raises(SkymodelInputError, match="frame 4"):
        animation.bake(bpy.context, folder=str(tmp_path / "bake"))
    assert not (tmp_path / "bake").exists() or not any((tmp_path / "bake").iterdir())


def test_remove_sky_after_a_bake_removes_the_exposure_keys_and_images(day, tmp_path):
    from blender_addon import animation

    sc, _ = day
    exposure_before = sc.view_settings.exposure
    r = animation.bake(bpy.context, folder=str(tmp_path / "bake"))
    assert os.path.isdir(r["folder"])
    assert bpy.ops.skymodel.remove_sky() == {"FINISHED"}
    assert animation.bake_record(sc) is None and not os.path.isdir(r["folder"])
    assert not [db for db in bpy.data.images if db.name.startswith(animation.SEQUENCE_NAME)]
    sc.frame_set(3)
    assert sc.view_settings.exposure == pytest.approx(exposure_before)


def test_headless_entry_renders_a_day(new_sky_scene, small_preview, tmp_path, monkeypatch, capsys):
    from blender_addon import render

    monkeypatch.setenv("SKYMODEL_CACHE_DIR", str(tmp_path / "cache"))
    new_sky_scene()
    out = tmp_path / "frames"
    day = ["--location", "zaragoza", "--date", "2026-06-21", "--from", "20:00", "--to", "21:30", "--every", "45min",
           "--timezone", "Europe/Madrid", "--size", "16x8", "--samples", "1", "--image-width", "32"]
    assert render.main([*day, "--out", str(out)]) == 0
    pngs = sorted(p.name for p in out.glob("frame_*.png"))
    assert pngs == ["frame_0001.png", "frame_0002.png", "frame_0003.png"]
    assert (out / "frame_0001.png").read_bytes() != (out / "frame_0003.png").read_bytes()
    exrs = sorted(out.glob("bake-*/sky_*.exr"))
    assert len(exrs) == 3
    # each frame its own sky (the keyframes evaluated in the render scene): the baked images and
    # the rendered frames' pixels differ (PNG bytes alone differ by their metadata)
    assert exrs[0].read_bytes() != exrs[2].read_bytes()
    assert not np.array_equal(_pixels(out / "frame_0001.png"), _pixels(out / "frame_0003.png"))
    # refused before any work, naming the option
    capsys.readouterr()
    # (a night is no longer refused: tests/test_addon_night.py)
    assert render.main([*day[:2], "--date", "2026-12-21", *day[4:6], "--to", "19:59", *day[8:],
                        "--out", str(tmp_path / "bad")]) == 2
    assert "time_to=" in capsys.readouterr().err and not (tmp_path / "bad").exists()
