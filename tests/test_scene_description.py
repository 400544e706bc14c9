"""Auto mode of the add-on: the scene description extracted from a Blender scene, the
plan it gives, the overrides, and Build Sky carrying the plan out (bpy, headless)."""

import json
import math

import pytest

bpy = pytest.importorskip("bpy")

pytestmark = pytest.mark.blender


@pytest.fixture
def scene(new_sky_scene):
    """An empty file with a world (sun at 60 degrees, tiny images), the add-on in Auto mode,
    and a camera 1.7 m above the ground looking north, level."""
    sc = new_sky_scene(image_width=64)
    s = sc.world.skymodel
    s.mode = "AUTO"
    s.sun_elevation = math.radians(60.0)
    s.plan_tolerance = 1.0
    cam_data = bpy.data.cameras.new("Cam")
    cam_data.lens = 50.0
    cam = bpy.data.objects.new("Cam", cam_data)
    cam.location = (0.0, 0.0, 1.7)
    cam.rotation_euler = (math.radians(90.0), 0.0, 0.0)  # -Z axis -> +Y (north)
    sc.collection.objects.link(cam)
    sc.camera = cam
    sc.render.resolution_x, sc.render.resolution_y, sc.render.resolution_percentage = 640, 360, 50
    bpy.context.view_layer.update()
    yield sc


def add_cube(sc, name, location, size=2.0):
    mesh = bpy.data.meshes.new(name)
    h = size / 2.0
    verts = [(x, y, z) for x in (-h, h) for y in (-h, h) for z in (-h, h)]
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    mesh.from_pydata(verts, [], faces)
    obj = bpy.data.objects.new(name, mesh)
    obj.location = location
    sc.collection.objects.link(obj)
    bpy.context.view_layer.update()
    return obj


def test_description_from_camera_objects_and_render_settings(scene):
    from blender_addon import scene_description

    add_cube(scene, "Near", (0.0, 100.0, 1.0))
    s = scene.world.skymodel
    d = scene_description.describe(scene, s)
    (cam,) = d.cameras
    assert cam.altitude_m == pytest.approx(1.7)
    # level camera: the view range is centred on the horizon, half the lens angle each side
    half = math.degrees(scene.camera.data.angle) / 2
    assert cam.min_elevation_deg == pytest.approx(-half, abs=1e-4)
    assert cam.max_elevation_deg == pytest.approx(half, abs=1e-4)
    # farthest corner of the 2 m cube centred 100 m north at z = 1: a bottom corner on the far side
    far = math.dist((0.0, 0.0, 1.7), (1.0, 101.0, 0.0))
    assert d.farthest_object_m == pytest.approx(far, rel=1e-6)
    assert (d.image_width, d.image_height) == (320, 180)
    assert d.sky_visible and d.sun_elevation_deg == pytest.approx(60.0)
    assert d.quality == s.quality  # the build's time is predicted at the quality it is built at (#23)
    s.quality = "final"
    assert scene_description.describe(scene, s).quality == "final"
    scene.render.film_transparent = True
    scene.unit_settings.scale_length = 2.0
    d2 = scene_description.describe(scene, s)
    assert not d2.sky_visible
    assert d2.farthest_object_m == pytest.approx(2 * far, rel=1e-6)
    assert d2.cameras[0].altitude_m == pytest.approx(3.4)


def test_near_cube_gives_environment_only_and_build_follows_the_plan(scene):
    from blender_addon import ops, scene_description

    add_cube(scene, "Near", (0.0, 100.0, 1.0))
    s = scene.world.skymodel
    plan = scene_description.make_plan(scene, s)
    assert plan.mode == "environment" and not plan["aerial_perspective"].on
    result = ops.build(bpy.context)
    assert result.mode == "ENVIRONMENT"
    assert not any(o.type == "MESH" and o.name != "Near" for o in scene.objects)  # no volume shells
    # the environment was rendered on the plan's wavelength grid
    n_wl = int(round(400.0 / plan.wavelength_step_nm)) + 1
    meta = result.image_path.replace(".exr", ".json")
    with open(meta, encoding="utf-8") as f:
        assert json.load(f)["info"]["wavelengths"] == n_wl


def test_far_object_gives_volume_shells(scene):
    from blender_addon import scene_description

    add_cube(scene, "Near", (0.0, 100.0, 1.0))
    add_cube(scene, "Mountain", (0.0, 30_000.0, 500.0), size=1000.0)
    s = scene.world.skymodel
    s.plan_time_budget = 1e6  # cost no object (the shells' Cycles time is counted: issue 21)
    plan = scene_description.make_plan(scene, s)
    assert plan.scene.farthest_object_m > 30_000.0
    assert plan.mode == "volumetric" and plan.n_layers >= 1
    params = scene_description.params_from_plan(s.to_params(), plan)
    assert params.mode == "VOLUMETRIC" and params.n_layers == plan.n_layers


def test_overrides_are_honoured(scene):
    from blender_addon import scene_description

    add_cube(scene, "Mountain", (0.0, 30_000.0, 500.0), size=1000.0)
    s = scene.world.skymodel
    s.override_aerial_perspective = "OFF"
    s.override_ozone = "ON"
    s.override_aerosols = "OFF"
    plan = scene_description.make_plan(scene, s)
    assert plan.mode == "environment"
    assert plan["ozone"].on and not plan["aerosols"].on
    assert plan["aerial_perspective"].reason.startswith("set by the user")
    params = scene_description.params_from_plan(s.to_params(), plan)
    assert params.mode == "ENVIRONMENT" and params.aerosol == "none" and params.stratospheric == "none"
    assert params.ozone_du is None  # ozone kept: the location's climatology
    s.override_aerial_perspective = "AUTO"
    s.override_n_layers = 5
    s.plan_time_budget = 1e6
    plan = scene_description.make_plan(scene, s)
    assert plan.mode == "volumetric" and plan.n_layers == 5
    lines = scene_description.plan_lines(plan)
    assert lines[0].startswith("Volumetric") and len(lines) == 1 + len(plan.warnings()) + len(list(plan))


def test_no_camera_plans_for_a_viewer_that_may_look_anywhere(scene):
    from blender_addon import scene_description

    bpy.data.objects.remove(scene.camera)
    d = scene_description.describe(scene, scene.world.skymodel)
    assert len(d.cameras) == 1 and d.elevation_range_deg == (-90.0, 90.0)


def test_panel_lists_the_plan_with_reasons_and_overrides(scene, recording_layout):
    from blender_addon import scene_description, ui

    add_cube(scene, "Near", (0.0, 100.0, 1.0))
    log = []
    ui.draw_plan(recording_layout(log), bpy.context, scene.world.skymodel)
    labels = [t for k, t in log if k == "label"]
    props = {t for k, t in log if k == "prop"}
    plan = scene_description.make_plan(scene, scene.world.skymodel)
    for d in plan:
        assert d.reason in labels
    assert set(scene_description.OVERRIDE_PROPS.values()) <= props and "override_n_layers" in props
    assert labels[0].startswith("Environment")
    # bad input: the panel says why instead of failing
    scene.world.skymodel.location = "atlantis"
    log.clear()
    ui.draw_plan(recording_layout(log), bpy.context, scene.world.skymodel)
    assert any("No plan" in t and "location" in t for k, t in log if k == "label")


def test_auto_environment_width_is_the_plans_within_the_time_budget(scene):
    """The width the planner chose (within the panel's time budget) is what gets built (issue 21)."""
    from blender_addon import scene_description

    s = scene.world.skymodel
    s.image_width = 0
    scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 3840, 2160, 100
    s.plan_time_budget = 1e5
    plan = scene_description.make_plan(scene, s)
    assert plan.environment_width == 8192  # a 4K picture asks for the largest environment
    budget = 0.95 * plan.predicted_build_s  # just under what the largest takes
    s.plan_time_budget = budget
    plan = scene_description.make_plan(scene, s)
    assert plan.environment_width < 8192 and plan["angular_resolution"].predicted_time_s <= budget
    assert "time budget" in plan["angular_resolution"].reason
    for quality in ("preview", "final"):
        s.quality = quality
        params = scene_description.params_from_plan(s.to_params(), plan)
        assert params.image_width == plan.environment_width
    s.image_width = 128  # the user's width wins
    assert scene_description.params_from_plan(s.to_params(), plan).image_width == 128
