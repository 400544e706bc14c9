"""The night in the renderer (skymodel.render.night, issue #24): moonlit sky, stars, moon disc and
glow through the renderer, continuity over the sun's -12..-18 and the moon's horizon, the 24-hour
sequence. Small tables (the preview preset shrunk, 9 wavelengths), so every test takes seconds."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from skymodel import scene
from skymodel.astro.stars import catalogue, star_irradiance, star_positions
from skymodel.colorimetry import cmf_weights
from skymodel.render import night
from skymodel.render.cameras import make_camera
from skymodel.render.sequence import SolutionCache
from skymodel.render.sky import render_sky_reduced
from skymodel.render.skyview import Reduction, xyz_reduction
from skymodel.wavelengths import default_wavelengths

ZARAGOZA = (41.65, -0.88)
WL = default_wavelengths(50.0)


@pytest.fixture(autouse=True)
def small_preview_unless_marked(request):
    """The preview preset with small tables (conftest's ``small_preview``: the night's arithmetic
    does not depend on their size), except for the tests marked ``full_preview`` (deep twilight
    needs the preset's own tables: with 10 sun-elevation nodes the sunlit sky at -14..-18 is not
    even monotonic)."""
    if not request.node.get_closest_marker("full_preview"):
        request.getfixturevalue("small_preview")


@pytest.fixture(scope="module")
def profile():
    from skymodel.optics.atmosphere import Atmosphere

    return Atmosphere(location="zaragoza", month=1, n_altitudes=32).optical_profile(WL)


def _frame(profile, camera, time_utc, cache, matrix=None):
    """What `skymodel render --time` composes: the sunlit sky above its bound plus the night's light,
    in the channels of ``matrix`` (None: XYZ). Returns (image, sun placement, NightInfo)."""
    red = xyz_reduction(WL) if matrix is None else Reduction(matrix, matrix.shape[1])
    sun = scene.place_sun(*ZARAGOZA, time_utc, allow_night=True)
    out = np.zeros(camera.shape + (red.n_channels,))
    if night.sunlit(sun.elevation_deg):
        out, _, _ = render_sky_reduced(profile, camera, sun.elevation_deg, red, red.n_channels, sun.azimuth_deg, 0.0,
                                       "preview", solutions=cache)
    add, info = night.night_light(profile, camera, *ZARAGOZA, sun.time_utc, red.matrix,
                                  sun_elevation_deg=sun.elevation_deg, quality="preview", solutions=cache)
    return out + add, sun, info


def _sky_mean_y(camera, xyz):
    d, valid = camera.directions()
    up = valid & (d[..., 2] > 0)
    w = camera.pixel_solid_angles()[up]
    return float(np.sum(xyz[..., 1][up] * w) / np.sum(w))


# ----------------------------------------------------------------------------- the pieces


@pytest.mark.full_preview
def test_line_of_sight_transmittance_agrees_with_the_marchers_sun_table(profile):
    from skymodel.render.marcher import solve_sky
    from skymodel.render.quality import quality_settings

    table = solve_sky(profile, quality_settings("preview")).sun_table
    z = np.array([0.0, 45.0, 70.0, 85.0, 89.0, 90.0])
    ours = night.slant_transmittance(profile, z)
    theirs = np.exp(-table.optical_depth(np.zeros(z.size), np.cos(np.radians(z)), 0))
    # two integrations of one profile (theirs the preview's 96 x 192 table): measured 0.03 % at the
    # zenith, 0.1 % at 85 deg, 0.4 % at 89 deg
    assert np.allclose(ours, theirs, rtol=0.005, atol=0)
    assert np.allclose(night.TransmittanceTable(profile)(z), ours, rtol=2e-3)


@pytest.mark.parametrize("name", ["equirectangular", "fisheye", "dome"])
def test_point_sources_keep_their_irradiance_in_every_camera(name):
    cam = make_camera(name, 64)
    rng = np.random.default_rng(3)
    el, az = np.radians(rng.uniform(2, 89, 50)), np.radians(rng.uniform(0, 360, 50))
    dirs = np.stack([np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el)], axis=-1)
    e = rng.uniform(0.5, 2.0, (50, 2))
    img = night.splat_points(cam, dirs, e, np.zeros(cam.shape + (2,)))
    total = np.einsum("hwk,hw->k", img, cam.pixel_solid_angles())
    assert np.allclose(total, e.sum(axis=0), rtol=1e-12)


def test_equirectangular_points_land_where_the_astro_splat_puts_them():
    from skymodel.astro.stars import splat_stars

    cam = make_camera("equirectangular", 64, center_azimuth_deg=90.0)
    el, az = np.array([10.0, 45.0, 80.0]), np.array([30.0, 200.0, 359.0])
    e = np.array([[1.0], [2.0], [3.0]])
    ref = splat_stars(np.zeros((32, 64, 1)), el, az, e)
    d = np.stack([np.cos(np.radians(el)) * np.sin(np.radians(az)), np.cos(np.radians(el)) * np.cos(np.radians(az)),
                  np.sin(np.radians(el))], axis=-1)
    ours = night.splat_points(cam, d, e, np.zeros((32, 64, 1)))
    assert np.allclose(ours, ref, rtol=1e-9, atol=0)


# ----------------------------------------------------------------------------- a moonless night


def test_a_moonless_night_is_finite_with_the_stars_where_the_catalogue_puts_them(profile):
    # 2026-01-18 23:00 UTC at Zaragoza: new moon (below the horizon), the sun at -67 deg
    cam = make_camera("equirectangular", 256, center_azimuth_deg=90.0, n_wavelengths=WL.size)
    t = "2026-01-18T23:00:00Z"
    spectra, sun, info = _frame(profile, cam, t, SolutionCache(), matrix=np.eye(WL.size))
    assert not night.sunlit(sun.elevation_deg) and info.moon_elevation_deg < 0 and not info.moonlit_sky
    assert np.all(np.isfinite(spectra)) and np.all(spectra >= 0) and info.stars_drawn > 3000
    # Sirius (HIP 32349, V -1.44): its 2x2 pixels hold its irradiance x the line of sight's
    # transmittance, within 10 %, on the glow of its rows
    cat = catalogue()
    k = int(np.argmin(cat.v_mag))
    sp = star_positions(*ZARAGOZA, t)
    el, az = float(sp.elevation_deg[k]), float(sp.azimuth_deg[k])
    assert el > 10
    d = np.array([math.cos(math.radians(el)) * math.sin(math.radians(az)),
                  math.cos(math.radians(el)) * math.cos(math.radians(az)), math.sin(math.radians(el))])
    (x, y), _ = cam.project(d)
    i545 = int(np.argmin(abs(WL - 550.0)))
    y545 = spectra[..., i545]
    peak = np.unravel_index(np.argmax(np.where(np.abs(np.arange(y545.shape[0])[:, None] - y) < 3, y545, 0)), y545.shape)
    assert abs(peak[0] - y) <= 1.0 and min(abs(peak[1] - x), cam.width - abs(peak[1] - x)) <= 1.0
    rows, cols = slice(int(np.floor(y)), int(np.floor(y)) + 2), [int(np.floor(x)) % cam.width,
                                                                  (int(np.floor(x)) + 1) % cam.width]
    omega = cam.pixel_solid_angles()
    background = np.median(y545[rows], axis=1)[:, None]
    got = float(np.sum((y545[rows][:, cols] - background) * omega[rows][:, cols]))
    # its spectrum (skymodel.astro.stars: V, B-V; tests/test_astro_stars.py checks the V zero point)
    e_top = float(star_irradiance(WL, cat.v_mag[k:k + 1], cat.b_v[k:k + 1])[0, i545])
    expected = e_top * float(night.slant_transmittance(profile, [90.0 - el])[0, i545])
    assert got == pytest.approx(expected, rel=0.10)


# ----------------------------------------------------------------------------- a full moon


def test_a_full_moon_at_45_degrees_lights_the_daytime_sky_shifted_by_the_lunar_spectrum(profile):
    """The check: the moonlit sky is, pixel by pixel and wavelength by wavelength, the sky of the
    same geometry lit by the sun (the sun at the moon's place) times E_moon / E_sun (to round-off);
    its chromaticity is that sky's shifted toward red, by about what the lunar spectrum shifts
    sunlight; its zenith is 1e-6 of that sky's, the ratio of the irradiances."""
    from skymodel.astro.lunar_irradiance import moon_irradiance
    from skymodel.astro.moon import moon_position

    cam = make_camera("equirectangular", 32, center_azimuth_deg=90.0, n_wavelengths=WL.size)
    t = "2026-01-03T21:15:00Z"  # the full moon (phase angle 8 deg) at 45 deg, the sun at -49 deg
    moon = moon_position(*ZARAGOZA, t)
    assert abs(float(moon.elevation_deg) - 45.0) < 0.3 and float(moon.phase_angle_deg) < 10
    cache = SolutionCache()
    eye = Reduction(None, WL.size)
    day, _, _ = render_sky_reduced(profile, cam, float(moon.elevation_deg), eye, WL.size, float(moon.azimuth_deg),
                                   0.0, "preview", solutions=cache)
    lit, _, _ = render_sky_reduced(night.moon_profile(profile, moon), cam, float(moon.elevation_deg), eye, WL.size,
                                   float(moon.azimuth_deg), 0.0, "preview", solutions=cache)
    ratio = moon_irradiance(moon, WL) / profile.solar_irradiance
    assert np.allclose(lit, day * ratio, rtol=1e-9, atol=0) and cache.stats["solves"] == 1  # one solve serves both

    def xy(spec):
        X, Y, Z = spec @ cmf_weights(WL)
        return np.array([X, Y]) / (X + Y + Z)

    zen_day, zen_moon = xy(day[0].mean(axis=0)), xy(lit[0].mean(axis=0))
    src = xy(moon_irradiance(moon, WL)) - xy(profile.solar_irradiance)
    assert 0.005 < zen_moon[0] - zen_day[0] < 0.06 and zen_moon[1] > zen_day[1]
    assert np.sign(zen_moon - zen_day).tolist() == np.sign(src).tolist()
    # through the renderer's composition: the moonlit sky is there, and it dominates the glow
    xyz, _, info = _frame(profile, cam, t, cache)
    assert info.moonlit_sky and 0.1 < info.moon_illuminance_lux * math.sin(math.radians(45)) < 0.3


def test_moon_lamp_numbers(profile):
    lamp = night.moon_lamp(profile, *ZARAGOZA, "2026-01-03T21:15:00Z")
    assert 44.5 < lamp.elevation_deg < 45.5 and 0.45 < lamp.angle_deg < 0.6 and lamp.visible_fraction == 1.0
    assert lamp.illuminance_lux == pytest.approx(683.0 * lamp.strength, rel=0.01)
    r, g, b = lamp.colour
    assert r > g > b and abs(0.2126 * r + 0.7152 * g + 0.0722 * b - 1.0) < 1e-6  # moonlight is redder than white
    down = night.moon_lamp(profile, *ZARAGOZA, "2026-01-18T23:00:00Z")
    assert down.strength == 0.0 and down.visible_fraction == 0.0 and json.dumps(down.lamp())


# ----------------------------------------------------------------------------- continuity


def _steps(times, profile, cam, cache):
    ys = [_sky_mean_y(cam, _frame(profile, cam, t, cache)[0]) for t in times]
    return np.array(ys), np.abs(np.diff(ys))


@pytest.mark.full_preview
def test_the_sun_passes_minus_12_to_minus_18_without_a_jump(profile):
    """Frames every 5 minutes (the sun 0.9 deg apart) as the sun goes from -12 to -20 on a
    moonless evening. Criterion: the step of the sky's mean luminance across the frame pair that
    straddles -18 (where the sunlit sky is dropped) is no larger than the larger of the two
    neighbouring steps (the physical change between neighbouring frames)."""
    cam = make_camera("equirectangular", 32, center_azimuth_deg=90.0)
    times = [f"2026-01-18T18:{m:02d}:00Z" for m in range(8, 49, 5)]
    els = [scene.place_sun(*ZARAGOZA, t, allow_night=True).elevation_deg for t in times]
    assert els[0] > -12.5 and els[-1] < -19.0
    ys, steps = _steps(times, profile, cam, SolutionCache())
    assert np.all(np.diff(ys) < 1e-3 * ys[1:])  # darker and darker (below -18: the stars move, the glow stays)
    b = next(i for i in range(len(els) - 1) if els[i] >= -18.0 > els[i + 1])
    assert steps[b] <= max(steps[b - 1], steps[b + 1])


def test_the_moon_rises_without_a_jump(profile):
    """Frames every 2 minutes across a moonrise in a dark sky (2026-01-05 19:25 UTC, phase 33 deg,
    the sun at -29): the steps across the horizon crossing are no larger than the larger of the
    steps just before and after (the moonlit sky grows continuously from below the horizon; the
    disc fades in with the fraction above the horizon)."""
    cam = make_camera("equirectangular", 32, center_azimuth_deg=90.0)
    times = [f"2026-01-05T19:{m:02d}:00Z" for m in range(13, 38, 2)]
    from skymodel.astro.moon import moon_position

    els = np.array([float(moon_position(*ZARAGOZA, t).elevation_deg) for t in times])
    assert els[0] < -1.0 and els[-1] > 1.0
    ys, steps = _steps(times, profile, cam, SolutionCache())
    b = int(np.nonzero((els[:-1] < 0) & (els[1:] >= 0))[0][0])
    assert steps[b] <= max(steps[b - 1], steps[b + 1])
    assert np.all(np.diff(ys) > 0)  # the rising moon brightens the sky frame by frame


# ----------------------------------------------------------------------------- daytime, exposure, the CLI


def test_a_daytime_map_is_unchanged_by_the_night(tmp_path):
    from skymodel.optics.atmosphere import Atmosphere
    from skymodel.render.environment import render_environment

    atm = Atmosphere(location="zaragoza", month=1, n_altitudes=32)
    t = "2026-01-03T12:00:00Z"  # the moon below the horizon
    sun = scene.place_sun(atm.latitude, atm.longitude, t)
    maps = [render_environment(atm, sun.elevation_deg, sun.azimuth_deg, width=32, time_iso=t, wavelength_step_nm=50,
                               cache_dir=tmp_path / mode, night=mode, include_sun=True)[0] for mode in ("auto", "off")]
    assert np.array_equal(*maps)


def test_a_24_hour_timelapse_runs_through_the_night(tmp_path):
    from skymodel.cli.main import main

    out = tmp_path / "day"
    assert main(["timelapse", "--location", "zaragoza", "--size", "16x8", "--wavelength-step", "50", "--altitudes",
                 "32", "--quiet", "--no-video", "--date", "2026-01-05", "--from", "00:00", "--to", "21:00", "--every",
                 "3h", "--timezone", "UTC", "--out", str(out)]) == 0
    rec = json.loads((out / "frames.json").read_text())
    frames = rec["frames"]
    assert rec["complete"] and len(frames) == 8 and rec["sequence"]["night"] == "auto"
    assert min(f["sun_elevation_deg"] for f in frames) < -18 < max(f["sun_elevation_deg"] for f in frames)
    for f in frames:
        assert f["exposure"]["sky_log_average_Y"] > 0 and "night" in f and math.isfinite(f["zenith_Y"])
    noon = next(f for f in frames if f["time_utc"].startswith("2026-01-05T12"))
    midnight = frames[0]
    assert midnight["preview_exposure_ev"] > noon["preview_exposure_ev"] + 10.0
    # the night's preview is darker than the day's
    from PIL import Image

    mean = {k: np.asarray(Image.open(out / f["png"]), float).mean() for k, f in (("noon", noon), ("night", midnight))}
    assert 0 < mean["night"] < 0.6 * mean["noon"]


def test_render_cli_at_night_and_with_night_off(tmp_path, capsys):
    from skymodel.cli.main import main

    base = ["render", "--location", "zaragoza", "--size", "16", "--wavelength-step", "50", "--altitudes", "32",
            "--quiet", "--time", "2026-01-18T23:00:00Z"]
    assert main([*base, "--out", str(tmp_path / "n.exr")]) == 0 and (tmp_path / "n.png").is_file()
    assert main([*base, "--night", "off", "--out", str(tmp_path / "off.exr")]) == 2
    assert "time_utc" in capsys.readouterr().err


def test_a_daytime_render_differs_from_the_sunlit_sky_only_by_the_moon(tmp_path, monkeypatch):
    from skymodel.cli.main import main
    from skymodel.render import image_io

    written = {}
    real = image_io._prepare_exr

    def spy(path, rgb, *a, **k):
        written[str(path).rsplit("/", 1)[-1]] = np.array(rgb)
        return real(path, rgb, *a, **k)

    monkeypatch.setattr(image_io, "_prepare_exr", spy)
    base = ["render", "--location", "zaragoza", "--size", "32", "--wavelength-step", "50", "--altitudes", "32",
            "--quiet", "--no-png"]
    for name, t in (("down", "2026-01-03T12:00:00Z"), ("up", "2026-01-10T09:00:00Z")):  # the moon down, then up
        for mode in ("auto", "off"):
            assert main([*base, "--time", t, "--night", mode, "--out", str(tmp_path / f"{name}-{mode}.exr")]) == 0
    assert np.array_equal(written["down-auto.exr"], written["down-off.exr"])  # bit for bit
    differ = np.any(written["up-auto.exr"] != written["up-off.exr"], axis=-1)
    assert 1 <= differ.sum() <= 4  # the daytime moon's pixels, nothing else


def test_a_moonlit_night_map_and_its_moon_lamp(tmp_path):
    from skymodel.optics.atmosphere import Atmosphere
    from skymodel.render.environment import render_environment

    atm = Atmosphere(location="zaragoza", month=1, n_altitudes=32)
    t = "2026-01-03T21:15:00Z"  # full moon at 45 deg, the sun at -49 (below the sunlit sky's bound)
    sun = scene.place_sun(atm.latitude, atm.longitude, t, allow_night=True)
    assert not night.sunlit(sun.elevation_deg)
    maps = {}
    for disc in (False, True):
        rgb, env = render_environment(atm, sun.elevation_deg, sun.azimuth_deg, width=64, time_iso=t,
                                      wavelength_step_nm=50, cache_dir=tmp_path / str(disc), include_sun=disc)
        assert np.all(np.isfinite(rgb)) and np.all(rgb >= 0) and math.isfinite(env.exposure)
        assert env.sun_strength == 0.0 and env.info["night"]["moonlit_sky"]
        maps[disc] = rgb
    moon = env.info["moon"]
    assert 44.5 < moon["elevation_deg"] < 45.5 and moon["strength"] > 0
    # the lamp mode leaves the disc to the lamp: the maps differ only at the moon's pixels
    differ = np.any(maps[True] != maps[False], axis=-1)
    assert 1 <= differ.sum() <= 4
    # a cache hit returns the same lamp numbers
    _, again = render_environment(atm, sun.elevation_deg, sun.azimuth_deg, width=64, time_iso=t, wavelength_step_nm=50,
                                  cache_dir=tmp_path / "True", include_sun=True)
    assert again.cache_hit and again.info["moon"] == moon
