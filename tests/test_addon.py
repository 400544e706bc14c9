"""The Blender add-on, headless (bpy module, Cycles on the CPU).

Tiny images everywhere (environment images 64x32, renders 64x32 at <= 16 samples) so the
whole file runs in well under the project's few-minute budget on 2 cores."""

import math

import pytest

bpy = pytest.importorskip("bpy")
import numpy as np  # noqa: E402

pytestmark = pytest.mark.blender

LUMA = np.array([0.2126, 0.7152, 0.0722])


@pytest.fixture
def scene(new_sky_scene):
    """A fresh empty file with a world; the add-on registered (``addon``, tests/conftest.py)."""
    from blender_addon import builder

    builder.FAIL_AT = None
    sc = new_sky_scene(image_width=64)
    yield sc
    builder.FAIL_AT = None


def settings(sc):
    return sc.world.skymodel


def snapshot():
    """Everything a build could touch, as comparable plain data."""
    sc = bpy.context.scene
    bpy.context.view_layer.update()  # matrices of objects moved since the last evaluation
    d = {}
    for kind in ("objects", "meshes", "lights", "images", "materials", "collections", "worlds", "cameras",
                 "node_groups"):
        d[kind] = sorted((db.name, tuple(sorted(db.keys()))) for db in getattr(bpy.data, kind))
    d["scene_children"] = sorted(c.name for c in sc.collection.children)
    d["scene_objects"] = sorted(o.name for o in sc.objects)
    d["object_data"] = sorted((o.name, tuple(map(tuple, o.matrix_world)), o.data.name if o.data else None)
                              for o in bpy.data.objects)
    d["lamps"] = sorted((l.name, round(l.energy, 9), tuple(l.color), l.angle) for l in bpy.data.lights)
    w = sc.world
    if w is not None:
        nt = w.node_tree
        d["nodes"] = sorted((n.name, n.bl_idname, tuple(n.location), tuple(sorted(n.keys()))) for n in nt.nodes)
        d["links"] = sorted((lk.from_node.name, lk.from_socket.identifier, lk.to_node.name, lk.to_socket.identifier)
                            for lk in nt.links)
        d["world_keys"] = sorted(w.keys())
        s = w.skymodel
        d["settings"] = {p: str(getattr(s, p)) for p in s.bl_rna.properties.keys() if p not in ("rna_type", "name")}
    vs = sc.view_settings
    d["view"] = (vs.view_transform, vs.look, vs.exposure, vs.gamma)
    d["engine"] = sc.render.engine
    if sc.render.engine == "CYCLES":
        c = sc.cycles
        d["cycles"] = (c.volume_bounces, c.max_bounces, c.transparent_max_bounces)
    d["camera_clip"] = [(c.name, c.clip_end) for c in bpy.data.cameras]
    return d


def build_ok():
    assert bpy.ops.skymodel.build_sky() == {"FINISHED"}


def ours(collection):
    from blender_addon.builder import is_ours

    return [db for db in collection if is_ours(db)]


# ------------------------------------------------------------------ camera helpers


def add_pano_camera(sc, center_azimuth_deg, height=1.7):
    cd = bpy.data.cameras.new("Test Camera")
    cd.type = "PANO"
    cd.panorama_type = "EQUIRECTANGULAR"
    cd.clip_end = 2.0e7
    cam = bpy.data.objects.new("Test Camera", cd)
    sc.collection.objects.link(cam)
    sc.camera = cam
    cam.location = (0.0, 0.0, height)
    cam.rotation_euler = (math.radians(90.0), 0.0, -math.radians(center_azimuth_deg))
    return cam


def render(sc, width=64, height=32, samples=8):
    from blender_addon.render import render_linear

    sc.render.engine = "CYCLES"
    sc.cycles.device = "CPU"
    sc.cycles.samples = samples
    sc.cycles.use_denoising = False
    sc.render.resolution_x, sc.render.resolution_y = width, height
    sc.render.resolution_percentage = 100
    return render_linear(sc)


def pixel_direction(i, j, h, w, center_azimuth_deg):
    """Direction (x east, y north, z up) of pixel (row i, column j) of the equirectangular
    test camera: rows equal steps in zenith angle from the top, azimuth increasing to the
    right with the centre line at ``center_azimuth_deg`` (checked by test_camera_convention)."""
    zen = math.radians((i + 0.5) / h * 180.0)
    az = math.radians(center_azimuth_deg + ((j + 0.5) / w - 0.5) * 360.0)
    return np.array([math.sin(zen) * math.sin(az), math.sin(zen) * math.cos(az), math.cos(zen)])


def column_of_azimuth(az, w, center_azimuth_deg):
    return int(np.floor((((az - center_azimuth_deg) / 360.0 + 0.5) % 1.0) * w))


# ------------------------------------------------------------------ registration


def test_register_unregister_leaves_no_trace(addon):
    import blender_addon

    assert hasattr(bpy.types.World, "skymodel")
    blender_addon.unregister()
    try:
        assert not hasattr(bpy.types.World, "skymodel")
        for name in ("SkymodelSettings", "SKYMODEL_OT_build_sky", "SKYMODEL_OT_remove_sky", "WORLD_PT_skymodel",
                     "VIEW3D_PT_skymodel"):
            assert getattr(bpy.types, name, None) is None, name
        with pytest.raises(AttributeError):
            bpy.ops.skymodel.build_sky()
    finally:
        blender_addon.register()
    assert hasattr(bpy.types.World, "skymodel")
    assert bpy.types.WORLD_PT_skymodel.bl_context == "world"
    assert bpy.types.VIEW3D_PT_skymodel.bl_space_type == "VIEW_3D"


def test_properties_units_and_ranges(scene):
    from skymodel.optics import aerosols
    from skymodel.optics.atmosphere import locations

    props = bpy.types.World.bl_rna.properties["skymodel"].fixed_type.properties
    deg = math.pi / 180

    def rng(name):
        p = props[name]
        return p.hard_min, p.hard_max

    assert rng("month") == (1, 12)
    assert rng("latitude") == pytest.approx((-90 * deg, 90 * deg))
    assert rng("longitude") == pytest.approx((-180 * deg, 180 * deg))
    from skymodel import scene as registry

    assert rng("sun_elevation") == pytest.approx((registry.parameter("sun_elevation").minimum * deg, 90 * deg))
    assert rng("sun_azimuth") == pytest.approx((0.0, 360 * deg))
    for name in ("latitude", "longitude", "sun_elevation", "sun_azimuth"):
        assert props[name].subtype == "ANGLE" and props[name].unit == "ROTATION"
    assert rng("aod550") == pytest.approx((0.0, 10.0))
    assert rng("turbidity") == pytest.approx((1.0, 64.0))
    assert rng("ozone_du") == pytest.approx((1.0, 1000.0))
    assert rng("albedo") == pytest.approx((0.0, 1.0)) and props["albedo"].subtype == "FACTOR"
    assert props["observer_altitude"].subtype == "DISTANCE" and props["observer_altitude"].unit == "LENGTH"
    assert rng("n_layers") == (1, 24)
    assert rng("year") == (1900, 2100) and rng("day") == (1, 31) and rng("hour") == (0, 23)
    assert {i.identifier for i in props["mode"].enum_items} == {"AUTO", "ENVIRONMENT", "VOLUMETRIC"}
    assert {i.identifier for i in props["quality"].enum_items} == {"preview", "final", "reference"}
    assert {i.identifier for i in props["stratospheric"].enum_items} == {"background", "volcanic", "none"}
    # values outside the range are clamped by Blender itself
    s = settings(scene)
    s.aod550 = 50.0
    assert s.aod550 == pytest.approx(10.0)
    # the search lists come from the core
    from blender_addon import props as addon_props

    assert addon_props._location_names() == sorted(locations())
    assert set(aerosols.aerosol_types()) <= set(addon_props._aerosol_names())
    assert {"location", "none"} <= set(addon_props._aerosol_names())


# ------------------------------------------------------------------ input errors


def test_custom_place_takes_the_location_rule_and_the_site_altitude(scene):
    # a custom latitude/longitude with the aerosol left at "location": the location rule chooses
    # (-85, 0: the Antarctic type over snow); the site altitude and the aerosol model reach the core
    from blender_addon import physics

    s = settings(scene)
    s.location_source, s.aerosol = "CUSTOM", "location"
    s.latitude, s.longitude = math.radians(-85.0), 0.0
    s.site_altitude, s.aerosol_model = 2835.0, "opac"
    atm = physics.resolve(s.to_params()).atmosphere
    assert (atm.aerosol, atm.surface, atm.aerosol_model) == ("polar_antarctic", "snow", "opac")
    assert atm.site_altitude_m == pytest.approx(2835.0) and atm.location_rules


@pytest.mark.parametrize("change, parameter", [
    ({"location": "atlantis"}, "location"),
    ({"aerosol": "smog"}, "aerosol"),
    ({"sun_source": "TIME", "year": 2026, "month": 2, "day": 30}, "day"),
    # a night time (sun -64 deg) is built in Environment mode only (the volumes show no stars or glow)
    ({"sun_source": "TIME", "year": 2026, "month": 12, "day": 21, "hour": 0, "minute": 0, "mode": "VOLUMETRIC"},
     "mode"),
])
def test_bad_values_are_refused_naming_the_parameter(scene, change, parameter):
    build_ok()  # a previous sky: a refused build must leave it as it is
    s = settings(scene)
    for k, v in change.items():
        setattr(s, k, v)
    before = snapshot()
    with pytest.raises(RuntimeError) as info:
        bpy.ops.skymodel.build_sky()
    assert f"{parameter}=" in str(info.value)
    assert snapshot() == before


# ------------------------------------------------------------------ building


def test_build_environment_on_fresh_scene(scene):
    from blender_addon.builder import TAG

    s = settings(scene)
    s.sun_elevation = math.radians(30.0)
    s.sun_azimuth = math.radians(200.0)
    build_ok()
    tree = scene.world.node_tree
    env = tree.nodes["Skymodel Environment"]
    bg = tree.nodes["Skymodel Background"]
    assert TAG in env.keys() and TAG in bg.keys()
    assert env.projection == "EQUIRECTANGULAR"
    img = env.image
    assert img is not None and img.name == "Skymodel Sky" and TAG in img.keys()
    assert tuple(img.size) == (64, 32) and img.is_float
    assert img.colorspace_settings.name == "Linear Rec.709"
    assert bg.inputs["Strength"].default_value == 1.0
    out = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputWorld" and n.is_active_output)
    assert out.inputs["Surface"].links[0].from_node == bg
    # the image holds the sky without the sun (the lamp is the sun): max well below a sun pixel
    px = np.empty(64 * 32 * 4, np.float32)
    img.pixels.foreach_get(px)
    assert np.isfinite(px).all() and px.max() < 1e3
    coll = bpy.data.collections["Skymodel"]
    assert coll.name in scene.collection.children and TAG in coll.keys()
    suns = [o for o in coll.objects if o.type == "LIGHT"]
    assert len(suns) == 1
    sun = suns[0]
    assert sun.name == "Skymodel Sun" and sun.data.type == "SUN"
    assert 10.0 < sun.data.energy < 200.0  # W/m^2 of ybar-weighted irradiance (<= ~190 above the air)
    assert math.degrees(sun.data.angle) == pytest.approx(0.53, abs=0.02)
    z = np.array(sun.matrix_world.to_3x3().col[2][:])
    el, az = math.radians(30.0), math.radians(200.0)
    expect = np.array([math.cos(el) * math.sin(az), math.cos(el) * math.cos(az), math.sin(el)])
    assert np.allclose(z, expect, atol=1e-5)
    assert scene.view_settings.view_transform == "AgX"
    assert -20 < scene.view_settings.exposure < 0
    assert s.last_build and "Environment" in s.last_info


def test_rebuild_replaces_and_keeps_user_data(scene):
    user_obj = bpy.data.objects.new("My Empty", None)
    scene.collection.objects.link(user_obj)
    build_ok()
    s = settings(scene)
    s.sun_elevation = math.radians(10.0)
    build_ok()
    s.image_width = 32  # a different image
    build_ok()
    assert [o.name for o in ours(bpy.data.objects)] == ["Skymodel Sun"]
    assert [l.name for l in ours(bpy.data.lights)] == ["Skymodel Sun"]
    assert [i.name for i in ours(bpy.data.images)] == ["Skymodel Sky"]
    assert [c.name for c in ours(bpy.data.collections)] == ["Skymodel"]
    tree = scene.world.node_tree
    names = sorted(n.name for n in tree.nodes)
    assert names == ["Background", "Skymodel Background", "Skymodel Environment", "World Output"]
    assert bpy.data.objects["My Empty"].name in scene.objects
    assert tree.nodes["Skymodel Environment"].image.size[0] == 32
    # Remove Sky: the add-on's things go, the world's own Background is connected again
    assert bpy.ops.skymodel.remove_sky() == {"FINISHED"}
    assert not ours(bpy.data.objects) and not ours(bpy.data.images) and not ours(bpy.data.collections)
    assert sorted(n.name for n in tree.nodes) == ["Background", "World Output"]
    assert tree.nodes["World Output"].inputs["Surface"].links[0].from_node.name == "Background"
    assert "My Empty" in bpy.data.objects


def test_cached_image_is_reused(scene):
    from blender_addon import physics

    calls = []
    orig = physics.render_environment

    def spy(*a, **k):
        rgb, res = orig(*a, **k)
        calls.append(res.cache_hit)
        return rgb, res

    physics.render_environment = spy
    try:
        settings(scene).sun_elevation = math.radians(41.0)
        build_ok()
        build_ok()
    finally:
        physics.render_environment = orig
    assert calls == [False, True]


@pytest.mark.parametrize("previous", [False, True])
def test_failed_build_leaves_the_scene_exactly_as_it_was(scene, previous):
    from blender_addon import builder

    if previous:
        build_ok()
    settings(scene).sun_elevation = math.radians(12.0)
    before = snapshot()
    builder.FAIL_AT = "after_swap"  # everything created and switched over, then an exception
    with pytest.raises(RuntimeError, match="scene unchanged"):
        bpy.ops.skymodel.build_sky()
    assert snapshot() == before
    builder.FAIL_AT = None
    build_ok()  # and the next build works
    assert len(ours(bpy.data.objects)) == 1


def test_unregister_removes_ui_but_keeps_user_data(scene, addon):
    s = settings(scene)
    s.location = "desert"
    build_ok()
    addon.unregister()
    try:
        assert not hasattr(bpy.types.World, "skymodel")
        assert "Skymodel Sun" in bpy.data.objects and "Skymodel Sky" in bpy.data.images
        assert "Skymodel Environment" in scene.world.node_tree.nodes
    finally:
        addon.register()
    assert settings(scene).location == "desert"  # the stored settings come back


# ------------------------------------------------------------------ rendering


def test_camera_convention():
    """The test camera maps +X (east) and +Y (north) where pixel_direction says."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    sc.world = bpy.data.worlds.new("Black")
    sc.world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
    for name, pos, colour in (("east", (100.0, 0.0, 30.0), (1, 0, 0, 1)), ("north", (0.0, 100.0, 1.7), (0, 1, 0, 1))):
        mesh = bpy.data.meshes.new(name)
        import bmesh

        bm = bmesh.new()
        bmesh.ops.create_uvsphere(bm, u_segments=16, v_segments=8, radius=8.0)
        bm.to_mesh(mesh)
        bm.free()
        mat = bpy.data.materials.new(name)
        nt = mat.node_tree
        nt.nodes.clear()
        em = nt.nodes.new("ShaderNodeEmission")
        em.inputs["Color"].default_value = colour
        em.inputs["Strength"].default_value = 10.0
        nt.links.new(em.outputs[0], nt.nodes.new("ShaderNodeOutputMaterial").inputs["Surface"])
        mesh.materials.append(mat)
        obj = bpy.data.objects.new(name, mesh)
        obj.location = pos
        sc.collection.objects.link(obj)
    add_pano_camera(sc, center_azimuth_deg=135.0)
    img = render(sc, samples=4)
    h, w = img.shape[:2]
    for channel, pos in ((0, (100.0, 0.0, 30.0 - 1.7)), (1, (0.0, 100.0, 0.0))):
        ii, jj = np.nonzero(img[..., channel] > 0.5)
        d = pixel_direction(ii.mean(), jj.mean(), h, w, 135.0)
        want = np.array(pos) / np.linalg.norm(pos)
        assert math.degrees(math.acos(np.clip(d @ want, -1, 1))) < 6.0


def test_render_noon_blue_zenith_bright_horizon(scene):
    s = settings(scene)
    s.sun_elevation = math.radians(60.0)
    s.sun_azimuth = math.radians(180.0)
    build_ok()
    add_pano_camera(scene, 180.0)
    img = render(scene, samples=8)
    assert np.isfinite(img).all()
    h = img.shape[0]
    zenith = img[:2].mean(axis=(0, 1))
    horizon = img[h // 2 - 2:h // 2].mean(axis=(0, 1))  # 0..11 degrees above the horizon
    assert zenith[2] > zenith[0]  # blue > red
    assert horizon @ LUMA > zenith @ LUMA


def test_render_sunset_horizon_toward_sun_redder_than_zenith(scene):
    s = settings(scene)
    s.sun_elevation = 0.0
    s.sun_azimuth = math.radians(270.0)
    build_ok()
    add_pano_camera(scene, 180.0)
    img = render(scene, samples=8)
    h, w = img.shape[:2]
    j = column_of_azimuth(270.0, w, 180.0)
    toward = img[h // 2 - 2:h // 2, j - 1:j + 2].mean(axis=(0, 1))
    away = img[h // 2 - 2:h // 2, column_of_azimuth(90.0, w, 180.0)].mean(axis=0)
    zenith = img[:2].mean(axis=(0, 1))
    assert toward[0] / toward[2] > zenith[0] / zenith[2]
    assert toward @ LUMA > away @ LUMA  # the bright side of the sky is where the lamp is


def test_environment_matches_lamp_direction(scene):
    """The aureole in the environment image lies where the sun lamp points."""
    s = settings(scene)
    s.location = "urban"  # hazy: a clear aureole
    s.sun_elevation = math.radians(20.0)
    s.sun_azimuth = math.radians(135.0)
    build_ok()
    add_pano_camera(scene, 180.0)
    img = render(scene, samples=16)
    h, w = img.shape[:2]
    y = img[: h // 2] @ LUMA
    i, j = np.unravel_index(np.argmax(y), y.shape)
    d = pixel_direction(i, j, h, w, 180.0)
    sun = next(o for o in bpy.data.objects if o.type == "LIGHT")
    to_sun = np.array(sun.matrix_world.to_3x3().col[2][:])
    assert math.degrees(math.acos(np.clip(d @ to_sun, -1, 1))) < 12.0  # pixels are 5.6 degrees


def test_volumetric_build_and_render(scene):
    from blender_addon import builder

    s = settings(scene)
    s.mode = "VOLUMETRIC"
    s.n_layers = 4
    s.volume_bounces = 1
    s.sun_elevation = math.radians(45.0)
    add_pano_camera(scene, 180.0)
    scene.camera.data.clip_end = 100.0  # the build must extend it
    before = snapshot()
    builder.FAIL_AT = "after_swap"
    with pytest.raises(RuntimeError, match="scene unchanged"):
        bpy.ops.skymodel.build_sky()
    assert snapshot() == before
    builder.FAIL_AT = None
    build_ok()
    objs = ours(bpy.data.objects)
    layers = sorted((o for o in objs if o.name.startswith("Skymodel Atmosphere")), key=lambda o: o["skymodel_top_m"])
    ground = bpy.data.objects["Skymodel Ground"]
    assert len(layers) == 4
    assert scene.render.engine == "CYCLES" and scene.cycles.volume_bounces == 1
    assert scene.camera.data.clip_end >= 2.0e7
    assert scene.world.node_tree.nodes["Skymodel Background"].inputs["Strength"].default_value == 0.0
    R = 6_360_000.0
    assert layers[-1]["skymodel_top_m"] == pytest.approx(100_000.0, abs=25.0)
    assert "skymodel_bottom_m" not in layers[0]  # the lowest layer: a ball around the camera
    for below, above in zip(layers, layers[1:]):  # the rest: shells, none overlapping another
        assert below["skymodel_top_m"] < above["skymodel_bottom_m"] < above["skymodel_top_m"]
    for o in layers + [ground]:
        me = o.data
        co = np.empty(len(me.vertices) * 3)
        me.vertices.foreach_get("co", co)
        r = np.linalg.norm(co.reshape(-1, 3) + [0, 0, R], axis=1)
        want = [R + (o["skymodel_top_m"] if o is not ground else -0.01)]
        if "skymodel_bottom_m" in o:
            want.append(R + o["skymodel_bottom_m"])
        on = np.zeros(r.shape, bool)
        for w in want:
            on |= np.isclose(r, w, rtol=2e-7, atol=1.0)
        assert on.all()
        n = np.empty(len(me.polygons) * 3)
        me.polygons.foreach_get("normal", n)
        c = np.empty(len(me.polygons) * 3)
        me.polygons.foreach_get("center", c)
        c = c.reshape(-1, 3) + [0, 0, R]
        outward = np.sum(n.reshape(-1, 3) * c, axis=1) > 0
        # outer surfaces face out, a shell's inner surface faces in (towards the planet centre):
        # which surface a polygon is on, from the radius of its first vertex
        starts = np.empty(len(me.polygons), np.int32)
        me.polygons.foreach_get("loop_start", starts)
        vidx = np.empty(len(me.loops), np.int32)
        me.loops.foreach_get("vertex_index", vidx)
        on_top = np.isclose(r[vidx[starts]], want[0], rtol=2e-7, atol=1.0)
        assert np.all(outward == on_top)
    # the camera sits on the ground: the pole of the ground sphere is right under it
    assert ground.data.vertices[0].co.z == pytest.approx(-0.01, abs=1e-3)
    img = render(scene, width=32, height=16, samples=8)
    assert np.isfinite(img).all()
    sky = img[:4].mean(axis=(0, 1))
    assert sky @ LUMA > 0 and sky[2] > sky[0]  # blue-ish
    # back to environment mode: the volumes go away
    s.mode = "ENVIRONMENT"
    build_ok()
    assert [o.name for o in ours(bpy.data.objects)] == ["Skymodel Sun"]
    assert not ours(bpy.data.meshes) and not ours(bpy.data.materials)


def test_headless_render_module(tmp_path, addon):
    from blender_addon import render as headless

    out = tmp_path / "desert.png"
    rc = headless.main(["--location", "desert", "--month", "1", "--sun-elevation", "5", "--mode", "environment",
                        "--samples", "4", "--size", "32x16", "--image-width", "64", "--out", str(out)])
    assert rc == 0 and out.stat().st_size > 0
    assert headless.main(["--location", "atlantis", "--size", "32x16", "--out", str(tmp_path / "x.png")]) == 2
    assert headless.main(["--sun-elevation", "-30", "--size", "32x16", "--out", str(tmp_path / "y.png")]) == 2


@pytest.mark.parametrize("mode", ["AUTO", "ENVIRONMENT", "VOLUMETRIC"])
def test_panel_draws_every_mode(scene, mode, recording_layout):
    from blender_addon import ui

    s = settings(scene)
    s.mode = mode
    log = []
    ui.draw_settings(recording_layout(log), bpy.context)
    props = {n for kind, n in log if kind == "prop"}
    assert {"mode", "quality", "location"} <= props
    assert ("n_layers" in props) == (mode == "VOLUMETRIC")
