"""``skymodel timelapse`` and the instants of a sequence (issue #19), at tiny sizes."""

from __future__ import annotations

import json

import numpy as np
import pytest

from skymodel import scene
from skymodel.cli import timelapse
from skymodel.cli.main import main
from skymodel.errors import SkymodelInputError
from skymodel.render import image_io, timeline

ZARAGOZA = (41.65, -0.88)
TINY = ["--location", "zaragoza", "--size", "16x8", "--quality", "preview", "--wavelength-step", "50",
        "--altitudes", "32", "--quiet", "--no-video"]


@pytest.fixture(autouse=True)
def small_preview(monkeypatch):
    """The preview preset with small tables, so the tests are quick (the sharing and the
    equality do not depend on the tables' size)."""
    from dataclasses import replace

    from skymodel.render.quality import QUALITIES

    q = QUALITIES["preview"]
    small = replace(q.settings, table_altitudes=10, table_mu=12, table_phi=6, table_mus=10, table_steps=16,
                    sun_table_altitudes=24, sun_table_x=32, sun_table_steps=32, grid_zenith=16,
                    grid_zenith_ground=6, grid_azimuth=9, max_orders=4)
    monkeypatch.setitem(QUALITIES, "preview", replace(q, settings=small))


def _capture_exr(monkeypatch):
    """The arrays the command writes as EXR, by file name."""
    written = {}
    real = image_io.write_exr

    def spy(path, rgb, *a, **k):
        written[str(path).rsplit("/", 1)[-1]] = np.array(rgb)
        return real(path, rgb, *a, **k)

    monkeypatch.setattr(image_io, "write_exr", spy)
    return written


def test_a_day_of_three_frames_equals_three_independent_renders(tmp_path, monkeypatch):
    from skymodel.cli.options import profile_for_sun
    from skymodel.colorimetry import spectral_to_xyz, xyz_to_rgb
    from skymodel.optics.atmosphere import Atmosphere
    from skymodel.render.cameras import make_camera
    from skymodel.render.sky import render_sky
    from skymodel.wavelengths import default_wavelengths

    written = _capture_exr(monkeypatch)
    out = tmp_path / "day"
    assert main(["timelapse", *TINY, "--date", "2026-06-21", "--from", "20:00", "--to", "22:00", "--every", "1h",
                 "--timezone", "Europe/Madrid", "--night", "off", "--out", str(out)]) == 0  # the sunlit sky alone
    record = json.loads((out / "frames.json").read_text())
    assert record["complete"] and record["solves"] == 1 and len(record["frames"]) == 3
    wl = default_wavelengths(50.0)
    cam = make_camera("equirectangular", 16, 8, n_wavelengths=wl.size)
    for entry, local in zip(record["frames"], ("20:00", "21:00", "22:00")):
        # what `skymodel render --time 2026-06-21T<local> --timezone Europe/Madrid` renders
        sun = scene.place_sun(*ZARAGOZA, f"2026-06-21T{local}", timezone="Europe/Madrid")
        assert entry["time_utc"] == sun.time_utc and entry["time_local"].endswith("+02:00")
        atm = Atmosphere(location="zaragoza", month=sun.month, day_of_year=sun.day_of_year, n_altitudes=32)
        img = render_sky(profile_for_sun(atm, wl, sun), cam, sun.elevation_deg, sun.azimuth_deg, 0.0, "preview",
                         solutions=False)  # its own solve, not the process's shared one
        xyz = np.where(img.valid[..., None], spectral_to_xyz(img.radiance, wl), 0.0)
        # the same arithmetic on the same arrays: equal to the bit
        assert np.array_equal(xyz_to_rgb(xyz, "rec709"), written[entry["exr"]]), local
        assert (out / entry["png"]).is_file()
        header = (out / entry["exr"]).read_bytes()[:4000]
        assert entry["time_utc"].encode() in header  # the UTC instant in the EXR's own metadata
    assert [f["solve_reused"] for f in record["frames"]] == [False, True, True]
    assert (out / "contact_sheet.png").is_file()


def test_days_at_one_sun_elevation_solve_once_per_ozone_column(tmp_path):
    out = tmp_path / "year"
    assert main(["timelapse", *TINY, "--dates", "2026-01-15:2026-03-15", "--every", "1month", "--sun-elevation",
                 "-4", "--exposure-curve", "fixed", "--out", str(out)]) == 0
    record = json.loads((out / "frames.json").read_text())
    frames = record["frames"]
    assert [f["time_utc"][:10] for f in frames] == ["2026-01-15", "2026-02-15", "2026-03-15"]
    assert all(abs(f["sun_elevation_deg"] + 4.0) < 0.01 for f in frames)
    assert len({round(f["ozone_du"], 6) for f in frames}) == 3 and record["solves"] == 3
    assert len({f["preview_exposure_ev"] for f in frames}) == 1  # one exposure for the year
    mean = np.mean([f["exposure"]["exposure"] for f in frames])  # the mean of the frames' display exposures
    assert frames[0]["preview_exposure_ev"] == pytest.approx(mean)
    assert all(0.15 < f["zenith_xy"][0] < 0.35 and 0.15 < f["zenith_xy"][1] < 0.35 for f in frames)  # blue


def test_bad_input_is_refused_before_any_work(tmp_path, capsys):
    out = tmp_path / "never"
    cases = [
        (["--date", "2026-03-29", "--from", "02:30", "--to", "04:00", "--every", "10min", "--timezone",
          "Europe/Madrid"], "time_from"),
        (["--date", "2026-12-21", "--from", "17:00", "--to", "21:30", "--every", "10min", "--timezone",
          "Europe/Madrid", "--night", "off"], "time_to"),  # night without the night's light
        (["--date", "2026-06-21", "--from", "19:00", "--to", "20:00", "--every", "1month"], "every"),
        (["--date", "2026-06-21", "--from", "19:00", "--to", "20:00", "--every", "0min"], "every"),
        (["--date", "2026-06-21", "--from", "19:00", "--to", "20:00"], "every"),
        (["--date", "2026-06-21", "--to", "20:00", "--every", "1h"], "time_from"),
        (["--date", "2026-06-21", "--dates", "2026-01-01:2026-02-01"], "date"),
        (["--dates", "2026-01-15:2026-12-15", "--every", "1month"], "sun_elevation"),
        (["--dates", "2026-06-15:2026-01-15", "--every", "1month", "--sun-elevation", "-4"], "dates"),
        (["--dates", "2026-01-15:2026-12-15", "--every", "1month", "--sun-elevation", "-19"], "sun_elevation"),
        (["--date", "2026-06-21", "--from", "19:00", "--to", "20:00", "--every", "1h", "--month", "3"], "month"),
        (["--date", "2026-06-21", "--from", "19:00", "--to", "22:00", "--every", "1s", "--max-frames", "100"],
         "every"),
        (["--date", "2026-06-21", "--from", "19:00", "--to", "20:00", "--every", "1h", "--timezone", "Mars/Olympus"],
         "timezone"),
    ]
    for extra, parameter in cases:
        assert main(["timelapse", *TINY, *extra, "--out", str(out)]) == 2, extra
        err = capsys.readouterr().err
        assert f"{parameter}=" in err and err.count("\n") == 1, (extra, err)
        assert not out.exists(), extra
    # a folder holding a sequence is not written into without --overwrite
    out.mkdir()
    (out / "frames.json").write_text("{}")
    assert main(["timelapse", *TINY, "--date", "2026-06-21", "--from", "19:00", "--to", "20:00", "--every", "1h",
                 "--out", str(out)]) == 2
    assert "out=" in capsys.readouterr().err
    # with --overwrite, the previous sequence's frames go (none stays stale), other files stay
    (out / "frames.json").write_text('{"frames": [{"exr": "frame_0009.exr", "png": "../escape.png"}]}')
    (out / "frame_0009.exr").write_bytes(b"old")
    (out / "notes.txt").write_text("mine")
    assert main(["timelapse", *TINY, "--date", "2026-06-21", "--from", "19:00", "--to", "19:00", "--every", "1h",
                 "--overwrite", "--out", str(out)]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["contact_sheet.png", "frame_0001.exr", "frame_0001.png",
                                                    "frames.json", "notes.txt"]


def test_ctrl_c_leaves_only_finished_frames(tmp_path, monkeypatch):
    from skymodel.render import sequence

    real, calls = sequence.render_frame, []

    def interrupted(*a, **k):
        calls.append(1)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return real(*a, **k)

    monkeypatch.setattr(sequence, "render_frame", interrupted)
    out = tmp_path / "cut"
    assert main(["timelapse", *TINY, "--date", "2026-06-21", "--from", "19:00", "--to", "21:00", "--every", "1h",
                 "--timezone", "Europe/Madrid", "--out", str(out)]) == 130
    assert sorted(p.name for p in out.iterdir()) == ["frame_0001.exr", "frames.json"]
    record = json.loads((out / "frames.json").read_text())
    assert not record["complete"] and [f["exr"] for f in record["frames"]] == ["frame_0001.exr"]


def test_a_day_steps_in_real_time_across_the_autumn_clock_change():
    frames = timeline.day_frames(*ZARAGOZA, "2026-10-25", "07:30", "09:30", "30min", "Europe/Madrid")
    assert [f.time_local[11:] for f in frames] == ["07:30:00+01:00", "08:00:00+01:00", "08:30:00+01:00",
                                                   "09:00:00+01:00", "09:30:00+01:00"]
    # the night of the change: 01:30 CEST .. 03:30 CET is 3 hours, 02:xx happening twice
    with pytest.raises(SkymodelInputError, match="time_from"):
        timeline.day_frames(*ZARAGOZA, "2026-10-25", "02:30", "03:30", "30min", "Europe/Madrid")
    utc = [f.time_utc for f in timeline.day_frames(*ZARAGOZA, "2026-06-21", "06:59", "07:59", "1h",
                                                   "Europe/Madrid")]
    assert utc == ["2026-06-21T04:59:00Z", "2026-06-21T05:59:00Z"]


def test_parse_every_and_the_dusk_crossing():
    assert timeline.parse_every("10min") == ("seconds", 600)
    assert timeline.parse_every("2 hours") == ("seconds", 7200)
    assert timeline.parse_every("1month") == ("months", 1)
    assert timeline.parse_every("2weeks") == ("days", 14)
    for bad in ("", "min", "1.5h", "-1h", "10 parsecs"):
        with pytest.raises(SkymodelInputError, match="every"):
            timeline.parse_every(bad)
    frames = timeline.days_frames(*ZARAGOZA, "2026-01-31:2026-04-30", "1month", -4.0, "Europe/Madrid")
    assert [f.time_utc[:10] for f in frames] == ["2026-01-31", "2026-02-28", "2026-03-31", "2026-04-30"]
    assert all(abs(f.elevation_deg + 4.0) < 0.01 and 200 < f.azimuth_deg < 340 for f in frames)
    dawn = timeline.days_frames(*ZARAGOZA, "2026-03-20:2026-03-20", "1day", 10.0, None, "dawn")
    assert abs(dawn[0].elevation_deg - 10.0) < 0.01 and dawn[0].azimuth_deg < 180
    with pytest.raises(SkymodelInputError, match="dates"):  # midnight sun: never down to -4
        timeline.days_frames(78.0, 15.0, "2026-06-01:2026-06-02", "1day", -4.0)


def test_exposure_curve_and_contact_sheet():
    ev = np.array([-4.0, -1.0, 6.0, 11.0])
    assert np.array_equal(timelapse.exposure_curve(ev, "follow"), ev)  # each frame its own: the add-on's
    assert np.allclose(timelapse.exposure_curve(ev, "fixed"), 3.0)
    sheet = timelapse.contact_sheet([np.full((8, 16, 3), k, np.uint8) for k in range(5)])
    assert sheet.dtype == np.uint8 and sheet.shape[1] > sheet.shape[0]
