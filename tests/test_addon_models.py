"""The add-on's Sky Model selector (bpy, headless): the environment image from another model."""

import math
import os
import tempfile

import pytest

bpy = pytest.importorskip("bpy")
import numpy as np  # noqa: E402
from test_addon import add_pano_camera  # noqa: E402

pytestmark = pytest.mark.blender


@pytest.fixture
def scene(new_sky_scene):
    """A fresh world in Environment mode, sun at 35 degrees (tests/conftest.py)."""
    sc = new_sky_scene(image_width=32)
    s = sc.world.skymodel
    s.mode = "ENVIRONMENT"
    s.sun_elevation = math.radians(35.0)
    return sc


def _pixels(img):
    px = np.empty(img.size[0] * img.size[1] * 4, np.float32)
    img.pixels.foreach_get(px)
    return px.reshape(img.size[1], img.size[0], 4)[::-1, :, :3]  # row 0 = top (zenith)


def test_preetham_builds_a_world_image_and_reports_the_model(scene):
    from blender_addon import physics

    s = scene.world.skymodel
    assert s.sky_model == "ours"  # the default
    s.sky_model = "preetham"
    assert bpy.ops.skymodel.build_sky() == {"FINISHED"}
    img = scene.world.node_tree.nodes["Skymodel Environment"].image
    assert img is not None and tuple(img.size) == (32, 16)
    px = _pixels(img)
    assert np.isfinite(px).all()
    sky, ground = px[:8], px[8:]
    assert sky.min() > 0 and np.all(ground == 0)  # Preetham describes the sky above the horizon only
    # the zenith row is Preetham's zenith luminance (1.0 = 683 cd/m^2) and bluish
    T = 2.0  # the rural AOD is below Preetham's range: clamped to T = 2
    from skymodel.models import preetham

    yz = 1000.0 * float(preetham.zenith_luminance_kcd(T, math.radians(55.0)))
    zen = px[0].mean(axis=0)
    assert float(zen @ physics.LUMA_709) * 683.0 == pytest.approx(yz, rel=0.03)
    assert zen[2] > zen[0]
    assert "Model preetham" in s.last_info
    sun = next(o for o in scene.objects if o.type == "LIGHT")
    assert 10.0 < sun.data.energy < 200.0


def test_other_models_refused_where_they_do_not_apply(scene):
    s = scene.world.skymodel
    s.sky_model = "preetham"
    s.sun_elevation = math.radians(-3.0)  # Preetham needs the sun above the horizon
    with pytest.raises(RuntimeError, match="sun_elevation"):
        bpy.ops.skymodel.build_sky()
    s.sun_elevation = math.radians(30.0)
    s.mode = "VOLUMETRIC"
    with pytest.raises(RuntimeError, match="sky_model"):
        bpy.ops.skymodel.build_sky()


def test_blender_sky_texture_node_points_its_sun_at_the_lamp(scene):
    s = scene.world.skymodel
    s.sky_model = "blender"
    s.sun_elevation = math.radians(20.0)
    s.sun_azimuth = math.radians(120.0)
    assert bpy.ops.skymodel.build_sky() == {"FINISHED"}
    tree = scene.world.node_tree
    assert "Skymodel Environment" not in tree.nodes
    sky = tree.nodes["Skymodel Sky Texture"]
    assert sky.sky_type == "MULTIPLE_SCATTERING" and not sky.sun_disc
    assert math.degrees(sky.sun_rotation) == pytest.approx(120.0) and math.degrees(sky.sun_elevation) == pytest.approx(20.0)
    from skymodel import Atmosphere
    from skymodel.models import SkyScene, blender_sky

    expect = blender_sky.scene_parameters(SkyScene(Atmosphere(location="rural", month=6), 20.0, 120.0, [550.0]))
    assert sky.aerosol_density == pytest.approx(expect["aerosol_density"], rel=1e-5)
    assert sky.ozone_density == pytest.approx(expect["ozone_density"], rel=1e-5)
    assert "Model blender" in s.last_info
    # render the world with a panoramic camera looking along the lamp's horizontal direction:
    # the brightest column of the row at the sun's height is the middle one
    sun = next(o for o in scene.objects if o.type == "LIGHT")
    to_sun = np.array(sun.matrix_world.to_3x3().col[2][:])
    scene.render.engine = "CYCLES"
    scene.cycles.samples = 1
    scene.cycles.use_denoising = False
    scene.render.resolution_x, scene.render.resolution_y = 32, 16
    sun.hide_render = True
    add_pano_camera(scene, math.degrees(math.atan2(to_sun[0], to_sun[1])))  # centred on the sun's azimuth
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.filepath = os.path.join(tempfile.mkdtemp(prefix="skymodel-test-"), "pano.exr")
    bpy.ops.render.render(write_still=True)
    px = _pixels(bpy.data.images.load(scene.render.filepath))
    row = px[6].sum(axis=1)  # 20-30 degrees above the horizon
    assert abs(int(np.argmax(row)) - 15.5) <= 2
