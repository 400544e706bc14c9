"""The command line: profile, sun, presets, radiance, render and its errors."""

import json

import numpy as np
import pytest

from skymodel.cli import main


def run(capsys, *argv):
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


def test_profile_json(capsys):
    code, out, _ = run(capsys, "profile", "--location", "urban", "--month", "6", "--wavelengths", "400,550,700",
                       "--json")
    assert code == 0
    s = json.loads(out)
    assert s["wavelengths_nm"] == [400.0, 550.0, 700.0]
    for key in ("rayleigh_optical_depth", "ozone_optical_depth", "aerosol_optical_depth",
                "aerosol_single_scattering_albedo", "aerosol_asymmetry"):
        assert len(s[key]) == 3 and all(np.isfinite(s[key]))
    assert s["rayleigh_optical_depth"][0] > s["rayleigh_optical_depth"][1] > s["rayleigh_optical_depth"][2]
    assert 100 < s["ozone_column_du"] < 600 and np.isfinite(s["angstrom_exponent"])


def test_profile_layers(capsys):
    code, out, _ = run(capsys, "profile", "--location", "desert", "--wavelengths", "550", "--layers", "6", "--json")
    s = json.loads(out)
    lay = s["layers"]
    assert len(lay["edges_m"]) == 7
    assert sum(r[0] for r in lay["rayleigh_optical_depth"]) == pytest.approx(s["rayleigh_optical_depth"][0], rel=1e-6)
    phase = np.asarray(lay["aerosol_phase_function_sr-1"])
    assert phase.shape[0] == 6 and phase.shape[2] == 1


def test_profile_answers_wavelengths_in_the_users_order(capsys):
    """Wavelengths in any order are computed on the ascending grid and answered in the order
    given (every per-wavelength array, the layers' too); a duplicate is refused naming them."""
    args = ("profile", "--location", "urban", "--month", "6", "--layers", "3", "--json")
    code, out, _ = run(capsys, *args, "--wavelengths", "700,400,550")
    assert code == 0
    mixed = json.loads(out)
    code, out, _ = run(capsys, *args, "--wavelengths", "400,550,700")
    ordered = json.loads(out)
    order = [2, 0, 1]  # 700, 400, 550 in the ascending list
    assert mixed["wavelengths_nm"] == [700.0, 400.0, 550.0]
    for key in ("rayleigh_optical_depth", "ozone_optical_depth", "aerosol_optical_depth"):
        assert mixed[key] == [ordered[key][i] for i in order]
        assert [row for row in mixed["layers"][key]] == [[r[i] for i in order] for r in ordered["layers"][key]]
    assert mixed["layers"]["edges_m"] == ordered["layers"]["edges_m"]
    code, _, err = run(capsys, "profile", "--wavelengths", "550,550")
    assert code == 2 and "wavelengths" in err


def test_sun_json_matches_the_module(capsys):
    from skymodel import sun

    code, out, _ = run(capsys, "sun", "--lat", "41.65", "--lon", "-0.88", "--time", "2026-06-21T12:00:00Z", "--json")
    s = json.loads(out)
    pos = sun.solar_position(41.65, -0.88, "2026-06-21T12:00:00Z")
    assert s["elevation_deg"] == pytest.approx(float(pos.elevation_deg))
    assert 60 < s["elevation_deg"] < 80 and 0 <= s["azimuth_deg"] < 360


def test_presets_lists_everything(capsys):
    code, out, _ = run(capsys, "presets", "--json")
    s = json.loads(out)
    assert "urban" in s["locations"] and "desert" in s["aerosol_types"] and len(s["aerosol_components"]) >= 10


@pytest.mark.parametrize("argv, parameter", [
    (["profile", "--month", "13"], "month"),
    (["profile", "--location", "atlantis"], "location"),
    (["profile", "--lat", "91", "--lon", "0", "--aerosol", "urban"], "latitude"),
    (["profile", "--aod550", "-1"], "aod550"),
    (["profile", "--wavelengths", "350,550"], "wavelengths"),
    (["sun", "--lat", "100", "--lon", "0", "--time", "2026-01-01T00:00:00Z"], "latitude"),
    (["render", "--sun-elevation", "-30", "--size", "16"], "sun_elevation"),
    (["render", "--camera", "pinhole", "--size", "16"], "camera"),
    (["render", "--quality", "ultra", "--size", "16"], "quality"),
    (["render", "--size", "0"], "width"),
])
def test_bad_input_is_one_clear_line(capsys, tmp_path, monkeypatch, argv, parameter):
    monkeypatch.chdir(tmp_path)
    code, out, err = run(capsys, *argv)
    assert code == 2
    assert parameter in err and "error" in err
    assert list(tmp_path.iterdir()) == []  # nothing written


def test_radiance_point_query(capsys):
    code, out, _ = run(capsys, "radiance", "--sun-elevation", "60", "--view-zenith", "0,60", "--relative-azimuth",
                       "0,180", "--wavelengths", "450,650", "--aerosol", "none", "--ozone-du", "300", "--albedo",
                       "0", "--quality", "preview", "--json")
    s = json.loads(out)
    rad = np.array([d["radiance"] for d in s["directions"]])
    assert rad.shape == (4, 2) and np.all(rad > 0)
    assert np.all(rad[:, 0] > rad[:, 1])  # a Rayleigh sky is bluer than red
    assert len(s["solar_irradiance_toa"]) == 2 and 1.5 < s["solar_irradiance_toa"][0] < 2.5


def test_render_writes_exr_png_and_spectral(capsys, tmp_path):
    out = tmp_path / "s.exr"
    code, _, err = run(capsys, "render", "--size", "32", "--camera", "fisheye", "--wavelength-step", "40",
                       "--out", str(out), "--spectral", str(tmp_path / "s.npz"), "--quiet")
    assert code == 0, err
    assert out.exists() and (tmp_path / "s.png").exists()
    z = np.load(tmp_path / "s.npz")
    assert z["radiance"].shape == (32, 32, 11) and np.all(np.isfinite(z["radiance"]))
