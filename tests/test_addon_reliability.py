"""The add-on as an artist relies on it (issue 21): Remove Sky puts back everything Build
Sky changed, the exposure keeps the colours of a low sun, the sky survives a missing cache,
a build can be cancelled, Auto mode counts the cost. Headless (bpy module, Cycles CPU),
tiny images."""

import math
import os

import pytest

bpy = pytest.importorskip("bpy")
import numpy as np  # noqa: E402

pytestmark = pytest.mark.blender


@pytest.fixture
def scene(new_sky_scene):
    from blender_addon import builder

    builder.FAIL_AT = None
    sc = new_sky_scene(image_width=64)
    yield sc
    builder.FAIL_AT = None


def rna_dump(obj, depth=3, seen=None):
    """Every readable property of ``obj`` (an RNA struct) as plain data: values, the names of
    datablocks pointed to, and nested structs (not datablocks) down to ``depth``."""
    seen = set() if seen is None else seen
    out = {}
    try:
        key = obj.as_pointer()
    except (AttributeError, ReferenceError):
        return repr(obj)
    if key in seen:
        return "<seen>"
    seen.add(key)
    for prop in obj.bl_rna.properties:
        name = prop.identifier
        if name in ("rna_type", "depsgraph") or name.startswith("is_evaluated"):
            continue
        try:
            value = getattr(obj, name)
        except (AttributeError, RuntimeError, TypeError):
            continue
        if prop.type == "POINTER":
            if value is None:
                out[name] = None
            elif isinstance(value, bpy.types.ID):
                out[name] = ("ID", value.name)
            elif depth > 0:
                out[name] = rna_dump(value, depth - 1, seen)
        elif prop.type == "COLLECTION":
            items = list(value)
            if items and isinstance(items[0], bpy.types.ID):
                out[name] = sorted(i.name for i in items)
            elif depth > 0 and len(items) <= 64:
                out[name] = [rna_dump(i, depth - 1, seen) for i in items]
            else:
                out[name] = len(items)
        else:
            try:
                out[name] = tuple(value) if hasattr(value, "__len__") and not isinstance(value, str) else value
            except TypeError:
                out[name] = repr(value)
    try:
        out["<custom>"] = sorted((k, repr(obj[k].to_dict() if hasattr(obj[k], "to_dict") else obj[k]))
                                 for k in obj.keys())
    except (AttributeError, TypeError):
        pass
    return out


def full_snapshot(sc):
    """Every scene, world, view-layer, camera and render property, and the datablocks."""
    bpy.context.view_layer.update()
    d = {"scene": rna_dump(sc, depth=4), "view_layers": [rna_dump(v, depth=3) for v in sc.view_layers],
         "render": rna_dump(sc.render, depth=3), "cycles": rna_dump(sc.cycles, depth=2),
         "view_settings": rna_dump(sc.view_settings, depth=3),
         "display_settings": rna_dump(sc.display_settings, depth=2),
         "cameras": {c.name: rna_dump(c, depth=3) for c in bpy.data.cameras},
         "worlds": {w.name: rna_dump(w, depth=3) for w in bpy.data.worlds}}
    for w in bpy.data.worlds:
        nt = w.node_tree
        d["world_nodes_" + w.name] = sorted((n.name, n.bl_idname, tuple(n.location)) for n in nt.nodes)
        d["world_links_" + w.name] = sorted((lk.from_node.name, lk.from_socket.identifier, lk.to_node.name,
                                             lk.to_socket.identifier) for lk in nt.links)
    for kind in ("objects", "meshes", "lights", "images", "materials", "collections", "worlds", "cameras",
                 "node_groups", "scenes"):
        d[kind] = sorted(db.name for db in getattr(bpy.data, kind))
    return d


def diff(a, b, path=""):
    """Paths where two snapshots differ (for a readable failure)."""
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for k in sorted(set(a) | set(b), key=str):
            out += diff(a.get(k, "<missing>"), b.get(k, "<missing>"), f"{path}.{k}")
        return out
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        out = []
        for i, (x, y) in enumerate(zip(a, b)):
            out += diff(x, y, f"{path}[{i}]")
        return out
    return [] if a == b else [f"{path}: {a!r} -> {b!r}"]


def add_camera(sc, clip_end=100.0):
    cd = bpy.data.cameras.new("User Camera")
    cd.clip_end = clip_end
    cam = bpy.data.objects.new("User Camera", cd)
    sc.collection.objects.link(cam)
    sc.camera = cam
    cam.location = (0.0, -10.0, 1.7)
    cam.rotation_euler = (math.radians(90.0), 0.0, 0.0)
    return cam


# ------------------------------------------------------------------ 1. Remove restores


@pytest.mark.parametrize("mode", ["ENVIRONMENT", "VOLUMETRIC"])
def test_remove_sky_restores_every_property_build_changed(scene, mode):
    """Snapshot every scene, world, view-layer, camera and render property; Build; Remove;
    the snapshot is identical (the engine, exposure, view transform, bounces and clip end
    all differ from the build's values before it)."""
    add_camera(scene, clip_end=100.0)
    scene.render.engine = "BLENDER_WORKBENCH"
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.exposure = 0.5
    scene.cycles.volume_bounces = 0
    scene.cycles.max_bounces = 3
    scene.cycles.transparent_max_bounces = 2
    s = scene.world.skymodel
    s.mode = mode
    s.n_layers = 2
    s.volume_bounces = 1
    s.sun_elevation = math.radians(20.0)
    before = full_snapshot(scene)
    assert bpy.ops.skymodel.build_sky() == {"FINISHED"}
    built = full_snapshot(scene)
    changed = diff(before, built)
    assert any("exposure" in c for c in changed) and any("view_transform" in c for c in changed)
    if mode == "VOLUMETRIC":
        assert scene.render.engine == "CYCLES" and bpy.data.cameras["User Camera"].clip_end >= 2e7
    # a rebuild (another sun) keeps the values from before the first build
    s.sun_elevation = math.radians(25.0)
    assert bpy.ops.skymodel.build_sky() == {"FINISHED"}
    assert bpy.ops.skymodel.remove_sky() == {"FINISHED"}
    after = full_snapshot(scene)
    problems = [d for d in diff(before, after) if ".last_build" not in d and ".last_info" not in d]
    assert problems == []


def test_remove_keeps_a_setting_the_user_changed_after_the_build(scene):
    scene.view_settings.exposure = 0.25
    assert bpy.ops.skymodel.build_sky() == {"FINISHED"}
    assert scene.view_settings.exposure != pytest.approx(0.25)
    scene.view_settings.exposure = 1.5  # the artist's own choice after the build
    assert bpy.ops.skymodel.remove_sky() == {"FINISHED"}
    assert scene.view_settings.exposure == pytest.approx(1.5)
    assert scene.view_settings.view_transform == "AgX" or scene.view_settings.view_transform != ""


def test_switching_modes_puts_back_what_only_the_previous_build_changed(scene):
    scene.render.engine = "BLENDER_WORKBENCH"
    s = scene.world.skymodel
    s.mode, s.n_layers, s.volume_bounces = "VOLUMETRIC", 2, 1
    assert bpy.ops.skymodel.build_sky() == {"FINISHED"}
    assert scene.render.engine == "CYCLES"
    s.mode = "ENVIRONMENT"
    assert bpy.ops.skymodel.build_sky() == {"FINISHED"}
    assert scene.render.engine == "BLENDER_WORKBENCH"


# ------------------------------------------------------------------ 2. exposure at a low sun


def _sky_display(elevation, tmp_path, exposure_rule="SKY", offset=0.0):
    """Environment mode, headless, rural, June, a 256x128 panorama centred on the sun
    through AgX to an 8-bit PNG: (mean largest channel, mean HSV saturation) of the sky
    above the horizon, and the exposure set."""
    from blender_addon import render

    o = render.parse_args(["--location", "rural", "--month", "6", "--sun-elevation", str(elevation),
                           "--mode", "environment", "--samples", "4", "--size", "256x128", "--image-width", "256",
                           "--out", str(tmp_path / "x.png")])
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = render.build_scene(o, progress=None)
    if exposure_rule != "SKY" or offset:
        s = sc.world.skymodel
        s.exposure_rule, s.exposure_offset = exposure_rule, offset
        from blender_addon import ops

        ops.build(_Ctx(sc))
    path = str(tmp_path / f"sky_{elevation}_{exposure_rule}.png")
    sc.render.image_settings.color_depth = "8"
    render._render(sc, path, "PNG")
    img = bpy.data.images.load(path, check_existing=False)
    w, h = img.size
    px = np.empty(w * h * 4, np.float32)
    img.pixels.foreach_get(px)
    bpy.data.images.remove(img)
    sky = px.reshape(h, w, 4)[::-1, :, :3][: h // 2]
    mx, mn = sky.max(axis=-1), sky.min(axis=-1)
    sat = np.where(mx > 0, (mx - mn) / np.maximum(mx, 1e-12), 0.0)
    return float(mx.mean()), float(sat.mean()), sc.view_settings.exposure


class _Ctx:
    def __init__(self, scene):
        self.scene, self.window_manager = scene, None


def test_exposure_keeps_sunset_and_twilight_colours(addon, tmp_path):
    """Sun 0 and -4 degrees display no brighter than sun 30 (mean largest channel) and keep
    their colour (mean saturation >= 0.22); the incident rule alone washes them out."""
    ref_bright, ref_sat, ref_ev = _sky_display(30.0, tmp_path)
    for el in (0.0, -4.0):
        bright, sat, _ = _sky_display(el, tmp_path)
        assert bright <= ref_bright, (el, bright, ref_bright)
        assert sat >= 0.22, (el, sat)
    washed, washed_sat, _ = _sky_display(0.0, tmp_path, exposure_rule="INCIDENT")
    assert washed > ref_bright and washed_sat < 0.22  # what the issue measured (0.80, 0.11)
    # midday: the incident-light rule's exposure, within 0.3 EV
    _, _, incident_ev = _sky_display(30.0, tmp_path, exposure_rule="INCIDENT")
    assert abs(ref_ev - incident_ev) <= 0.3


def test_exposure_offset_and_rule_add_to_the_build(scene):
    s = scene.world.skymodel
    s.sun_elevation = math.radians(-2.0)
    assert bpy.ops.skymodel.build_sky() == {"FINISHED"}
    base = scene.view_settings.exposure
    s.exposure_offset = 1.5
    assert bpy.ops.skymodel.build_sky() == {"FINISHED"}
    assert scene.view_settings.exposure == pytest.approx(base + 1.5, abs=1e-5)
    s.exposure_offset = 0.0
    s.exposure_rule = "INCIDENT"
    assert bpy.ops.skymodel.build_sky() == {"FINISHED"}
    assert scene.view_settings.exposure > base + 2.0  # the incident rule is 2-3 EV brighter at -2 degrees


# ------------------------------------------------------------------ 4. the sky survives its cache


def _pixels(img):
    px = np.empty(img.size[0] * img.size[1] * img.channels, np.float32)
    img.pixels.foreach_get(px)
    return px


def test_reopened_blend_without_the_cache_has_the_same_sky(scene, tmp_path):
    """Packed by default: save, clear the cache, reopen: the same pixels (no magenta)."""
    from blender_addon import ops

    s = scene.world.skymodel
    assert s.image_storage == "PACK"
    assert bpy.ops.skymodel.build_sky() == {"FINISHED"}
    img = bpy.data.images["Skymodel Sky"]
    assert img.packed_file is not None
    before = _pixels(img)
    blend = str(tmp_path / "sunset.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend)
    assert bpy.ops.skymodel.clear_cache() == {"FINISHED"}
    assert not list(ops.cache_dir().glob("sky-*"))
    bpy.ops.wm.open_mainfile(filepath=blend)
    img = bpy.data.images["Skymodel Sky"]
    assert img.has_data or img.size[0] > 0
    np.testing.assert_array_equal(_pixels(img), before)


def test_image_saved_beside_the_blend(scene, tmp_path):
    from blender_addon import builder, ops

    s = scene.world.skymodel
    s.image_storage = "BESIDE"
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "beside.blend"))
    sc = bpy.context.scene
    assert bpy.ops.skymodel.build_sky() == {"FINISHED"}
    img = bpy.data.images["Skymodel Sky"]
    assert img.packed_file is None and img.filepath.startswith("//" + builder.BESIDE_FOLDER + "/")
    assert (tmp_path / builder.BESIDE_FOLDER / img.filepath.split("/")[-1]).is_file()
    assert builder.BESIDE_FOLDER in sc.world.skymodel.last_info
    ops.clear_cache()  # the copy beside the .blend stays
    img.reload()
    assert img.size[0] == 64


def test_corrupt_cached_exr_is_detected_and_rebuilt(scene):
    from blender_addon import ops

    assert bpy.ops.skymodel.build_sky() == {"FINISHED"}
    exr = next(ops.cache_dir().glob("sky-*.exr"))
    good = exr.read_bytes()
    ctx = _Ctx(scene)
    assert ops.build(ctx).cache_hit
    damaged = bytearray(good)
    damaged[len(good) // 2] ^= 0xFF  # one flipped byte in the pixel data: same size
    exr.write_bytes(bytes(damaged))
    lines = []
    res = ops.build(ctx, progress=lines.append)
    assert not res.cache_hit and any("damaged" in t for t in lines)
    assert exr.read_bytes() == good  # rendered again, the same image
    exr.write_bytes(good[: len(good) // 3])  # truncated
    assert not ops.build(ctx).cache_hit
    assert ops.build(ctx).cache_hit


def test_clear_cache_reports_what_it_freed_and_keeps_the_scene(scene):
    from blender_addon import ops

    from skymodel.render import environment

    scene.world.skymodel.image_storage = "PACK"
    assert bpy.ops.skymodel.build_sky() == {"FINISHED"}
    folder = ops.cache_dir()
    n_files = len(list(folder.glob("sky-*")))
    assert n_files >= 2
    # the multiple-scattering solutions the build stores in solutions/ (the build may have
    # taken its solution from memory and written none: then one named as the cache names
    # them, SolutionCache.path, and a temporary of one being written, as mkstemp names it)
    solutions = folder / environment.SOLUTIONS_FOLDER
    solutions.mkdir(exist_ok=True)
    stored = environment.solution_cache(folder).path("0123456789abcdef" * 2)
    assert stored.parent == solutions
    stored.write_bytes(b"\0" * 1000)
    (solutions / f"{stored.name}.k2j4x9.tmp").write_bytes(b"\0" * 10)
    ours = sorted(solutions.glob("solution-*"))
    assert len(ours) >= 2
    solution_bytes = sum(f.stat().st_size for f in ours)
    (folder / "not-ours.txt").write_text("keep")
    (solutions / "notes.txt").write_text("keep")
    assert environment.cache_size(folder) == (n_files + len(ours), sum(
        f.stat().st_size for f in [*folder.glob("sky-*"), *ours]))
    r = ops.clear_cache()
    assert r["files"] == n_files + len(ours) and r["bytes"] > solution_bytes
    assert not any(solutions.glob("solution-*"))
    assert (folder / "not-ours.txt").is_file() and (solutions / "notes.txt").is_file()
    (folder / "not-ours.txt").unlink()
    (solutions / "notes.txt").unlink()
    assert bpy.data.images["Skymodel Sky"].size[0] == 64
    assert ops.clear_cache()["files"] == 0
    assert not solutions.exists()  # the emptied solutions/ goes too
    # a build after the clear still works (from the solution in memory or solved again)
    assert bpy.ops.skymodel.build_sky() == {"FINISHED"}
    # refused while a build runs (it writes into the folder)
    saved_job = ops.JOB

    class _Running:
        running = True

    ops.JOB = _Running()
    try:
        with pytest.raises(RuntimeError, match="build is running"):
            ops.clear_cache()
        with pytest.raises(RuntimeError, match="build is running"):  # the operator reports an ERROR
            bpy.ops.skymodel.clear_cache()
    finally:
        ops.JOB = saved_job
    assert any(folder.glob("sky-*"))
    ops.clear_cache()


def test_cache_lives_outside_the_extension_folder(addon, monkeypatch):
    from blender_addon import ops

    monkeypatch.delenv("SKYMODEL_CACHE_DIR", raising=False)
    folder = ops.cache_dir()
    assert folder.is_dir()
    assert os.path.commonpath([str(folder), os.path.dirname(ops.__file__)]) != os.path.dirname(ops.__file__)
    assert str(folder).startswith(os.environ["BLENDER_USER_RESOURCES"])


def test_headless_entry_interrupted_prints_one_line(addon, monkeypatch, tmp_path, capsys):
    from blender_addon import render

    def interrupt(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(render, "build_scene", interrupt)
    assert render.main(["--out", str(tmp_path / "x.png")]) == 130
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["skymodel: interrupted"]


# ------------------------------------------------------------------ 2. volumetric twilight (no bpy needed)


def _sky_luminance(profile, elevation, width=32):
    from skymodel.render.cameras import make_camera
    from skymodel.render.environment import spectrum_rgb
    from skymodel.render.sky import render_sky

    cam = make_camera("equirectangular", width, center_azimuth_deg=90.0)
    img = render_sky(profile, cam, elevation, 180.0, 0.0, "preview", include_sun=False)
    y = spectrum_rgb(img.radiance, profile.wavelengths_nm) @ np.array([0.2126, 0.7152, 0.0722])
    return y[: y.shape[0] // 2 - 1]  # above the horizon


def test_volumetric_layers_carry_twilight_within_ten_percent():
    """Sun -4 degrees: the layers Volumetric mode builds (layer_edges), rendered by the
    marcher, against the smooth atmosphere: within 10 % at TWILIGHT_MIN_LAYERS (the old equal
    optical-depth edges were 4-7x too bright at 8 layers: the cause); fewer layers warn."""
    from blender_addon import physics, volumetric
    from skymodel.wavelengths import default_wavelengths

    sky = physics.resolve(physics.SkyParams(location="rural", month=6, sun_elevation_deg=-4.0, mode="VOLUMETRIC"))
    prof = sky.profile(default_wavelengths(20.0))
    smooth = _sky_luminance(prof, -4.0)
    n = volumetric.TWILIGHT_MIN_LAYERS
    layered = _sky_luminance(prof.layered(edges_m=volumetric.layer_edges(prof, n)), -4.0)
    assert np.abs(layered / smooth - 1).max() < 0.10
    old = _sky_luminance(prof.layered(n_layers=8), -4.0)
    assert (old / smooth).mean() > 2.0
    assert volumetric.twilight_warning(-4.0, 8) and not volumetric.twilight_warning(-4.0, n)
    assert not volumetric.twilight_warning(5.0, 8)


# ------------------------------------------------------------------ 3. Auto mode counts the cost


def _auto_scene(scene, distance_m, sun_deg):
    s = scene.world.skymodel
    s.mode = "AUTO"
    s.sun_elevation = math.radians(sun_deg)
    add_camera(scene)
    scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 1920, 1080, 100
    mesh = bpy.data.meshes.new("Box")
    mesh.from_pydata([(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (0, 2)], [], [])
    obj = bpy.data.objects.new("Box", mesh)
    obj.location = (0.0, distance_m - 10.0, 0.0)  # the camera stands at y = -10
    scene.collection.objects.link(obj)
    bpy.context.view_layer.update()
    return s


def test_auto_on_a_50_m_scene_picks_environment_and_says_why(scene):
    from blender_addon import scene_description

    s = _auto_scene(scene, 50.0, 5.0)
    p = scene_description.make_plan(scene, s)
    assert 45.0 < p.scene.farthest_object_m < 60.0
    assert p.mode == "environment"
    assert "time budget" in p["aerial_perspective"].reason
    assert bpy.ops.skymodel.build_sky() == {"FINISHED"}
    assert "Skymodel Atmosphere 00" not in bpy.data.objects
    assert "Auto: Environment: predicted error" in s.last_info and " s to build" in s.last_info


def test_auto_over_tolerance_builds_but_says_so(scene):
    s = _auto_scene(scene, 30_000.0, -4.0)
    s.plan_tolerance = 0.5
    assert bpy.ops.skymodel.build_sky() == {"FINISHED"}
    assert "exceeds the tolerance" in s.last_info


def test_explicit_volumetric_in_twilight_with_few_layers_warns(scene):
    s = scene.world.skymodel
    s.mode, s.n_layers, s.volume_bounces = "VOLUMETRIC", 2, 0
    s.sun_elevation = math.radians(-4.0)
    assert bpy.ops.skymodel.build_sky() == {"FINISHED"}
    assert "Twilight: 2 layers" in s.last_info


# ------------------------------------------------------------------ 6. builds that never freeze the UI


def test_cancelled_background_build_leaves_the_scene_exactly_as_it_was(scene):
    """The modal operator's job: physics in a thread, Esc -> cancel(); nothing touched the scene."""
    from blender_addon import ops

    add_camera(scene)
    s = scene.world.skymodel
    s.sun_elevation = math.radians(7.25)  # not cached
    before = full_snapshot(scene)
    job = ops.BuildJob(_Ctx(scene))
    started = len(job.lines)
    job.start()
    job.cancel()
    assert job.wait(timeout=120)
    with pytest.raises(ops.BuildCancelled):
        job.finish(_Ctx(scene))
    assert diff(before, full_snapshot(scene)) == []
    assert not any("writing" in line for line in job.lines[started:])  # stopped before the image was written
    assert not list(ops.cache_dir().glob("sky-*.tmp"))


def test_background_build_finishes_on_the_main_thread_and_refuses_a_second(scene):
    from blender_addon import ops

    s = scene.world.skymodel
    s.sun_elevation = math.radians(8.5)
    job = ops.BuildJob(_Ctx(scene)).start()
    ops.JOB = job
    try:
        if job.running:  # a second build while one runs is refused, by the operator and the function
            with pytest.raises(RuntimeError, match="already running"):  # the operator's ERROR report
                bpy.ops.skymodel.build_sky()
            with pytest.raises(RuntimeError, match="already running"):
                ops.build(_Ctx(scene))
        assert job.wait(timeout=300)
        result = job.finish(_Ctx(scene))
    finally:
        ops.JOB = None
    assert result.mode == "ENVIRONMENT" and "Skymodel Sun" in bpy.data.objects
    assert bpy.data.objects["Skymodel Sun"]["skymodel_sun_elevation_deg"] == pytest.approx(8.5, abs=1e-4)


def test_invoke_without_a_window_builds_in_one_go(scene):
    assert bpy.ops.skymodel.build_sky("INVOKE_DEFAULT") == {"FINISHED"}
    assert "Skymodel Sun" in bpy.data.objects


def test_a_failing_background_build_reports_and_leaves_the_scene(scene, monkeypatch):
    from blender_addon import ops, physics

    before = full_snapshot(scene)

    def boom(*a, **k):
        raise FloatingPointError("sky image: non-finite values")

    monkeypatch.setattr(physics, "render_environment", boom)
    job = ops.BuildJob(_Ctx(scene)).start()
    assert job.wait(timeout=60)
    with pytest.raises(FloatingPointError):
        job.finish(_Ctx(scene))
    assert diff(before, full_snapshot(scene)) == []
