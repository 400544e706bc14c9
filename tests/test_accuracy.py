"""The accuracy benchmark (skymodel bench accuracy): the quick run, its error metrics, and
the checked-in measured table (skymodel/data/presets/accuracy/measured.json). No timing asserts."""

from __future__ import annotations

import copy
import json
import os

import numpy as np
import pytest

from skymodel.errors import SkymodelInputError
from skymodel.validation import accuracy
from skymodel.wavelengths import default_wavelengths

from skymodel.data import data_path

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
MEASURED = str(data_path("presets", "accuracy", "measured.json"))
ROW_KEYS = {"scene": str, "knob": str, "settings": dict, "time_s": float, "radiance_rel_rms": float,
            "radiance_rel_max": float, "de2000_mean": float, "de2000_p95": float}
PRESET_KEYS = ("time_s", "radiance_rel_mean", "de2000_mean", "peak_memory_mb", "width", "height")


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    """One quick run (all knobs, one scene, 32x16) with its own reference cache."""
    cache = tmp_path_factory.mktemp("cache")
    old = os.environ.get("SKYMODEL_CACHE")
    os.environ["SKYMODEL_CACHE"] = str(cache)
    try:
        yield accuracy.run_benchmark(accuracy.quick_config(), log=lambda m: None)
    finally:
        if old is None:
            os.environ.pop("SKYMODEL_CACHE", None)
        else:
            os.environ["SKYMODEL_CACHE"] = old


def _check_schema(result):
    for key, typ in (("machine", str), ("command", str), ("date", str), ("camera", dict), ("scenes", dict),
                     ("rows", list), ("presets", dict)):
        assert isinstance(result[key], typ), key
    assert result["camera"]["kind"] == "equirectangular"
    assert result["camera"]["width"] > 0 and result["camera"]["height"] > 0
    for name, scene in result["scenes"].items():
        assert name in accuracy.SCENES
        assert scene["sun_elevation_deg"] == accuracy.SCENES[name]
        assert isinstance(scene["location"], str) and isinstance(scene["month"], int)
    for row in result["rows"]:
        for key, typ in ROW_KEYS.items():
            assert isinstance(row[key], typ), (key, row)
        assert isinstance(row["value"], (str, int, float))
        assert row["knob"] in accuracy.KNOBS
        assert row["scene"] in result["scenes"]
        for key in ("time_s", "radiance_rel_rms", "radiance_rel_max", "de2000_mean", "de2000_p95"):
            assert np.isfinite(row[key]) and row[key] >= 0.0, (key, row)
        assert row["radiance_rel_max"] >= row["radiance_rel_rms"] - 1e-15
        assert row["de2000_p95"] >= 0.0
    assert set(result["presets"]) == {"preview", "final", "reference"}
    for name, per_scene in result["presets"].items():
        assert set(per_scene) == set(result["scenes"]), name
        for entry in per_scene.values():
            for key in PRESET_KEYS:
                assert np.isfinite(entry[key]) and entry[key] >= 0, (name, key)


def _row(result, knob, value, scene="noon"):
    (row,) = [r for r in result["rows"] if r["knob"] == knob and r["value"] == value and r["scene"] == scene]
    return row


def test_quick_run_has_the_schema_and_every_knob(quick):
    _check_schema(quick)
    cfg = accuracy.quick_config()
    for knob in accuracy.KNOBS:
        got = [r["value"] for r in quick["rows"] if r["knob"] == knob]
        want = list(cfg.presets) if knob == "preset" else list(cfg.knob_values(knob))
        assert got == want, knob
    json.dumps(quick)  # serialisable as is


def test_more_scattering_orders_shrink_the_error(quick):
    e = [_row(quick, "orders", n)["radiance_rel_rms"] for n in (1, 2, 4)]
    assert e[0] > e[1] > e[2]
    assert _row(quick, "orders", 1)["de2000_mean"] > _row(quick, "orders", 4)["de2000_mean"]
    # single scattering alone misses a large share of a noon sky (several percent at least)
    assert _row(quick, "orders", 1)["radiance_rel_mean"] > 0.05


def test_more_wavelengths_shrink_the_error(quick):
    assert _row(quick, "wavelengths", 11)["radiance_rel_mean"] > _row(quick, "wavelengths", 41)["radiance_rel_mean"]
    assert _row(quick, "wavelengths", 11)["de2000_mean"] > _row(quick, "wavelengths", 41)["de2000_mean"]
    # the 3-wavelength shortcut is the worst in colour
    assert _row(quick, "wavelengths", "rgb3")["de2000_mean"] > _row(quick, "wavelengths", 11)["de2000_mean"]


def test_reference_preset_has_zero_error(quick):
    ref = quick["presets"]["reference"]["noon"]
    # the reference against itself: zero up to rounding (the colour conversion's BLAS sums are not
    # bit-reproducible between runs: a CI run measured dE2000 1.6e-15)
    assert ref["radiance_rel_mean"] < 1e-12 and ref["de2000_mean"] < 1e-9
    assert quick["presets"]["final"]["noon"]["radiance_rel_mean"] > 0.0


def test_monte_carlo_error_falls_with_samples(quick):
    rows = [r for r in quick["rows"] if r["knob"] == "mc_samples"]
    assert len(rows) >= 2
    assert rows[0]["mc_stderr_rel_mean"] > rows[-1]["mc_stderr_rel_mean"]


def test_errors_of_an_image_against_itself_are_zero():
    rng = np.random.default_rng(3)
    wl = default_wavelengths(20.0)
    ref = rng.uniform(0.01, 0.5, (6, 5, wl.size))
    w = rng.uniform(0.1, 1.0, (6, 5))
    e = accuracy.errors(ref, wl, ref, wl, w)
    # the radiance is compared through the band matrix, the identity here: exactly zero
    assert [e[k] for k in ("radiance_rel_mean", "radiance_rel_rms", "radiance_rel_max")] == [0.0, 0.0, 0.0]
    # the colour difference runs the two images through the tone map and Lab separately;
    # BLAS may round those two passes differently in the last bit (two fresh-clone CI
    # runs saw a non-zero value here that no rerun reproduced), so round-off, not zero
    assert e["de2000_mean"] <= 1e-9 and e["de2000_p95"] <= 1e-9, (e["de2000_mean"], e["de2000_p95"])
    # a uniform 1% excess is a 1% error at every point
    e = accuracy.errors(ref * 1.01, wl, ref, wl, w)
    assert e["radiance_rel_mean"] == pytest.approx(0.01) and e["radiance_rel_max"] == pytest.approx(0.01)
    assert e["de2000_mean"] > 0.0
    # zero weight everywhere: nothing to compare
    with pytest.raises(SkymodelInputError, match="weights"):
        accuracy.errors(ref, wl, ref, wl, np.zeros((6, 5)))


def test_errors_by_view_band_place_an_error_in_the_band_that_has_it():
    """An error only near the horizon shows in the horizon band's row, not in the high sky's,
    and the whole sky's mean is the bands' means weighted by their solid angles."""
    rng = np.random.default_rng(5)
    wl = default_wavelengths(20.0)
    elev = np.repeat(np.array([2.0, 5.0, 8.0, 20.0, 45.0, 80.0])[:, None], 4, axis=1)
    ref = rng.uniform(0.01, 0.5, elev.shape + (wl.size,))
    w = rng.uniform(0.1, 1.0, elev.shape)
    img = ref.copy()
    img[elev < 10.0] *= 1.03
    e = accuracy.errors(img, wl, ref, wl, w, elevation_deg=elev)
    assert set(e["bands"]) == {"horizon", "low", "high"}  # no ground point, no ground band
    assert e["bands"]["horizon"]["radiance_rel_mean"] == pytest.approx(0.03)
    assert e["bands"]["horizon"]["radiance_rel_rms"] == pytest.approx(0.03)
    assert e["bands"]["high"]["radiance_rel_mean"] == 0.0 and e["bands"]["high"]["de2000_mean"] <= 1e-9
    assert e["bands"]["horizon"]["de2000_mean"] > 10 * e["bands"]["low"]["de2000_mean"]
    share = w[elev < 10.0].sum() / w.sum()
    assert e["radiance_rel_mean"] == pytest.approx(0.03 * share)
    assert e["de2000_mean"] == pytest.approx(sum(e["bands"][b]["de2000_mean"] * w[m].sum() for b, m in
                                                 (("horizon", elev < 10), ("low", (elev >= 10) & (elev < 30)),
                                                  ("high", elev >= 30))) / w.sum())
    assert "bands" not in accuracy.errors(img, wl, ref, wl, w)


def test_quick_run_rows_carry_their_errors_by_view_band(quick):
    row = _row(quick, "wavelengths", 11)
    assert set(row["bands"]) <= {"horizon", "low", "high"} and "high" in row["bands"]
    worst = max(b["de2000_mean"] for b in row["bands"].values())
    least = min(b["de2000_mean"] for b in row["bands"].values())
    assert least <= row["de2000_mean"] <= worst


def test_quick_run_rows_carry_their_error_as_lighting(quick):
    """Every knob row but the Monte Carlo's, and every preset, carries the error of the light on
    a horizontal surface; single scattering loses light, which shows as an illuminance error of
    the same sign as its radiance error, and the sky's colour as a colour difference of the light."""
    for r in quick["rows"]:
        if r["knob"] == "mc_samples":
            assert "lighting" not in r
            continue
        light = r["lighting"]
        assert set(light) == {"illuminance_rel", "de2000"}
        assert all(np.isfinite(v) and v >= 0.0 for v in light.values())
    one, conv = _row(quick, "orders", 1), _row(quick, "orders", "tolerance")
    assert one["lighting"]["illuminance_rel"] > 10 * conv["lighting"]["illuminance_rel"]
    assert one["lighting"]["de2000"] > 10 * conv["lighting"]["de2000"]
    # the reference preset is the reference: no error as lighting either
    assert quick["presets"]["reference"]["noon"]["lighting"]["illuminance_rel"] == pytest.approx(0.0, abs=1e-12)
    assert quick["presets"]["final"]["noon"]["lighting"]["illuminance_rel"] > 0.0


def test_lighting_of_the_rgb_shortcut_goes_through_its_own_colours():
    """The irradiance's colour of a 3-wavelength sky is read as its images are (the RGB shortcut):
    the top-of-atmosphere sun at the three wavelengths has the full solar spectrum's XYZ."""
    from skymodel.colorimetry import spectral_to_xyz

    wl3 = np.array(sorted(accuracy.RGB3_WAVELENGTHS_NM))
    e3 = accuracy.base_profile(wl3).solar_irradiance
    full = accuracy.base_profile(default_wavelengths())
    assert np.allclose(accuracy.xyz_of(e3, wl3), spectral_to_xyz(full.solar_irradiance, full.wavelengths_nm))
    assert np.allclose(accuracy.xyz_of(full.solar_irradiance, full.wavelengths_nm),
                       spectral_to_xyz(full.solar_irradiance, full.wavelengths_nm))


def test_band_matrix_averages_the_reference_over_each_band():
    fine, coarse = default_wavelengths(5.0), default_wavelengths(10.0)
    assert np.allclose(accuracy.band_matrix(fine, fine), np.eye(fine.size))
    m = accuracy.band_matrix(coarse, fine)
    assert np.allclose(m.sum(axis=1), 1.0)
    j = int(np.nonzero(fine == 550.0)[0][0])
    i = int(np.nonzero(coarse == 550.0)[0][0])
    assert np.allclose(m[i, j - 1:j + 2], [0.25, 0.5, 0.25])  # trapezoid over 545..555 nm
    # a linear spectrum is kept exactly away from the ends
    lin = 2.0 + 0.01 * fine
    assert np.allclose((m @ lin)[1:-1], 2.0 + 0.01 * coarse[1:-1])


def test_rgb_shortcut_maps_the_solar_spectrum_to_its_own_colour():
    from skymodel.colorimetry import spectral_to_rgb

    wl3 = np.array(sorted(accuracy.RGB3_WAVELENGTHS_NM))
    e3 = accuracy.base_profile(wl3).solar_irradiance
    full = accuracy.base_profile(default_wavelengths())
    assert np.allclose(accuracy.rgb_of(e3, wl3), spectral_to_rgb(full.solar_irradiance, full.wavelengths_nm))
    # twice the light, twice the RGB
    assert np.allclose(accuracy.rgb_of(2 * e3, wl3), 2 * accuracy.rgb_of(e3, wl3))


def test_fitted_phase_keeps_the_asymmetry_and_normalisation():
    from skymodel.numerics import trapezoid
    from skymodel.optics.phase_fit import asymmetry

    prof = accuracy.base_profile(default_wavelengths(100.0))
    assert accuracy.with_fitted_phase(prof, "mie") is prof
    ang = prof.aerosol_phase_angles_deg
    mu = np.cos(np.radians(ang))
    fits = accuracy.phase_fits(prof)
    for kind in ("hg", "dhg"):
        p = accuracy.with_fitted_phase(prof, kind, fits)
        assert p.aerosol_phase.shape == prof.aerosol_phase.shape
        assert not np.allclose(p.aerosol_phase, prof.aerosol_phase)
        for r in range(prof.aerosol_phase.shape[0]):
            if not np.any(prof.aerosol_phase[r] > 0):
                continue
            if kind == "hg":  # HG takes the table's asymmetry parameter as its g
                assert np.allclose(asymmetry(ang, p.aerosol_phase[r]), asymmetry(ang, prof.aerosol_phase[r]),
                                   atol=2e-3)
            norm = -2 * np.pi * trapezoid(p.aerosol_phase[r], mu, axis=0)
            assert np.allclose(norm, 1.0, atol=0.02)
    with pytest.raises(SkymodelInputError, match="phase"):
        accuracy.with_fitted_phase(prof, "rayleigh")


def test_scale_angular_keeps_the_parity_the_solver_needs():
    from skymodel.render.marcher import MarchSettings

    for f in (0.25, 0.5, 0.75, 1.0, 1.5):
        s = accuracy.scale_angular(MarchSettings(), f)
        assert s.table_mu % 2 == 0 and s.grid_azimuth % 2 == 1
    assert accuracy.scale_angular(MarchSettings(), 1.0) == MarchSettings()
    assert accuracy.scale_angular(MarchSettings(), 2.0).grid_zenith == 2 * MarchSettings().grid_zenith
    with pytest.raises(SkymodelInputError, match="angular_grid"):
        accuracy.scale_angular(MarchSettings(), 0.0)


@pytest.mark.parametrize("quality", ["final", "reference"])
def test_scale_angular_keeps_the_horizon_nodes_valid(quality):
    """The presets crowd some zenith nodes at the horizon; every angular_grid factor of the
    benchmark (0.25 takes final's 20 nodes per hemisphere to 5) keeps their count below the
    hemisphere's, so the knob's MarchSettings are valid."""
    from skymodel.render.quality import quality_settings

    base = quality_settings(quality)
    for f in (0.25, 0.5, 0.625, 0.75, 1.0, 1.5):
        s = accuracy.scale_angular(base, f)
        assert 1 <= s.table_mu_horizon_nodes < s.table_mu // 2
        # final runs some orders on every other azimuth: an even count (0.625 x 24 is 15, made 16)
        assert not s.halves_azimuths or s.table_phi % 2 == 0
    assert accuracy.scale_angular(base, 1.0) == base


def test_unknown_knob_or_scene_is_refused():
    cfg = accuracy.quick_config()
    with pytest.raises(SkymodelInputError, match="knob"):
        accuracy.run_benchmark(cfg, knobs=["resolution"], log=lambda m: None)
    with pytest.raises(SkymodelInputError, match="scene"):
        accuracy.run_benchmark(cfg, scenes=["midnight"], log=lambda m: None)


def test_cli_writes_the_table_and_the_markdown(quick, tmp_path, monkeypatch):
    # the references are cached by the quick fixture: only the layers knob renders here
    from skymodel.cli import main

    monkeypatch.setenv("SKYMODEL_CACHE", os.environ.get("SKYMODEL_CACHE", str(tmp_path)))
    md, js = tmp_path / "acc.md", tmp_path / "m.json"
    md.write_text("# Accuracy\n\nprose kept\n")
    assert main(["bench", "accuracy", "--quick", "--knobs", "layers", "--out", str(md), "--json", str(js)]) == 0
    result = json.loads(js.read_text())
    assert {r["knob"] for r in result["rows"]} == {"layers"}
    assert result["command"].startswith("skymodel bench accuracy --quick")
    text = md.read_text()
    assert "prose kept" in text and "| layers | 4 |" in text
    assert (tmp_path / "img" / "accuracy_noon.png").stat().st_size > 1000



def _checked_in_files():
    """The files only --write-docs may change: docs/accuracy.md, its plots and the package's table."""
    import glob

    return [os.path.join(ROOT, "docs", "accuracy.md"), MEASURED] + sorted(
        glob.glob(os.path.join(ROOT, "docs", "img", "accuracy_*.png")))


def _digests(paths):
    import hashlib

    return {p: hashlib.sha256(open(p, "rb").read()).hexdigest() if os.path.exists(p) else None for p in paths}


def test_cli_without_write_docs_leaves_docs_and_package_data_untouched(quick, tmp_path, monkeypatch):
    # no --out/--json: the run writes into ./bench-accuracy-quick/ of the current directory, nowhere else
    from skymodel.cli import main
    from skymodel.cli.bench import QUICK_DIR, checked_in_targets

    monkeypatch.setenv("SKYMODEL_CACHE", os.environ.get("SKYMODEL_CACHE", str(tmp_path / "cache")))
    work = tmp_path / "cwd"
    work.mkdir()
    monkeypatch.chdir(work)
    files = _checked_in_files()
    assert set(checked_in_targets()) == {files[0], os.path.realpath(MEASURED)}
    before = _digests(files)
    assert main(["bench", "accuracy", "--quick", "--knobs", "layers"]) == 0
    assert main(["bench", "accuracy", "--merge", str(work / QUICK_DIR / "measured.json")]) == 0
    assert _digests(files) == before
    assert {p.name for p in work.iterdir()} == {QUICK_DIR, "bench-accuracy"}
    result = json.loads((work / QUICK_DIR / "measured.json").read_text())
    assert {r["knob"] for r in result["rows"]} == {"layers"}
    assert result["command"] == "skymodel bench accuracy --quick --knobs layers"
    assert "| layers | 4 |" in (work / QUICK_DIR / "accuracy.md").read_text()
    assert (work / QUICK_DIR / "img" / "accuracy_noon.png").stat().st_size > 1000
    merged = json.loads((work / "bench-accuracy" / "measured.json").read_text())
    assert merged["rows"] == result["rows"] and merged["command"] == "skymodel bench accuracy"


def test_cli_write_docs_goes_to_the_checked_in_files_only(quick, tmp_path, monkeypatch):
    from skymodel.cli import bench, main

    md, js = tmp_path / "docs" / "accuracy.md", tmp_path / "measured.json"
    md.parent.mkdir()
    md.write_text("# Accuracy\n\nprose kept\n")
    monkeypatch.setattr(bench, "checked_in_targets", lambda: (str(md), str(js)))
    monkeypatch.chdir(tmp_path)
    part = tmp_path / "part.json"
    part.write_text(json.dumps(dict(quick, command="skymodel bench accuracy --quick --json part.json")))
    # the project's files take a full run: not a quick one, and not beside --out/--json
    for extra in (["--quick"], ["--out", str(tmp_path / "x.md")], ["--json", str(tmp_path / "x.json")]):
        assert main(["bench", "accuracy", "--write-docs", *extra]) == 2
    assert not js.exists() and md.read_text() == "# Accuracy\n\nprose kept\n"
    assert main(["bench", "accuracy", "--merge", str(part), "--write-docs"]) == 0
    merged = json.loads(js.read_text())
    assert merged["command"] == "skymodel bench accuracy --write-docs"
    assert "prose kept" in md.read_text() and "    skymodel bench accuracy --write-docs" in md.read_text()
    assert (md.parent / "img" / "accuracy_noon.png").stat().st_size > 1000
    assert not (tmp_path / "bench-accuracy").exists()
    # merging the merged table alone changes nothing: the checked-in doc can be regenerated without rendering
    text = md.read_text()
    assert main(["bench", "accuracy", "--merge", str(js), "--write-docs"]) == 0
    assert json.loads(js.read_text()) == merged and md.read_text() == text

def test_merge_replaces_only_the_rows_remeasured(quick):
    part = dict(quick, rows=[dict(r, time_s=r["time_s"] + 1.0) for r in quick["rows"] if r["knob"] == "orders"],
                presets={}, command="skymodel bench accuracy --quick --knobs orders", total_s=1.0)
    merged = accuracy.merge_results(quick, part)
    assert len(merged["rows"]) == len(quick["rows"])
    for old, new in zip(quick["rows"], merged["rows"]):
        assert (old["knob"], old["value"]) == (new["knob"], new["value"])
        assert new["time_s"] == old["time_s"] + (1.0 if old["knob"] == "orders" else 0.0)
    assert merged["presets"] == quick["presets"]
    assert merged["partial_runs"][-1]["command"].endswith("--knobs orders")
    # a run of another configuration is not merged into this one
    assert accuracy.merge_results(quick, dict(part, config="full"))["config"] == "full"


def test_a_preset_refresh_keeps_every_other_row_and_says_when_each_was_measured(quick):
    """``skymodel bench accuracy --knobs preset --write-docs`` re-measures only the presets'
    rows: the other rows stay as they were, each with the date it was measured (inferred
    from the table's partial runs for rows written before rows carried a date)."""
    old = copy.deepcopy(quick)
    for r in old["rows"]:
        r.pop("date", None)
    for per in old["presets"].values():
        for v in per.values():
            v.pop("date", None)
    old["partial_runs"] = [{"command": "skymodel bench accuracy --quick --knobs orders --scenes noon",
                            "date": "2026-01-01T00:00:00Z", "total_s": 1.0},
                           {"command": "skymodel bench accuracy --quick --knobs preset", "date": "2026-01-02T00:00:00Z",
                            "total_s": 1.0}]
    old["date"] = "2026-01-03T00:00:00Z"
    new = dict(copy.deepcopy(quick), rows=[dict(r, time_s=0.5, date="2026-02-01T00:00:00Z")
                                           for r in quick["rows"] if r["knob"] == "preset"],
               command="skymodel bench accuracy --quick --knobs preset", total_s=1.0, date="2026-02-01T00:00:00Z",
               atmosphere=dict(quick["atmosphere"], aerosol_model="another"))
    merged = accuracy.merge_results(old, new)
    # the rows kept are the old atmosphere's; the part measured in another says so
    assert merged["atmosphere"] == old["atmosphere"]
    assert merged["partial_runs"][-1]["atmosphere"]["aerosol_model"] == "another"
    from skymodel.validation.accuracy_report import _run_atmosphere

    assert "aerosol model another" in _run_atmosphere(merged["partial_runs"][-1])
    by_knob = {}
    for r in merged["rows"]:
        by_knob.setdefault(r["knob"], set()).add(r["date"])
    assert by_knob["orders"] == {"2026-01-01T00:00:00Z"}  # its partial run
    assert by_knob["preset"] == {"2026-02-01T00:00:00Z"}
    assert by_knob["phase"] == {"2026-01-03T00:00:00Z"}  # no run names it: the table's date
    assert [r["time_s"] for r in merged["rows"] if r["knob"] == "orders"] == \
        [r["time_s"] for r in quick["rows"] if r["knob"] == "orders"]
    assert all(r["time_s"] == 0.5 for r in merged["rows"] if r["knob"] == "preset")
    assert accuracy.row_date(merged, "noon", "orders") == "2026-01-01T00:00:00Z"
    # the orders' run still holds rows and stays listed; the earlier presets' run holds none: dropped
    assert [r["date"] for r in merged["partial_runs"]] == ["2026-01-01T00:00:00Z", "2026-02-01T00:00:00Z"]


def test_a_table_remeasured_row_by_row_in_another_atmosphere_becomes_that_atmospheres():
    """Runs whose rows were all replaced leave the table's list of runs, and once every row
    was measured again in another atmosphere the table says that atmosphere is its own."""
    def part(knobs, date, atmosphere):
        rows = [{"scene": "noon", "knob": k, "value": 1, "time_s": 1.0, "date": date} for k in knobs]
        return {"config": "quick", "camera": {"width": 32}, "scenes": {"noon": {}}, "rows": rows, "presets": {},
                "machine": "m", "date": date, "load_avg_end": [0.0], "reference_settings": {},
                "baseline_settings": {}, "atmosphere": atmosphere, "total_s": 10.0,
                "command": "skymodel bench accuracy --knobs " + ",".join(knobs)}

    old = part(["orders", "layers"], "2026-01-01T00:00:00Z", {"aerosol_model": "opac"})
    old["partial_runs"] = [{"command": old["command"], "date": old["date"], "total_s": 10.0}]
    paper = {"aerosol_model": "guimera2018"}
    half = accuracy.merge_results(old, part(["orders"], "2026-02-01T00:00:00Z", paper))
    assert half["atmosphere"] == {"aerosol_model": "opac"}  # the layers row is still the old model's
    assert [r.get("atmosphere") for r in half["partial_runs"]] == [None, paper]
    full = accuracy.merge_results(half, part(["layers"], "2026-03-01T00:00:00Z", paper))
    assert full["atmosphere"] == paper
    assert [r["date"] for r in full["partial_runs"]] == ["2026-02-01T00:00:00Z", "2026-03-01T00:00:00Z"]
    assert all("atmosphere" not in r for r in full["partial_runs"]) and full["total_s"] == 20.0


def test_cli_merges_parts_measured_in_parallel(quick, tmp_path):
    # two parts as two processes would write them: the orders rows, then the presets
    from skymodel.cli import main

    orders = dict(quick, rows=[r for r in quick["rows"] if r["knob"] == "orders"], presets={}, total_s=2.0,
                  command="skymodel bench accuracy --quick --knobs orders --json a.json")
    presets = dict(quick, rows=[r for r in quick["rows"] if r["knob"] == "preset"], total_s=3.0,
                   command="skymodel bench accuracy --quick --knobs preset --json b.json")
    paths = []
    for name, part in (("a.json", orders), ("b.json", presets)):
        (tmp_path / name).write_text(json.dumps(part))
        paths.append(str(tmp_path / name))
    md, js = tmp_path / "acc.md", tmp_path / "m.json"
    assert main(["bench", "accuracy", "--merge", *paths, "--out", str(md), "--json", str(js)]) == 0
    merged = json.loads(js.read_text())
    assert {r["knob"] for r in merged["rows"]} == {"orders", "preset"}
    assert merged["presets"] == quick["presets"]
    assert [r["command"] for r in merged["partial_runs"]] == [orders["command"], presets["command"]]
    assert merged["total_s"] == 5.0 and merged["command"] == "skymodel bench accuracy"
    assert "measured in parts: `skymodel bench accuracy --quick --knobs orders" in md.read_text()
    # a part of another configuration is refused with a message, and nothing is written
    (tmp_path / "c.json").write_text(json.dumps(dict(presets, config="full")))
    js.unlink()
    assert main(["bench", "accuracy", "--merge", paths[0], str(tmp_path / "c.json"), "--json", str(js),
                 "--out", str(md)]) == 2
    assert not js.exists()


def test_checked_in_measured_table_covers_every_knob_and_scene():
    with open(MEASURED, encoding="utf-8") as f:
        result = json.load(f)
    _check_schema(result)
    assert set(result["scenes"]) == {"noon", "sunset5", "twilight"}
    assert result["camera"] == {"kind": "equirectangular", "width": 128, "height": 64}
    want = {"wavelengths": {81, 41, 21, 11, "rgb3"}, "orders": set(range(1, 9)) | {"tolerance"},
            "layers": {4, 8, 16, 32, 64, "smooth"}, "phase": {"mie", "hg", "dhg"},
            "geometry": {"columns0", "columns1", "columns2", "columns3", "columns20", "no-aureole"},
            "preset": {"preview", "final", "reference"}}
    for scene in result["scenes"]:
        for knob in accuracy.KNOBS:
            values = {r["value"] for r in result["rows"] if r["scene"] == scene and r["knob"] == knob}
            assert values, (scene, knob)
            if knob in want:
                assert values == want[knob], (scene, knob)
    for scene in result["scenes"]:
        for name in ("preview", "final", "reference"):
            entry = result["presets"][name][scene]
            assert (entry["width"], entry["height"]) == (512, 256)
        assert result["presets"]["reference"][scene]["radiance_rel_mean"] == 0.0
        # the presets are ordered in error: reference (0) < final < preview
        assert 0.0 < result["presets"]["final"][scene]["radiance_rel_mean"] < \
            result["presets"]["preview"][scene]["radiance_rel_mean"]
    # the rows the planner reads carry the errors it prices: by view band and as lighting
    for r in result["rows"]:
        if r["knob"] in ("wavelengths", "orders", "layers"):
            assert {"horizon", "low", "high"} <= set(r["bands"]) and set(r["lighting"]) == {"illuminance_rel", "de2000"}, r
    # ... and the layers rows are the add-on's shells (skymodel.optics.shells): at twilight its floor of
    # 16 carries the light within 1 dE2000 (shells of equal optical depth: 10.9, and 108 % of the illuminance)
    from skymodel.optics.shells import TWILIGHT_MIN_LAYERS

    floor = next(r for r in result["rows"] if r["scene"] == "twilight" and r["knob"] == "layers"
                 and r["value"] == TWILIGHT_MIN_LAYERS)
    assert floor["lighting"]["de2000"] < 1.0 and floor["lighting"]["illuminance_rel"] < 0.05


def test_cache_key_changes_with_the_renderer(tmp_path, monkeypatch):
    """code_digest hashes every module of the package, so a renderer change renders the
    cached references and presets again (it hashed skymodel/validation alone before)."""
    pkg = tmp_path / "skymodel"
    (pkg / "validation").mkdir(parents=True)
    (pkg / "render").mkdir()
    (pkg / "validation" / "accuracy.py").write_text("x = 1\n")
    (pkg / "render" / "marcher.py").write_text("y = 1\n")
    monkeypatch.setattr(accuracy, "__file__", str(pkg / "validation" / "accuracy.py"))
    before = accuracy.code_digest()
    (pkg / "render" / "marcher.py").write_text("y = 2\n")
    assert accuracy.code_digest() != before
