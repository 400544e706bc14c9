"""skymodel.render.exposure: the one exposure rule of the add-on, `skymodel render`'s PNG and
`skymodel timelapse` (the sky meter's night branch, its continuity through a day, and the
same exposure for the same instant in the CLI and the environment map)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from skymodel import scene
from skymodel.cli.main import main
from skymodel.render import exposure

TINY = ["--location", "zaragoza", "--quality", "preview", "--wavelength-step", "50", "--altitudes", "32", "--quiet"]
#: Sky log-averages [cd m^-2] of an environment map (rural, 64 px, preview; docs/night.md "The
#: exposure"): noon of 2026-12-21, a 93 %-lit moon 66 degrees up that night, a moonless night.
NOON, FULL_MOON, MOONLESS = 2750.0, 5.39e-3, 2.96e-4


def _y(cd_m2):
    return cd_m2 / exposure.CANDELA_PER_UNIT


def test_the_sky_target_meets_the_day_key_at_the_knee_and_falls_at_a_quarter_below():
    knee = _y(exposure.NIGHT_KNEE_CD_M2)
    assert exposure.sky_target(knee * (1 + 1e-12)) == pytest.approx(exposure.sky_target(knee * (1 - 1e-12)))
    assert exposure.sky_target(knee) == pytest.approx(exposure.SKY_KEY_SCALE * exposure.sky_key(knee))
    for y in (knee, _y(100.0), _y(3000.0)):  # day and twilight: the existing key, unchanged
        assert exposure.sky_target(y) == exposure.SKY_KEY_SCALE * exposure.sky_key(y)
    # below: 8 stops less light are shown 2 stops darker (the exposure opens up by 6)
    assert exposure.sky_target(knee / 2**8) == pytest.approx(exposure.sky_target(knee) / 4)
    assert exposure.exposure_from_sky(knee / 2**8) - exposure.exposure_from_sky(knee) == pytest.approx(6.0)


def test_the_exposure_falls_continuously_with_the_light_and_never_faster():
    y = np.geomspace(1e-9, 20.0, 4000)  # a starless night to a bright day, in colour-scale units
    ev = np.array([exposure.exposure_from_sky(v) for v in y])
    shown = np.array([exposure.sky_target(v) for v in y])
    assert np.all(np.diff(ev) < 0) and np.all(np.diff(shown) > 0)  # brighter sky: less exposure, shown brighter
    # a step of the light moves the exposure by at most as many stops (no jump of its own)
    assert np.max(np.abs(np.diff(ev)) / np.diff(np.log2(y))) <= 1.0


def test_a_moonlit_night_is_shown_brighter_than_a_moonless_one_and_both_under_the_day():
    day, moon, dark = (exposure.sky_target(_y(v)) for v in (NOON, FULL_MOON, MOONLESS))
    under_moon, under_dark = np.log2(day / moon), np.log2(day / dark)
    assert under_moon == pytest.approx(3.6, abs=0.1)  # the figures docs/night.md states
    assert under_dark == pytest.approx(4.7, abs=0.1)
    assert dark < moon < day


def test_a_coarse_days_exposure_changes_no_more_than_its_light(tmp_path):
    """A 24-hour time-lapse every hour (full moon, so the frames cross dusk, -18 degrees, the
    night and moonrise): between consecutive frames the exposure moves by no more stops than
    the light it meters (the sky's log-average, or the horizontal illuminance where the
    incident rule wins), so no frame jumps on its own; night frames are exposed far above
    day frames and a frame's PNG exposure is its own display exposure."""
    out = tmp_path / "day"
    assert main(["timelapse", *TINY, "--size", "16x8", "--no-video", "--date", "2026-01-03", "--from", "00:00",
                 "--to", "23:00", "--every", "1h", "--timezone", "UTC", "--out", str(out)]) == 0
    frames = json.loads((out / "frames.json").read_text())["frames"]
    m = [f["exposure"] for f in frames]
    ev = np.array([x["exposure"] for x in m])
    assert np.array_equal(ev, [f["preview_exposure_ev"] for f in frames])  # follow: each frame its own
    light = np.log2([[x["sky_log_average_Y"], x["horizontal_illuminance_Y"]] for x in m])
    assert np.all(np.abs(np.diff(ev)) <= np.max(np.abs(np.diff(light, axis=0)), axis=1) + 1e-9)
    els = np.array([f["sun_elevation_deg"] for f in frames])
    assert els.min() < -18 < 0 < els.max()
    assert ev[els < -18].min() > ev[els > 10].max() + 10


def _cli_meter(monkeypatch, tmp_path, t, *extra):
    """The display exposure `skymodel render` gives its PNG for instant ``t`` (32x16)."""
    got = []
    real = exposure.display_exposure
    monkeypatch.setattr(exposure, "display_exposure", lambda *a, **k: got.append(real(*a, **k)) or got[-1])
    assert main(["render", *TINY, "--size", "32", "--time", t, "--out", str(tmp_path / "c.exr"), *extra]) == 0
    return got[-1]


@pytest.mark.parametrize("t", ["2026-01-03T23:00:00Z", "2026-01-18T23:00:00Z", "2026-01-03T12:00:00Z"])
def test_the_cli_png_and_the_environment_map_get_the_same_exposure(monkeypatch, tmp_path, t):
    """One rule: `skymodel render`'s PNG (the moon's and the sun's discs in the image) and the
    add-on's environment map (the same sky, the sun and the moon as lamps) of the same
    instant are exposed alike: a full-moon night, a moonless night, noon."""
    from skymodel.optics.atmosphere import Atmosphere
    from skymodel.render.environment import render_environment

    cli = _cli_meter(monkeypatch, tmp_path, t)
    atm = Atmosphere(location="zaragoza", month=scene.month_of(t), day_of_year=scene.day_of_year(t), n_altitudes=32)
    sun = scene.place_sun(atm.latitude, atm.longitude, t, allow_night=True)
    _, env = render_environment(atm, sun.elevation_deg, sun.azimuth_deg,
                                earth_sun_distance_au=sun.earth_sun_distance_au, width=32, wavelength_step_nm=50,
                                time_iso=t, cache_dir=tmp_path / "env")
    assert cli["exposure"] == pytest.approx(env.exposure, abs=0.05)  # measured: within 0.04 EV
    # the disc left out: the sun and the moon still count as light on the ground
    no_disc = _cli_meter(monkeypatch, tmp_path, t, "--no-sun")
    assert no_disc["exposure"] == pytest.approx(cli["exposure"], abs=0.05)


def test_save_outputs_refuses_a_bad_average_luminance(tmp_path):
    from skymodel.errors import SkymodelInputError
    from skymodel.render import image_io
    from skymodel.render.cameras import make_camera

    cam = make_camera("equirectangular", 8)
    for bad in (0.0, -1.0, float("nan"), "grey"):
        with pytest.raises(SkymodelInputError, match="average_luminance"):
            image_io.save_outputs(png=str(tmp_path / "a.png"), xyz=np.ones(cam.shape + (3,)), wavelengths=None,
                                  camera=cam, average_luminance=bad)
    assert not (tmp_path / "a.png").exists()
