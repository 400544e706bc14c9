"""Live update of the World panel (issue #23): debounced background builds, a preview
while the settings move and the chosen quality once they stop, stale results never shown.

Headless bpy has no event loop, so the timer is run by calling ``live.tick(now=...)``
with a fake clock; the builds run in their real background threads (waited for with
``job.wait``). Tiny images (preview 16 px wide, final 32 px) and small preview tables."""

import math

import pytest

bpy = pytest.importorskip("bpy")
import numpy as np  # noqa: E402

pytestmark = pytest.mark.blender


class FakeClock:
    def __init__(self):
        self.t = 1000.0

    def __call__(self):
        return self.t


@pytest.fixture
def live_scene(new_sky_scene, small_preview, monkeypatch, tmp_path):
    """A scene whose panel asks for preview quality at 32 px, with the live preview at 16 px."""
    from blender_addon import live

    monkeypatch.setenv("SKYMODEL_CACHE_DIR", str(tmp_path / "cache"))
    clock = FakeClock()
    monkeypatch.setattr(live, "clock", clock)
    monkeypatch.setattr(live, "PREVIEW_WIDTH", 16)
    live.reset()
    sc = new_sky_scene(image_width=32)
    yield sc, clock, live
    live.reset()


def _run_job(live):
    job = live.STATE.job
    assert job is not None
    assert job.wait(300), "the live build did not finish"
    return job


def _image(world):
    img = next(n.image for n in world.node_tree.nodes if n.bl_idname == "ShaderNodeTexEnvironment")
    w, h = img.size
    px = np.empty(w * h * 4, np.float32)
    img.pixels.foreach_get(px)
    return px.reshape(h, w, 4)[::-1, :, :3]


def _lamp(sc):
    return bpy.data.objects["Skymodel Sun"]


def test_quick_changes_give_one_preview_then_the_chosen_quality_matching_the_core(live_scene, tmp_path):
    from blender_addon import physics

    sc, clock, live = live_scene
    s = sc.world.skymodel
    s.image_storage = "BESIDE"  # previews are packed all the same; only the chosen quality goes beside the .blend
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "live.blend"))
    s.live_update = True
    for el in (10.0, 12.0, 14.0):  # a drag: three changes within the debounce time
        clock.t += 0.05
        s.sun_elevation = math.radians(el)
    assert live.STATE.generation == 4 and live.STATE.job is None
    assert live.tick() == live.POLL_S and live.STATE.job is None  # still within the debounce
    clock.t += live.DEBOUNCE_S
    live.tick()
    job = _run_job(live)
    assert (job.stage, job.generation) == ("preview", 4)
    clock.t += 0.1
    live.tick()  # applies the preview
    assert live.STATE.shown == (4, "preview") and live.STATE.builds["preview"] == 1
    assert tuple(bpy.data.images["Skymodel Sky"].size) == (16, 8)
    assert abs(_lamp(sc)["skymodel_sun_elevation_deg"] - 14.0) < 1e-4
    assert "Live update: preview" in s.last_info
    assert bpy.data.images["Skymodel Sky"].packed_file is not None  # previews are packed, whatever the storage
    live.tick()
    assert live.STATE.job is None  # the chosen quality waits until the settings have been still for SETTLE_S
    clock.t += live.SETTLE_S
    live.tick()
    job = _run_job(live)
    assert (job.stage, job.generation) == ("final", 4)
    live.tick()
    assert live.STATE.shown == (4, "final") and live.STATE.builds == {"preview": 1, "final": 1, "cancelled": 0,
                                                                      "dropped": 0}
    assert live.tick() is None  # idle: the timer ends
    assert [p.suffix for p in (tmp_path / "skymodel_sky").iterdir()] == [".exr"]  # the final one only
    assert bpy.data.images["Skymodel Sky"].packed_file is None
    # the scene shows the core's image of the final parameters (rendered afresh in another cache)
    sky = physics.resolve(s.to_params())
    rgb, res = physics.render_environment(sky, tmp_path / "other-cache")
    img = _image(sc.world)
    assert img.shape == rgb.shape == (16, 32, 3)
    np.testing.assert_allclose(img, rgb, rtol=1e-6, atol=0)
    assert _lamp(sc).data.energy == pytest.approx(res.sun_strength, rel=1e-6)
    assert sc.view_settings.exposure == pytest.approx(res.exposure, abs=1e-5)


def _settle(live, clock, stages=3):
    """Run the timer until idle: each pending build started, waited for and applied."""
    for _ in range(stages):
        clock.t += live.SETTLE_S
        live.tick()
        if live.STATE.job is not None:
            _run_job(live)
            live.tick()


def test_a_change_during_a_build_supersedes_it_and_older_skies_are_never_shown(live_scene):
    sc, clock, live = live_scene
    s = sc.world.skymodel
    s.live_update = True
    s.sun_elevation = math.radians(20.0)
    clock.t += live.DEBOUNCE_S
    live.tick()
    first = live.STATE.job
    assert (first.stage, first.generation) == ("preview", 2)
    # a change while a preview runs: it goes on, is shown (nothing newer is), then 30 degrees follows
    s.sun_elevation = math.radians(30.0)
    assert not first.cancelled.is_set() and live.STATE.job is first
    _run_job(live)
    live.tick()
    assert live.STATE.shown == (2, "preview") and abs(_lamp(sc)["skymodel_sun_elevation_deg"] - 20.0) < 1e-4
    assert live.STATE.job is None  # the next waits for the debounce
    clock.t += live.DEBOUNCE_S
    live.tick()
    _run_job(live)
    live.tick()
    assert live.STATE.shown == (3, "preview") and abs(_lamp(sc)["skymodel_sun_elevation_deg"] - 30.0) < 1e-4
    # a change while the chosen quality is built: that build is cancelled, set aside, never shown
    clock.t += live.SETTLE_S
    live.tick()
    final = live.STATE.job
    assert (final.stage, final.generation) == ("final", 3)
    s.sun_elevation = math.radians(40.0)
    assert final.cancelled.is_set() and live.STATE.builds["cancelled"] == 1
    assert live.STATE.job is None and live.running() == final.running
    clock.t += live.DEBOUNCE_S
    live.tick()  # the next build starts at once, beside the cancelled one if that still runs
    _run_job(live)
    assert final.wait(300)
    live.tick()
    assert live.STATE.shown == (4, "preview") and abs(_lamp(sc)["skymodel_sun_elevation_deg"] - 40.0) < 1e-4
    # the chosen quality finished after a newer change (before the timer applied it): dropped
    clock.t += live.SETTLE_S
    live.tick()
    _run_job(live)
    s.sun_elevation = math.radians(50.0)
    live.tick()
    assert live.STATE.shown == (4, "preview") and live.STATE.builds["dropped"] == 1
    _settle(live, clock)
    assert live.STATE.shown == (5, "final") and abs(_lamp(sc)["skymodel_sun_elevation_deg"] - 50.0) < 1e-4
    assert live.STATE.history == [(2, "preview"), (3, "preview"), (4, "preview"), (5, "preview"), (5, "final")]
    assert not live.running()


def test_a_long_drag_shows_previews_while_it_moves_in_order(live_scene):
    sc, clock, live = live_scene
    s = sc.world.skymodel
    s.live_update = True
    live.stop()
    elevation, started = 10.0, []
    for _ in range(30):  # a drag: a change every 0.1 s for 3 s (never still for the debounce time)
        elevation += 1.0
        clock.t += 0.1
        s.sun_elevation = math.radians(elevation)
        live.tick()
        job = live.STATE.job
        if job is not None and job not in started:
            started.append(job)
            job.wait(300)  # a fast build: done before the next change
    assert len(started) >= 4  # a preview every DRAG_REFRESH_S while the slider moves
    assert all(j.stage == "preview" for j in started)
    shown_during_drag = list(live.STATE.history)
    assert len(shown_during_drag) >= 3 and live.STATE.shown[0] < live.STATE.generation
    _settle(live, clock)
    gens = [g for g, _ in live.STATE.history]
    assert gens == sorted(gens) and live.STATE.shown == (live.STATE.generation, "final")
    assert abs(_lamp(sc)["skymodel_sun_elevation_deg"] - elevation) < 1e-4


def test_bad_input_is_named_and_leaves_the_scene_as_it_was(live_scene):
    sc, clock, live = live_scene
    s = sc.world.skymodel
    s.live_update = True
    clock.t += live.DEBOUNCE_S
    live.tick()
    _run_job(live)
    live.tick()  # the first stage's sky is shown
    names = sorted(o.name for o in bpy.data.objects)
    exposure = sc.view_settings.exposure
    info = s.last_info
    s.sun_source = "TIME"
    s.location = "zaragoza"
    s.year, s.month, s.day, s.hour, s.minute = 2026, 3, 29, 2, 30
    s.timezone = "Europe/Madrid"  # 02:30 does not exist there that night
    clock.t += live.DEBOUNCE_S
    assert live.tick() is None
    assert "time_utc" in live.STATE.error and "skipped" in live.STATE.error and "daylight saving" in live.STATE.error
    s.timezone = "Europe/Zaragoza"
    clock.t += live.DEBOUNCE_S
    live.tick()
    assert "timezone" in live.STATE.error and "IANA" in live.STATE.error
    assert sorted(o.name for o in bpy.data.objects) == names
    assert sc.view_settings.exposure == exposure and s.last_info == info


def test_live_update_off_builds_nothing_and_switching_off_cancels(live_scene):
    sc, clock, live = live_scene
    s = sc.world.skymodel
    s.sun_elevation = math.radians(25.0)
    assert live.STATE.generation == 0 and live.STATE.pending is None
    s.live_update = True
    clock.t += live.DEBOUNCE_S
    live.tick()
    job = live.STATE.job
    s.live_update = False
    assert job.cancelled.is_set() and live.STATE.pending is None
    job.wait(300)
    assert live.tick() is None and live.STATE.shown is None
    s.mode = "VOLUMETRIC"
    s.live_update = True
    clock.t += live.DEBOUNCE_S
    assert live.tick() is None and live.STATE.job is None
    assert "Environment mode" in live.STATE.status


def test_build_sky_cancels_a_live_build_first(live_scene):
    from blender_addon import ops

    sc, clock, live = live_scene
    s = sc.world.skymodel
    s.live_update = True
    clock.t += live.DEBOUNCE_S
    live.tick()
    job = live.STATE.job
    assert job is not None and job.stage == "preview"
    assert bpy.ops.skymodel.build_sky() == {"FINISHED"}  # waits for the cancelled thread, then builds
    assert job.cancelled.is_set() and not live.running() and live.STATE.pending is None
    assert tuple(bpy.data.images["Skymodel Sky"].size) == (32, 16)  # the panel's own quality
    assert live.tick() is None
    assert tuple(bpy.data.images["Skymodel Sky"].size) == (32, 16) and live.STATE.shown is None
    # a deferred Build Sky job (the modal one waits for a live thread): running until started
    deferred = ops.BuildJob(bpy.context)
    deferred.deferred = True
    assert deferred.running and not deferred.wait(0.01)
    deferred.cancel()
    assert not deferred.running


def test_a_panel_at_preview_quality_needs_no_second_build_and_remove_sky_stops_live(live_scene, monkeypatch):
    sc, clock, live = live_scene
    monkeypatch.setattr(live, "PREVIEW_WIDTH", 64)  # the panel's 32 px preview is its own final sky
    s = sc.world.skymodel
    s.live_update = True
    clock.t += live.DEBOUNCE_S
    live.tick()
    job = live.STATE.job
    assert job.stage == "preview"
    s.sun_elevation = math.radians(33.0)  # a drag: the running preview is not cancelled
    assert not job.cancelled.is_set()
    _run_job(live)
    live.tick()
    assert live.STATE.shown == (1, "preview")  # values of a moment ago
    clock.t += live.DEBOUNCE_S
    live.tick()
    _run_job(live)
    live.tick()
    assert live.STATE.shown == (2, "final") and live.tick() is None  # no second build
    assert live.STATE.builds == {"preview": 2, "final": 0, "cancelled": 0, "dropped": 0}
    # a change, then Remove Sky while its build runs: the sky does not come back
    s.sun_elevation = math.radians(35.0)
    clock.t += live.DEBOUNCE_S
    live.tick()
    job = live.STATE.job
    assert bpy.ops.skymodel.remove_sky() == {"FINISHED"}
    job.wait(300)
    live.tick()
    assert "Skymodel Sun" not in bpy.data.objects and "Skymodel Sky" not in bpy.data.images
    # switching to Volumetric while a build runs: its environment sky is not applied
    s.sun_elevation = math.radians(36.0)
    clock.t += live.DEBOUNCE_S
    live.tick()
    job = live.STATE.job
    s.mode = "VOLUMETRIC"
    job.wait(300)
    live.tick()
    assert "Skymodel Sun" not in bpy.data.objects


def test_live_update_follows_a_time_into_the_night(live_scene):
    """Dragging the hour from dusk into the night (issue 24): the live preview is the core's night
    (sun lamp 0, the info box's night line), no refusal."""
    sc, clock, live = live_scene
    s = sc.world.skymodel
    s.sun_source, s.timezone, s.moon_lamp = "TIME", "UTC", True
    s.year, s.month, s.day, s.hour, s.minute = 2026, 12, 21, 16, 0  # rural: sun -5.8
    s.live_update = True
    for hour in (17, 18, 20):  # -14.9, -24.7, -44.6 deg
        clock.t += 0.05
        s.hour = hour
    clock.t += live.DEBOUNCE_S
    live.tick()
    job = _run_job(live)
    assert job.stage == "preview"
    clock.t += 0.1
    live.tick()
    assert live.STATE.shown[1] == "preview"
    assert _lamp(sc).data.energy == 0.0 and _lamp(sc)["skymodel_sun_elevation_deg"] < -40.0
    assert "Night (no sunlit sky below -18°)" in s.last_info and "Live update: preview" in s.last_info
