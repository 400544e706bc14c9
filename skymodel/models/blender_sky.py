"""Blender's own Sky Texture (Blender 5.0) as a peer model, rendered headlessly with ``bpy``.

``bpy`` is optional and is never imported by the core: :func:`render_equirectangular`
runs Blender in a separate Python process (``python -m skymodel.models.blender_sky``),
which imports ``bpy`` there, builds a world with a Sky Texture node, renders it with a
Cycles equirectangular panoramic camera at 1 sample per pixel (box filter of 0.01 px, so
each pixel is the sky at its centre; no denoising, "Standard" view transform) to a 32-bit
float EXR, and hands the linear Rec.709 pixels back. A separate process keeps Blender's
global state (and a crash) out of the caller.

Image layout: rows equal steps in zenith angle from the zenith (top) to the nadir, columns
equal steps in azimuth with the sun in the middle of the image (Sky Texture
``sun_rotation = 90 degrees`` with the camera looking along +X puts it there; measured,
see ``tests/test_models.py``). The sky is symmetric about the sun's vertical, so a
direction is looked up by its zenith angle and its azimuth from the sun's.

Parameters from our atmosphere (``SkyScene``):

* ``SINGLE_SCATTERING`` / ``MULTIPLE_SCATTERING``: ``air_density`` 1, ``altitude`` 0 (Blender
  clamps to 1 m), ``aerosol_density`` = our AOD550 / 0.02664 (Blender's aerosol at density
  1: scattering 2e-5 m^-1 with a 1.2 km scale height, extinction 1.11 x scattering, grey),
  ``ozone_density`` = our ozone column / Blender's (its 600 nm ozone coefficient 2.7355e-6
  m^-1 over the 15 km-area triangular profile, 0.0410 optical depth, expressed in DU with
  our 600 nm cross section), ``sun_disc`` off.
* ``PREETHAM`` / ``HOSEK_WILKIE``: ``turbidity`` = Preetham's T of
  :func:`skymodel.models.preetham.scene_turbidity`, ``ground_albedo`` = ours (Hosek).

Units: Blender's physical sky integrates spectral radiance (W m^-2 sr^-1 nm^-1) against
the CIE colour matching functions, the same scale as
:func:`skymodel.colorimetry.spectral_to_xyz`; the Rec.709 pixels are turned back into XYZ
with the inverse of our Rec.709 matrix. The Preetham/Hosek outputs of Blender are on
Blender's own arbitrary scale: they are used as relative luminance only.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile

import numpy as np

from skymodel.errors import SkymodelInputError, check_choice, check_range
from skymodel.models import ModelRadiance, SkyModel, SkyScene, register

SKY_TYPES = ("SINGLE_SCATTERING", "MULTIPLE_SCATTERING", "PREETHAM", "HOSEK_WILKIE")
#: Blender's aerosol optical depth at aerosol_density 1: 2e-5 m^-1 x 1200 m x 1.11.
BLENDER_AOD_AT_DENSITY_1 = 2e-5 * 1200.0 * 1.11
#: Blender's ozone optical depth at 600 nm at ozone_density 1: 2.7355e-6 m^-1 x 15000 m.
BLENDER_OZONE_TAU600_AT_DENSITY_1 = 2.73551299461512e-6 * 15000.0
#: Seconds a Blender render may take before it is abandoned.
TIMEOUT_S = 300


def bpy_available() -> bool:
    import importlib.util

    return importlib.util.find_spec("bpy") is not None


def blender_ozone_du() -> float:
    """Ozone column (DU) of Blender's ozone_density = 1, by our 600 nm cross section."""
    from skymodel.optics.ozone import DOBSON_UNIT_M2, ozone_cross_section

    return BLENDER_OZONE_TAU600_AT_DENSITY_1 / (float(ozone_cross_section([600.0])[0]) * DOBSON_UNIT_M2)


def render_equirectangular(sky_type="MULTIPLE_SCATTERING", sun_elevation_deg=30.0, width=64, height=None,
                           air_density=1.0, aerosol_density=1.0, ozone_density=1.0, altitude_m=0.0,
                           turbidity=2.2, ground_albedo=0.3, timeout_s=TIMEOUT_S) -> np.ndarray:
    """Blender's Sky Texture as a float linear Rec.709 image (height, width, 3), the zenith
    at the top and the sun in the middle column (see the module doc). Needs ``bpy``."""
    st = check_choice("sky_type", sky_type, SKY_TYPES)
    elev = check_range("sun_elevation", sun_elevation_deg, -90.0, 90.0, "degrees")
    w = int(width)
    h = w // 2 if height is None else int(height)
    if w < 4 or h < 2 or w > 8192 or h > 4096:
        raise SkymodelInputError("width", width, "4..8192 pixels (height 2..4096)")
    if not bpy_available():
        raise SkymodelInputError("model", f"blender sky {st}", "a Python with the bpy module (pip install bpy)")
    args = {"sky_type": st, "sun_elevation_deg": elev, "width": w, "height": h,
            "air_density": check_range("air_density", air_density, 0.0, 10.0),
            "aerosol_density": check_range("aerosol_density", aerosol_density, 0.0, 10.0),
            "ozone_density": check_range("ozone_density", ozone_density, 0.0, 10.0),
            "altitude_m": check_range("altitude_m", altitude_m, 0.0, 60000.0, "metres"),
            "turbidity": check_range("turbidity", turbidity, 1.0, 10.0),
            "ground_albedo": check_range("ground_albedo", ground_albedo, 0.0, 1.0)}
    with tempfile.TemporaryDirectory(prefix="skymodel_blender_") as tmp:
        out = os.path.join(tmp, "sky.npy")
        env = dict(os.environ)
        root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
        env["PYTHONPATH"] = root + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
        proc = subprocess.run([sys.executable, "-m", "skymodel.models.blender_sky", json.dumps(args), out],
                              capture_output=True, text=True, timeout=timeout_s, env=env, cwd=tmp)
        if proc.returncode != 0 or not os.path.exists(out):
            tail = (proc.stderr or proc.stdout or "")[-800:]
            raise RuntimeError(f"Blender sky render failed (exit {proc.returncode}): {tail}")
        return np.load(out)


def _render_here(args: dict, out_path: str) -> None:
    """Runs inside the child process: the only place that imports bpy."""
    import math

    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = 1
    scene.cycles.use_denoising = False
    scene.cycles.pixel_filter_type = "BOX"
    scene.cycles.filter_width = 0.01
    scene.cycles.seed = 0
    scene.render.threads_mode = "FIXED"
    scene.render.threads = max(1, min(2, os.cpu_count() or 1))
    scene.render.resolution_x = args["width"]
    scene.render.resolution_y = args["height"]
    scene.render.resolution_percentage = 100
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    world = bpy.data.worlds.new("skymodel_sky")
    scene.world = world
    nt = world.node_tree
    nt.nodes.clear()
    sky = nt.nodes.new("ShaderNodeTexSky")
    bg = nt.nodes.new("ShaderNodeBackground")
    out = nt.nodes.new("ShaderNodeOutputWorld")
    nt.links.new(sky.outputs["Color"], bg.inputs["Color"])
    nt.links.new(bg.outputs["Background"], out.inputs["Surface"])
    sky.sky_type = args["sky_type"]
    if args["sky_type"] in ("SINGLE_SCATTERING", "MULTIPLE_SCATTERING"):
        sky.sun_disc = False
        sky.sun_elevation = math.radians(args["sun_elevation_deg"])
        sky.sun_rotation = math.radians(90.0)
        sky.altitude = args["altitude_m"]
        sky.air_density = args["air_density"]
        sky.aerosol_density = args["aerosol_density"]
        sky.ozone_density = args["ozone_density"]
    else:
        # the older analytic skies take a world-space sun direction vector: toward +X, where
        # the camera looks (as sun_rotation = 90 degrees above; checked in tests/test_models.py)
        e = math.radians(args["sun_elevation_deg"])
        sky.sun_direction = (math.cos(e), 0.0, math.sin(e))
        sky.turbidity = args["turbidity"]
        sky.ground_albedo = args["ground_albedo"]
    cam_data = bpy.data.cameras.new("skymodel_cam")
    cam_data.type = "PANO"
    cam_data.panorama_type = "EQUIRECTANGULAR"
    cam = bpy.data.objects.new("skymodel_cam", cam_data)
    scene.collection.objects.link(cam)
    scene.camera = cam
    cam.rotation_euler = (math.pi / 2.0, 0.0, -math.pi / 2.0)  # look along +X, up +Z
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    exr = os.path.join(os.path.dirname(os.path.abspath(out_path)), "sky.exr")
    scene.render.filepath = exr
    bpy.ops.render.render(write_still=True)
    img = bpy.data.images.load(exr)
    px = np.array(img.pixels[:], dtype=np.float32).reshape(img.size[1], img.size[0], 4)[::-1, :, :3]
    np.save(out_path, np.ascontiguousarray(px, dtype=np.float64))


# ------------------------------------------------------------------ sampling and the models
def sample_equirectangular(image, zenith_rad, relative_azimuth_rad):
    """Bilinear look-up in an image of :func:`render_equirectangular` at zenith angles and
    azimuths from the sun (radians, wrapped)."""
    img = np.asarray(image, dtype=float)
    h, w = img.shape[:2]
    y = np.asarray(zenith_rad, float) / np.pi * h - 0.5
    x = (0.5 + np.asarray(relative_azimuth_rad, float) / (2.0 * np.pi)) * w - 0.5
    y = np.clip(y, 0.0, h - 1.0)
    i0 = np.clip(np.floor(y).astype(int), 0, h - 2) if h > 1 else np.zeros(y.shape, int)
    fy = (y - i0)[..., None]
    x0f = np.floor(x)
    fx = (x - x0f)[..., None]
    j0 = x0f.astype(int) % w
    j1 = (j0 + 1) % w
    i1 = np.minimum(i0 + 1, h - 1)
    return ((img[i0, j0] * (1 - fx) + img[i0, j1] * fx) * (1 - fy)
            + (img[i1, j0] * (1 - fx) + img[i1, j1] * fx) * fy)


def scene_parameters(scene: SkyScene) -> dict:
    """Blender Sky Texture settings that mirror ``scene`` (see the module doc)."""
    from skymodel.models.preetham import scene_turbidity

    meta = scene.atmosphere.optical_profile([550.0]).metadata
    return {"air_density": 1.0,
            "aerosol_density": float(min(10.0, meta["aod550"] / BLENDER_AOD_AT_DENSITY_1)),
            "ozone_density": float(min(10.0, meta["ozone_du"] / blender_ozone_du())),
            "altitude_m": 0.0,
            "turbidity": float(min(10.0, scene_turbidity(scene)[0])),
            "ground_albedo": float(meta["albedo"])}


#: Resolution (width) of the Blender panorama sampled by the models; set by callers
#: (``compare`` uses 2 x its image size, tests a tiny one).
PANORAMA_WIDTH = 512


def _make(sky_type):
    def fn(scene: SkyScene, d) -> ModelRadiance:
        params = scene_parameters(scene)
        img = render_equirectangular(sky_type, scene.sun_elevation_deg, PANORAMA_WIDTH, **params)
        theta = np.arccos(np.clip(d[:, 2], -1.0, 1.0))
        rgb = sample_equirectangular(img, theta, scene.relative_azimuth(d))
        from skymodel.colorimetry import xyz_to_rgb_matrix

        xyz = rgb @ np.linalg.inv(xyz_to_rgb_matrix("rec709")).T
        info = dict(params, sky_type=sky_type, panorama=img.shape[:2])
        if sky_type in ("PREETHAM", "HOSEK_WILKIE"):
            y = xyz[:, 1]
            zen = float(sample_equirectangular(img, np.array([0.0]), np.array([0.0]))[0] @
                        np.linalg.inv(xyz_to_rgb_matrix("rec709"))[1])
            return ModelRadiance("relative", y / zen if zen > 0 else y, None, info)
        return ModelRadiance("xyz", xyz, None, info)

    return fn


for _name, _type, _desc in (
        ("blender_multiple", "MULTIPLE_SCATTERING", "Blender 5.0 Sky Texture, multiple scattering"),
        ("blender_single", "SINGLE_SCATTERING", "Blender 5.0 Sky Texture, single scattering (Nishita)"),
        ("blender_preetham", "PREETHAM", "Blender's Preetham sky (relative luminance)"),
        ("blender_hosek", "HOSEK_WILKIE", "Blender's Hosek-Wilkie sky (relative luminance)")):
    register(SkyModel(_name, "relative" if _type in ("PREETHAM", "HOSEK_WILKIE") else "xyz",
                      _desc + " (needs bpy)", _make(_type), requires="bpy"))


if __name__ == "__main__":  # the child process of render_equirectangular
    _render_here(json.loads(sys.argv[1]), sys.argv[2])
