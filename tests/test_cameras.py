"""Cameras: orientation conventions, pixel <-> direction round trips, solid angles that
integrate, and input validation."""

import numpy as np
import pytest

from skymodel.errors import SkymodelInputError
from skymodel.render.cameras import (CAMERAS, MEMORY_FACTOR, estimate_memory_bytes, make_camera)
from skymodel.render.rays import direction_from_angles

NAMES = ["equirectangular", "fisheye", "dome"]


def _zenith_deg(d):
    return np.degrees(np.arccos(np.clip(d[..., 2], -1, 1)))


def _azimuth_deg(d):
    return np.mod(np.degrees(np.arctan2(d[..., 0], d[..., 1])), 360.0)


def _angle_diff(a, b):
    return np.mod(a - b + 180.0, 360.0) - 180.0


# ------------------------------------------------------------------ solid angles


@pytest.mark.parametrize("width", [8, 64, 200])
def test_equirectangular_solid_angles_sum_to_4pi(width):
    om = make_camera("equirectangular", width).pixel_solid_angles()
    assert om.shape == (width // 2, width)
    assert om.sum() == pytest.approx(4 * np.pi, rel=1e-12)


@pytest.mark.parametrize("size", [(64, None), (101, None), (256, None), (120, 80), (33, 90)])
def test_fisheye_solid_angles_sum_to_2pi(size):
    cam = make_camera("fisheye", *size)
    om = cam.pixel_solid_angles()
    _, valid = cam.directions()
    assert om.sum() == pytest.approx(2 * np.pi, rel=1e-4)  # brief asks 1e-3; we get ~1e-6
    assert np.all(om[~valid] == 0) and np.all(om[valid] > 0)


def test_fisheye_wider_than_hemisphere():
    cam = make_camera("fisheye", 128, max_zenith_deg=120)
    expected = 2 * np.pi * (1 - np.cos(np.radians(120)))
    assert cam.pixel_solid_angles().sum() == pytest.approx(expected, rel=1e-4)


@pytest.mark.parametrize("below", [0.0, 5.0, 30.0])
def test_dome_solid_angles(below):
    cam = make_camera("dome", 180, below_horizon_deg=below)
    expected = 2 * np.pi * (1 + np.sin(np.radians(below)))
    assert cam.pixel_solid_angles().sum() == pytest.approx(expected, rel=1e-12)


@pytest.mark.parametrize("name,width", [("equirectangular", 128), ("fisheye", 128), ("dome", 144)])
def test_cosine_weighted_integral_is_pi(name, width):
    """Not only the sum: the weights sit where they should. The integral of
    max(cos(zenith), 0) over the upper hemisphere is pi (irradiance of unit radiance)."""
    cam = make_camera(name, width)
    d, valid = cam.directions()
    om = cam.pixel_solid_angles()
    integral = np.sum(np.where(valid, np.maximum(d[..., 2], 0.0), 0.0) * om)
    assert integral == pytest.approx(np.pi, rel=2e-3)


# ------------------------------------------------------------------ directions


@pytest.mark.parametrize("name", NAMES)
def test_directions_are_unit_vectors(name):
    d, valid = make_camera(name, 64).directions()
    assert d.shape[:2] == valid.shape and d.shape[2] == 3 and valid.dtype == bool
    assert np.allclose(np.linalg.norm(d, axis=-1), 1.0)


def test_fisheye_centre_is_zenith_and_edge_is_horizon():
    cam = make_camera("fisheye", 65)
    d, valid = cam.directions()
    assert np.allclose(d[32, 32], [0, 0, 1])
    # zenith projects to the image centre for even sizes too
    for w in (64, 65):
        xy, vis = make_camera("fisheye", w).project([0.0, 0.0, 1.0])
        assert vis and np.allclose(xy, [(w - 1) / 2, (w - 1) / 2])
    # every horizon direction lands on the inscribed circle (radius w/2 px)
    az = np.linspace(0, 360, 37)
    xy, vis = cam.project(direction_from_angles(90.0, az))
    r = np.hypot(xy[:, 0] - 32, xy[:, 1] - 32)
    assert np.all(vis) and np.allclose(r, 65 / 2)
    # zenith angle is proportional to the distance from the centre (equidistant)
    rows, cols = cam.pixel_centres()
    rpx = np.hypot(rows - 32, cols - 32)
    assert np.allclose(_zenith_deg(d)[valid], 90.0 * rpx[valid] / 32.5)
    # just inside the circle: a few degrees above the horizon; outside: masked
    assert valid[32, 0] and 85 < _zenith_deg(d[32, 0]) < 90
    assert not valid[0, 0] and valid.sum() == pytest.approx(np.pi * 32.5**2, rel=0.02)


def test_fisheye_north_up_east_left():
    cam = make_camera("fisheye", 65)
    d, _ = cam.directions()
    c = 32
    assert _azimuth_deg(d[0, c]) == pytest.approx(0.0, abs=1e-9)      # top: north
    assert _azimuth_deg(d[c, 0]) == pytest.approx(90.0)                # left: east
    assert _azimuth_deg(d[64, c]) == pytest.approx(180.0)              # bottom: south
    assert _azimuth_deg(d[c, 64]) == pytest.approx(270.0)              # right: west
    xy, _ = cam.project(direction_from_angles([45.0, 45.0], [0.0, 90.0]))
    assert xy[0, 1] < c and xy[0, 0] == pytest.approx(c)  # north above the centre
    assert xy[1, 0] < c and xy[1, 1] == pytest.approx(c)  # east left of it


@pytest.mark.parametrize("centre", [180.0, 90.0, 0.0])
def test_equirectangular_orientation(centre):
    W = 72
    cam = make_camera("equirectangular", W, center_azimuth_deg=centre)
    d, valid = cam.directions()
    assert valid.all()
    az = _azimuth_deg(d[18])
    half = 360.0 / W / 2
    # the two middle columns straddle the centre azimuth
    assert _angle_diff(az[W // 2 - 1], centre - half) == pytest.approx(0, abs=1e-9)
    assert _angle_diff(az[W // 2], centre + half) == pytest.approx(0, abs=1e-9)
    xy, vis = cam.project(direction_from_angles(90.0, centre))
    assert vis and xy[0] == pytest.approx((W - 1) / 2) and xy[1] == pytest.approx((W // 2 - 1) / 2)
    # azimuth increases to the right: with south in the middle, east is on the left
    assert np.all(np.mod(np.diff(np.unwrap(np.radians(az))), 2 * np.pi) > 0)
    # top row next to the zenith, bottom row next to the nadir, rows in equal steps
    zen = _zenith_deg(d[:, 0])
    assert np.allclose(zen, (np.arange(W // 2) + 0.5) * 180.0 / (W // 2))


def test_equirectangular_default_south_centre_east_left():
    cam = make_camera("equirectangular", 64)
    xs, _ = cam.project(direction_from_angles(90.0, [90.0, 180.0, 270.0]))
    assert xs[0, 0] < xs[1, 0] < xs[2, 0]
    assert xs[1, 0] == pytest.approx(31.5)


def test_dome_orientation():
    cam = make_camera("dome", 360, below_horizon_deg=10)
    assert cam.shape == (100, 360)
    d, valid = cam.directions()
    assert valid.all()
    elev = 90.0 - _zenith_deg(d[:, 0])
    assert elev[0] == pytest.approx(90 - 0.5) and elev[-1] == pytest.approx(-10 + 0.5)
    xy, vis = cam.project(direction_from_angles([90.0, 100.0, 100.5], 180.0))
    assert xy[0, 0] == pytest.approx(179.5) and xy[0, 1] == pytest.approx(89.5)
    assert list(vis) == [True, True, False]


@pytest.mark.parametrize("name,w,h,opts", [
    ("equirectangular", 64, None, {}),
    ("equirectangular", 50, 25, {"center_azimuth_deg": 37.0}),
    ("fisheye", 64, None, {}),
    ("fisheye", 51, 40, {}),
    ("fisheye", 60, None, {"max_zenith_deg": 100.0}),
    ("dome", 90, None, {}),
    ("dome", 100, 31, {"below_horizon_deg": 7.0, "center_azimuth_deg": -20.0}),
])
def test_project_round_trips_to_pixel_centres(name, w, h, opts):
    cam = make_camera(name, w, h, **opts)
    d, valid = cam.directions()
    xy, vis = cam.project(d)
    rows, cols = cam.pixel_centres()
    assert np.all(vis[valid])
    assert np.allclose(xy[..., 0][valid], cols[valid], atol=1e-7)
    assert np.allclose(xy[..., 1][valid], rows[valid], atol=1e-7)


def test_project_handles_bad_vectors_and_scaling():
    cam = make_camera("fisheye", 32)
    xy, vis = cam.project([[0.0, 0.0, 0.0], [np.nan, 0, 1], [0, 0, 5.0], [0, 0, -1.0]])
    assert list(vis) == [False, False, True, False]
    assert np.all(np.isnan(xy[:2])) and np.allclose(xy[2], [15.5, 15.5])


# ------------------------------------------------------------------ validation


def test_unknown_camera_lists_known_names():
    with pytest.raises(SkymodelInputError) as e:
        make_camera("pinhole", 64)
    assert e.value.parameter == "camera"
    for n in CAMERAS:
        assert n in str(e.value)


def test_camera_name_case_insensitive():
    assert make_camera("FishEye", 16).name == "fisheye"


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("width", [0, -4, 2.5, "wide", True, None])
def test_bad_width(name, width):
    with pytest.raises(SkymodelInputError) as e:
        make_camera(name, width)
    assert e.value.parameter == "width"


@pytest.mark.parametrize("name", NAMES)
def test_bad_height(name):
    with pytest.raises(SkymodelInputError) as e:
        make_camera(name, 64, 0)
    assert e.value.parameter == "height"


def test_equirectangular_must_be_2_to_1():
    with pytest.raises(SkymodelInputError) as e:
        make_camera("equirectangular", 64, 40)
    assert e.value.parameter == "height"
    with pytest.raises(SkymodelInputError) as e:
        make_camera("equirectangular", 65)
    assert e.value.parameter == "width"


def test_unknown_or_bad_option():
    with pytest.raises(SkymodelInputError) as e:
        make_camera("fisheye", 64, center_azimuth_deg=10)
    assert e.value.parameter == "center_azimuth_deg" and "max_zenith_deg" in str(e.value)
    with pytest.raises(SkymodelInputError) as e:
        make_camera("dome", 64, below_horizon_deg=-5)
    assert e.value.parameter == "below_horizon_deg"
    with pytest.raises(SkymodelInputError) as e:
        make_camera("fisheye", 64, max_zenith_deg=float("nan"))
    assert e.value.parameter == "max_zenith_deg"


def test_memory_estimate_and_limit():
    assert estimate_memory_bytes(100, 50, 81) == 100 * 50 * 81 * 8 * MEMORY_FACTOR
    with pytest.raises(SkymodelInputError) as e:
        estimate_memory_bytes(100, 50, 0)
    assert e.value.parameter == "n_wavelengths"
    est = estimate_memory_bytes(8192, 4096, 81)
    assert est > 4 * 1024**3
    with pytest.raises(SkymodelInputError) as e:
        make_camera("equirectangular", 8192)
    assert e.value.parameter == "width"
    assert str(est) in str(e.value) and "GiB" in str(e.value)
    # the limit is settable, and n_wavelengths counts
    make_camera("equirectangular", 8192, max_memory_bytes=2 * est)
    make_camera("equirectangular", 8192, n_wavelengths=3)
    with pytest.raises(SkymodelInputError) as e:
        make_camera("fisheye", 64, max_memory_bytes=1000)
    assert e.value.parameter == "width"
    with pytest.raises(SkymodelInputError) as e:
        make_camera("fisheye", 64, max_memory_bytes=-1)
    assert e.value.parameter == "max_memory_bytes"


def test_describe_is_json_friendly():
    import json

    cam = make_camera("dome", 90, below_horizon_deg=5)
    desc = json.loads(json.dumps(cam.describe()))
    assert desc == {"camera": "dome", "width": 90, "height": 24, "center_azimuth_deg": 180.0,
                    "below_horizon_deg": 5.0}


@pytest.mark.parametrize("name", ["equirectangular", "dome", "fisheye"])
def test_directions_of_a_band_of_rows_are_those_of_the_whole_image(name):
    """Large renders look up their pixels by bands of rows (``Camera.directions_rows``)."""
    cam = make_camera(name, 64)
    d, valid = cam.directions()
    for start, stop in ((0, 1), (3, 17), (cam.height - 5, cam.height)):
        dr, vr = cam.directions_rows(start, stop)
        np.testing.assert_array_equal(dr, d[start:stop])
        np.testing.assert_array_equal(vr, valid[start:stop])


@pytest.mark.parametrize("name, w, h, opts", [("equirectangular", 512, 256, {}), ("equirectangular", 96, 48, {}),
                                              ("dome", 360, 120, {"below_horizon_deg": 10.0})])
@pytest.mark.parametrize("zenith, angle", [(65.0, 8.0), (78.0, 12.0), (3.0, 8.0), (95.0, 2.0), (0.0, 5.0)])
def test_panorama_counts_the_pixels_near_a_direction(name, w, h, opts, zenith, angle):
    """The memory guard's count of pixels near the sun, row by row without any direction, is
    the count over the pixels' directions (up to one pixel per row for the rounding up); a
    cap around the pole (zenith 3, 8 degrees) takes whole rows."""
    cam = make_camera(name, w, h, **opts)
    d, _ = cam.directions()
    zs = np.radians(zenith)
    sun = np.array([np.sin(zs), 0.0, np.cos(zs)])
    exact = int((d @ sun >= np.cos(np.radians(angle))).sum())
    counted = cam.pixels_near(zenith, angle)
    assert exact <= counted <= exact + 2 * h


def test_other_cameras_bound_the_pixels_near_a_direction():
    """A camera without a row formula counts the share 1 - cos(angle) of its pixels, a bound."""
    cam = make_camera("fisheye", 256, 256)
    d, valid = cam.directions()
    for zenith in (0.0, 45.0, 80.0):
        zs = np.radians(zenith)
        sun = np.array([0.0, np.sin(zs), np.cos(zs)])
        exact = int(((d @ sun >= np.cos(np.radians(8.0))) & valid).sum())
        assert exact <= cam.pixels_near(zenith, 8.0)
