"""The effect planner (skymodel/planner.py): the three examples of issue 5, tolerance
monotonicity, validation, reasons, and that the predictions come from the measured tables
(skymodel/data/presets/planner/effects.json; the accuracy table's schema via tests/data)."""

import copy
import json
import os

import numpy as np
import pytest

from skymodel.errors import SkymodelInputError
from skymodel.planner import (EFFECT_NAMES, EFFECTS_PATH, PHYSICAL, CameraView, SceneDescription, load_table,
                              plan)

FIXTURE = os.path.join(os.path.dirname(__file__), "data", "accuracy_measured_fixture.json")


@pytest.fixture(scope="module")
def effects():
    table = load_table(EFFECTS_PATH)
    assert table is not None, "skymodel/data/presets/planner/effects.json is missing (benchmarks/bench_planner.py --write)"
    return table


@pytest.fixture(scope="module")
def accuracy():
    with open(FIXTURE, encoding="utf-8") as f:
        return json.load(f)


def product_shot(tolerance=5.0, **kw):
    args = dict(cameras=[CameraView(altitude_m=1.7, view_directions=[(0.0, 1.0, -0.1)], fov_deg=40.0)],
                sun_elevation_deg=60.0, farthest_object_m=200.0, image_width=1920, image_height=1080,
                tolerance=tolerance)
    args.update(kw)
    return SceneDescription(**args)


def landscape(tolerance=2.0, **kw):
    args = dict(cameras=[CameraView(altitude_m=1.7, view_directions=[(0.0, 1.0, 0.05)], fov_deg=60.0)],
                sun_elevation_deg=5.0, farthest_object_m=30_000.0, tolerance=tolerance)
    args.update(kw)
    return SceneDescription(**args)


def twilight(tolerance=2.0, **kw):
    args = dict(cameras=[CameraView(min_elevation_deg=0.0, max_elevation_deg=90.0, fov_deg=180.0)],
                sun_elevation_deg=-4.0, farthest_object_m=0.0, tolerance=tolerance)
    args.update(kw)
    return SceneDescription(**args)


# --------------------------------------------------------------------------- the examples


def test_product_shot_at_noon_is_environment_only_without_ozone_and_coarse_spectrum(effects):
    p = plan(product_shot(), effects=effects, accuracy=None)
    assert p.mode == "environment"
    assert not p["aerial_perspective"].on and p.n_layers is None
    assert not p["ozone"].on
    assert "ozone" in p["ozone"].reason and "60" in p["ozone"].reason
    assert p.wavelength_step_nm > 10.0  # coarser than the reference grid
    assert p.predicted_error <= 5.0


def test_landscape_with_far_mountains_at_low_sun_gets_shells_scattering_and_ozone(effects):
    p = plan(landscape(), effects=effects, accuracy=None)
    assert p.mode == "volumetric"
    ap = p["aerial_perspective"]
    assert ap.on and ap.value["n_layers"] >= 1
    lo, hi = ap.value["altitude_range_m"]
    assert lo == 0.0 and hi > 10_000.0
    assert "30 km" in ap.reason
    assert p["multiple_scattering"].on and p.orders != 1
    assert p["ozone"].on


def test_twilight_sky_only_needs_shadow_ozone_and_high_orders_but_no_shells(effects):
    p = plan(twilight(), effects=effects, accuracy=None)
    assert p.mode == "environment" and not p["aerial_perspective"].on
    assert p["earth_shadow"].on
    assert p["ozone"].on and "twilight" in p["ozone"].reason
    assert p["multiple_scattering"].on
    assert p.orders is None or p.orders >= 4
    assert not p["sun_disc"].on  # the sun is below the horizon


def test_ozone_is_kept_when_the_tolerance_is_below_its_measured_effect(effects):
    loose = plan(product_shot(tolerance=5.0), effects=effects, accuracy=None)
    tight = plan(product_shot(tolerance=0.5), effects=effects, accuracy=None)
    assert not loose["ozone"].on and tight["ozone"].on
    # the error the planner quotes for leaving ozone out is larger than the tight budget
    assert loose["ozone"].predicted_error > 0.25


# --------------------------------------------------------------------------- behaviour


@pytest.mark.parametrize("make", [product_shot, landscape, twilight])
def test_tighter_tolerance_turns_more_on(effects, make):
    prev = None
    for tol in (20.0, 10.0, 5.0, 2.0, 1.0, 0.5, 0.2):
        p = plan(make(tolerance=tol), effects=effects, accuracy=None)
        on = {k for k in PHYSICAL if p[k].on}
        orders = 99 if p.orders is None else p.orders
        state = (on, orders, p.wavelength_step_nm, p["aerial_perspective"].on)
        if prev is not None:
            assert prev[0] <= on, f"tolerance {tol}: an effect went off as the tolerance tightened"
            assert orders >= prev[1]
            assert p.wavelength_step_nm <= prev[2]
            assert p["aerial_perspective"].on >= prev[3]
        # within the tolerance, unless even the most layers measured do not fit (then said so)
        assert p.predicted_error <= tol + 1e-9 or "exceeds" in p["aerial_perspective"].reason
        prev = state


def test_every_decision_has_a_one_sentence_reason(effects):
    for make in (product_shot, landscape, twilight):
        p = plan(make(), effects=effects, accuracy=None)
        assert tuple(p.decisions) == EFFECT_NAMES
        for d in p:
            assert isinstance(d.reason, str) and len(d.reason) > 20
            assert ". " not in d.reason and "\n" not in d.reason
            assert d.predicted_error >= 0.0
        assert len(p.summary()) == len(EFFECT_NAMES)


def test_farther_objects_need_shells(effects):
    near = plan(landscape(farthest_object_m=10.0, sun_elevation_deg=60.0), effects=effects, accuracy=None)
    far = plan(landscape(farthest_object_m=100_000.0, sun_elevation_deg=60.0), effects=effects, accuracy=None)
    assert not near["aerial_perspective"].on and far["aerial_perspective"].on


def test_sky_seen_only_as_lighting_gets_a_small_environment(effects):
    seen = plan(product_shot(), effects=effects, accuracy=None)
    lit = plan(product_shot(sky_visible=False), effects=effects, accuracy=None)
    assert lit.environment_width < seen.environment_width
    assert not lit["sun_disc"].on


def test_overrides_are_honoured(effects):
    p = plan(product_shot(), effects=effects, accuracy=None, overrides={"ozone": True, "aerial_perspective": True,
                                                                         "n_layers": 6})
    assert p["ozone"].on and p["ozone"].reason.startswith("set by the user")
    assert p.mode == "volumetric" and p.n_layers == 6
    q = plan(landscape(), effects=effects, accuracy=None, overrides={"aerial_perspective": False,
                                                                     "multiple_scattering": False})
    assert q.mode == "environment" and q.orders == 1 and not q["multiple_scattering"].on
    t = plan(twilight(), effects=effects, accuracy=None, overrides={"sun_disc": True})
    assert t["sun_disc"].on and t["sun_disc"].reason.startswith("set by the user") and "drawn" in t["sun_disc"].reason
    # the user's choice costs its measured error
    assert q.predicted_error > plan(landscape(), effects=effects, accuracy=None).predicted_error


def test_plan_applies_to_atmosphere_and_settings(effects):
    from skymodel import Atmosphere
    from skymodel.planner import NO_OZONE_DU

    p = plan(product_shot(), effects=effects, accuracy=None)
    assert not p["ozone"].on and p.atmosphere_changes() == {"ozone_du": NO_OZONE_DU}
    atm = Atmosphere(location="rural", month=6)
    wl = [450.0, 550.0, 650.0]
    prof, out = atm.optical_profile(wl), p.apply_to_atmosphere(atm).optical_profile(wl)
    assert np.all(out.ozone_absorption <= 1e-8 * prof.ozone_absorption.max()) and np.any(prof.ozone_absorption)
    assert np.array_equal(out.rayleigh_scattering, prof.rayleigh_scattering)
    assert np.array_equal(out.aerosol_scattering_by_regime, prof.aerosol_scattering_by_regime)
    # everything left out: no aerosol of any kind, no ground reflection
    off = plan(product_shot(), effects=effects, accuracy=None,
               overrides={"aerosols": False, "ozone": False, "ground_reflection": False})
    bare = off.apply_to_atmosphere(atm).optical_profile(wl)
    assert not np.any(bare.aerosol_scattering_by_regime) and not np.any(bare.aerosol_absorption)
    assert not np.any(bare.ground_albedo)
    everything = plan(product_shot(), effects=effects, accuracy=None, overrides={k: True for k in PHYSICAL})
    assert everything.apply_to_atmosphere(atm) is atm
    s = p.march_settings()
    assert s.orders == p.orders and s.earth_shadow == p["earth_shadow"].on


# --------------------------------------------------------------------------- from the tables


def _scale_effect(table, effect, factor, key_filter=None):
    t = copy.deepcopy(table)
    for row in t["rows"]:
        e = row["effects"][effect]
        for band in e["sky"].values():
            for k in band:
                band[k] *= factor
        for k in e["lighting"]:
            e["lighting"][k] *= factor
    return t


def test_predictions_follow_the_effect_table(effects):
    base = plan(product_shot(tolerance=1.0), effects=effects, accuracy=None)
    assert base["ozone"].on
    cheap_ozone = _scale_effect(effects, "ozone_off", 0.001)
    p = plan(product_shot(tolerance=1.0), effects=cheap_ozone, accuracy=None)
    assert not p["ozone"].on
    assert p["ozone"].predicted_error == pytest.approx(base_err := _ozone_err(effects, 60.0) * 0.001, rel=1e-6)
    assert base_err > 0
    # times: double every measured time, the predictions double
    slow = copy.deepcopy(effects)
    for row in slow["rows"]:
        row["reference"]["time_s"] *= 2
        for e in row["effects"].values():
            e["time_s"] *= 2
    q = plan(product_shot(), effects=slow, accuracy=None)
    r = plan(product_shot(), effects=effects, accuracy=None)
    assert q.predicted_time_everything_s == pytest.approx(2 * r.predicted_time_everything_s)
    assert q.predicted_time_s == pytest.approx(2 * r.predicted_time_s)


def _ozone_err(table, el):
    """The product shot's ozone error straight from the table (worst visible band or lighting)."""
    rows = sorted(table["rows"], key=lambda r: r["sun_elevation_deg"])
    x = [r["sun_elevation_deg"] for r in rows]
    scene = product_shot()
    lo, hi = scene.elevation_range_deg
    from skymodel.planner import BANDS_DEG

    bands = [b for b, (a, z) in BANDS_DEG.items() if hi > a and lo < z]
    y = [max([r["effects"]["ozone_off"]["lighting"]["de2000"]]
             + [r["effects"]["ozone_off"]["sky"][b]["de2000_mean"] for b in bands]) for r in rows]
    return float(np.interp(el, x, y))


def test_predictions_follow_the_accuracy_table(effects, accuracy):
    scene = landscape(sun_elevation_deg=32.5, farthest_object_m=0.0, tolerance=1.0)
    p = plan(scene, effects=effects, accuracy=accuracy)
    # time scale: the fixture's 'final' preset, interpolated between sunset5 (5 deg) and noon (60 deg)
    final = accuracy["presets"]["final"]
    expected = np.interp(32.5, [5.0, 60.0], [final["sunset5"]["time_s"], final["noon"]["time_s"]])
    assert p.predicted_time_everything_s == pytest.approx(expected)
    assert "accuracy table" in p.time_basis
    changed = copy.deepcopy(accuracy)
    for r in changed["rows"]:
        if r["knob"] == "wavelengths" and r["value"] in (11, 21, 41):
            r["de2000_mean"] += 50.0  # every coarse grid now far off
    q = plan(scene, effects=effects, accuracy=changed)
    assert q.wavelength_step_nm < p.wavelength_step_nm or p.wavelength_step_nm == 5.0
    assert q.wavelength_step_nm == 5.0 and "measured.json wavelengths=81" in q["spectral_resolution"].source
    faster = copy.deepcopy(accuracy)
    for v in faster["presets"]["final"].values():
        v["time_s"] /= 4
    assert plan(scene, effects=effects, accuracy=faster).predicted_time_everything_s == pytest.approx(expected / 4)


def test_knob_errors_are_those_of_the_bands_the_cameras_see(effects, accuracy):
    """A coarse spectral grid that misses only near the horizon is priced at its horizon band's
    error for a camera that sees the horizon, at the high sky's for one looking up, and at the
    whole sky's for a sky seen only as lighting; rows measured without bands keep the whole sky's."""
    from skymodel.planner import decisions
    from skymodel.planner.tables import _AccuracyTable

    banded = copy.deepcopy(accuracy)
    for r in banded["rows"]:
        r.pop("lighting", None)  # the whole sky's error stands in for the light (rows before 2026-11-29)
        if r["knob"] == "wavelengths" and r["value"] == 11:
            r["bands"] = {"horizon": {"de2000_mean": r["de2000_mean"] + 3.0},
                          "low": {"de2000_mean": r["de2000_mean"]}, "high": {"de2000_mean": 0.0}}
    table = _AccuracyTable(banded)
    whole = table.knob("wavelengths", 20.0, "de2000_mean")[11][0]
    assert table.knob("wavelengths", 20.0, "de2000_mean", ["horizon", "low"])[11][0] == pytest.approx(whole + 3.0)
    assert table.knob("wavelengths", 20.0, "de2000_mean", ["high"])[11][0] == pytest.approx(whole)
    assert table.knob("wavelengths", 20.0, "de2000_mean", ["ground"])[11][0] == pytest.approx(whole)  # not measured
    assert table.knob("wavelengths", 20.0, "de2000_mean", ["horizon"])[41][0] == pytest.approx(
        table.knob("wavelengths", 20.0, "de2000_mean")[41][0])  # a row without bands
    sees_horizon = landscape(sun_elevation_deg=20.0, farthest_object_m=0.0)
    looks_up = landscape(sun_elevation_deg=20.0, farthest_object_m=0.0,
                         cameras=[CameraView(altitude_m=1.7, view_directions=[(0.0, 0.3, 1.0)], fov_deg=30.0)])
    lighting = landscape(sun_elevation_deg=20.0, farthest_object_m=0.0, sky_visible=False)
    steps = {}
    for name, scene in (("horizon", sees_horizon), ("up", looks_up), ("lighting", lighting)):
        p = plan(scene, effects=effects, accuracy=banded)
        ctx = decisions._Planning(scene, {}, *decisions.read_tables(effects, banded), unit="dE2000",
                                  acc_metric="de2000_mean", light_metric="de2000", t_ref=1.0, where="sky")
        steps[name] = decisions.spectral_step_options(ctx)[40.0][0]
        assert p["spectral_resolution"].value != 40.0 or steps[name] <= 0.1 * scene.tolerance
    assert steps["horizon"] == pytest.approx(whole + 3.0)
    assert steps["up"] == pytest.approx(whole) and steps["lighting"] == pytest.approx(whole)


def test_knob_errors_as_lighting_are_the_lights_not_the_whole_skys(effects, accuracy):
    """Where a knob row carries its error as lighting (the irradiance on a horizontal surface),
    a sky seen only as lighting is priced at that error, not at the whole sky's image error; a
    camera that sees the horizon pays the worse of the light's and the horizon band's; a plan
    for lighting takes a coarse grid that the whole sky's error would have refused."""
    from skymodel.planner.tables import _AccuracyTable

    lit = copy.deepcopy(accuracy)
    for r in lit["rows"]:
        if r["knob"] == "wavelengths":
            r["de2000_mean"] = 5.0 if r["value"] != 81 else 0.0  # every coarse grid far off in the image
            r["radiance_rel_rms"] = 0.5 if r["value"] != 81 else 0.0
            r["lighting"] = {"de2000": 0.01 if r["value"] != 81 else 0.0, "illuminance_rel": 0.001}
            r["bands"] = {"horizon": {"de2000_mean": 7.0, "radiance_rel_rms": 0.7},
                          "high": {"de2000_mean": 0.02, "radiance_rel_rms": 0.002}}
    table = _AccuracyTable(lit)
    assert table.knob("wavelengths", 20.0, "de2000_mean", [], "de2000")[11][0] == pytest.approx(0.01)
    assert table.knob("wavelengths", 20.0, "de2000_mean", [])[11][0] == pytest.approx(5.0)  # no light metric asked
    assert table.knob("wavelengths", 20.0, "de2000_mean", ["high"], "de2000")[11][0] == pytest.approx(0.02)
    assert table.knob("wavelengths", 20.0, "de2000_mean", ["horizon", "high"], "de2000")[11][0] == pytest.approx(7.0)
    assert table.knob("wavelengths", 20.0, "radiance_rel_rms", [], "illuminance_rel")[11][0] == pytest.approx(0.001)
    lighting = landscape(sun_elevation_deg=20.0, farthest_object_m=0.0, sky_visible=False)
    seen = landscape(sun_elevation_deg=20.0, farthest_object_m=0.0)
    assert plan(lighting, effects=effects, accuracy=lit).wavelength_step_nm == 40.0
    assert plan(seen, effects=effects, accuracy=lit).wavelength_step_nm < 40.0


def test_the_accuracy_table_in_presets_is_read_by_default(effects):
    """With skymodel/data/presets/accuracy/measured.json present, a plan prices its spectral grid against the
    5 nm build from that table (the effect table's own reference is 10 nm, so it could not)."""
    from skymodel.planner import ACCURACY_PATH

    acc = load_table(ACCURACY_PATH)
    if acc is None:
        pytest.skip("skymodel/data/presets/accuracy/measured.json is absent (skymodel bench accuracy)")
    for make in (product_shot, landscape, twilight):
        p = plan(make(), effects=effects)
        assert "accuracy table" in p.time_basis
        spec = p["spectral_resolution"]
        assert spec.source.startswith("measured.json wavelengths=")
        assert spec.predicted_error > 0.0  # even a 10 nm grid: its difference to 5 nm is counted
        assert plan(make(), effects=effects, accuracy=None)["spectral_resolution"].source.startswith("effects.json")


def test_missing_accuracy_table_falls_back_to_the_effect_table(effects, tmp_path):
    p = plan(twilight(), effects=effects, accuracy=str(tmp_path / "absent.json"))
    assert "effect table" in p.time_basis
    with pytest.raises(SkymodelInputError) as ex:
        plan(twilight(), effects=str(tmp_path / "absent.json"))
    assert ex.value.parameter == "effects"


# --------------------------------------------------------------------------- validation


@pytest.mark.parametrize("kwargs, parameter", [
    (dict(sun_elevation_deg=-20.0), "sun_elevation_deg"),
    (dict(sun_elevation_deg=float("nan")), "sun_elevation_deg"),
    (dict(farthest_object_m=-1.0), "farthest_object_m"),
    (dict(tolerance=0.0), "tolerance"),
    (dict(tolerance_kind="psnr"), "tolerance_kind"),
    (dict(tolerance_kind="radiance_rel", tolerance=2.0), "tolerance"),
    (dict(image_width=0), "image_width"),
    (dict(image_height=10.5), "image_height"),
    (dict(cameras=[]), "cameras"),
    (dict(cameras=[{"altitude_m": -3.0}]), "altitude_m"),
    (dict(cameras=[{"min_elevation_deg": 40.0, "max_elevation_deg": 10.0}]), "min_elevation_deg"),
    (dict(cameras=[{"view_directions": [(0.0, 0.0, 0.0)]}]), "view_directions"),
    (dict(cameras=[{"fov_deg": 0.0}]), "fov_deg"),
    (dict(cameras=[{"lens_mm": 50}]), "cameras"),
])
def test_bad_scene_is_refused_naming_the_parameter(kwargs, parameter):
    with pytest.raises(SkymodelInputError) as ex:
        SceneDescription(**kwargs)
    assert ex.value.parameter == parameter
    assert ex.value.allowed


@pytest.mark.parametrize("overrides, parameter", [
    ({"clouds": True}, "overrides"), ({"ozone": "yes"}, "ozone"), ({"n_layers": 99}, "n_layers"),
])
def test_bad_overrides_are_refused(effects, overrides, parameter):
    with pytest.raises(SkymodelInputError) as ex:
        plan(product_shot(), effects=effects, accuracy=None, overrides=overrides)
    assert ex.value.parameter == parameter


def test_camera_view_range_from_directions():
    c = CameraView(view_directions=[(0.0, 1.0, 0.0)], fov_deg=40.0)
    assert (c.min_elevation_deg, c.max_elevation_deg) == pytest.approx((-20.0, 20.0))
    up = CameraView(view_directions=[(0.0, 0.0, 1.0)], fov_deg=90.0)
    assert up.max_elevation_deg == 90.0 and up.min_elevation_deg == pytest.approx(45.0)


def test_marcher_switch_for_the_earths_shadow():
    """MarchSettings(earth_shadow=False), used to measure the shadow's effect: no change with
    the sun high, a brighter sky in twilight (points in the shadow receive light)."""
    from dataclasses import replace

    from skymodel import Atmosphere
    from skymodel.render.marcher import SkyMarcher
    from skymodel.render.sky import QUALITY

    prof = Atmosphere(location="rural", month=6).optical_profile([450.0, 550.0, 650.0])
    fast = replace(QUALITY["preview"], exact=True, table_altitudes=8, table_mu=8, table_phi=4, table_mus=8,
                   table_steps=16, sun_table_altitudes=32, sun_table_x=48, sun_table_steps=48, view_steps=24)
    dirs = np.array([[0.0, 0.0, 1.0], [0.0, -0.9, 0.2], [0.0, 0.9, 0.2]])
    out = {}
    for el in (30.0, -5.0):
        for shadow in (True, False):
            m = SkyMarcher(prof, el, 180.0, 0.0, replace(fast, earth_shadow=shadow, orders=2))
            out[el, shadow] = m.radiance(dirs).radiance
            if not shadow:
                assert np.all(m.sun_table.visible_fraction(np.array([0.0, 1000.0]), np.array([-0.5, -0.1])) == 1.0)
    # not bit-identical: the field's sun-angle interpolation is a cubic spline in log J,
    # whose slopes feel (weakly) the nodes with the sun below the horizon, which the
    # switch changes (0.04 % here, with 8 sun nodes)
    np.testing.assert_allclose(out[30.0, False], out[30.0, True], rtol=1e-3)
    assert np.all(out[-5.0, False] >= out[-5.0, True] * (1 - 1e-9))
    assert np.any(out[-5.0, False] > out[-5.0, True] * 1.05)


def test_the_effect_tables_shells_are_the_add_ons(effects):
    """The effect table's layers_N rows are measured on the shells the add-on builds
    (skymodel.optics.shells): with the sun 4 degrees down its twilight floor of layers carries
    the light within 1 dE2000 and the high sky within 2 (shells of equal optical depth, measured
    until 2026-11-29: 11.1 and 11.9), so a twilight scene with near objects plans within its tolerance."""
    from skymodel.optics.shells import TWILIGHT_MIN_LAYERS

    row = next(r for r in effects["rows"] if r["sun_elevation_deg"] == -4.0)
    shells = row["effects"][f"layers_{TWILIGHT_MIN_LAYERS}"]
    assert shells["lighting"]["de2000"] < 1.0 and shells["sky"]["high"]["de2000_mean"] < 2.0
    near = SceneDescription(cameras=[CameraView(altitude_m=1.7, view_directions=[(0.0, 1.0, 0.0)], fov_deg=60.0)],
                            sun_elevation_deg=-4.0, farthest_object_m=30.0, sky_visible=False, tolerance=2.0)
    p = plan(near, effects=effects)
    assert p.n_layers is not None and p.n_layers >= TWILIGHT_MIN_LAYERS and p.within_tolerance
