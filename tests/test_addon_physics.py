"""The add-on's computations that need no Blender: parameters, colour scale, exposure,
volume layering and tessellation."""

import math

import numpy as np
import pytest

from blender_addon import physics, volumetric
from skymodel.errors import SkymodelInputError


def test_resolve_validates_through_the_core():
    plan = physics.resolve(physics.SkyParams(location="desert", month=1, sun_elevation_deg=5, sun_azimuth_deg=-90))
    assert plan.atmosphere.aerosol == "desert" and plan.sun_azimuth_deg == pytest.approx(270.0)
    with pytest.raises(SkymodelInputError) as e:
        physics.resolve(physics.SkyParams(time_utc=(2026, 2, 30, 12, 0)))
    assert e.value.parameter == "day"
    with pytest.raises(SkymodelInputError) as e:
        physics.resolve(physics.SkyParams(sun_elevation_deg=-20))
    assert e.value.parameter == "sun_elevation"
    with pytest.raises(SkymodelInputError) as e:
        physics.resolve(physics.SkyParams(location="atlantis"))
    assert e.value.parameter == "location"


def test_time_places_the_sun_and_sets_the_month():
    plan = physics.resolve(physics.SkyParams(location="zaragoza", month=1, time_utc=(2026, 6, 21, 12, 0)))
    assert plan.atmosphere.month == 6
    assert 60 < plan.sun_elevation_deg < 75 and 150 < plan.sun_azimuth_deg < 200
    assert plan.sun_angular_diameter_deg() == pytest.approx(0.524, abs=0.003)  # aphelion


def test_cache_key_changes_with_every_input():
    base = physics.SkyParams(location="rural")
    k0 = physics.cache_key(physics.resolve(base), "environment", width=64)
    assert k0 == physics.cache_key(physics.resolve(base), "environment", width=64)
    for change in ({"month": 7}, {"sun_elevation_deg": 24.0}, {"aod550": 0.3}, {"albedo": 0.5},
                   {"quality": "final"}, {"ozone_du": 250.0}):
        p = physics.SkyParams(**{**base.__dict__, **change})
        assert physics.cache_key(physics.resolve(p), "environment", width=64) != k0, change
    assert physics.cache_key(physics.resolve(base), "environment", width=128) != k0


def test_gamut_fit_keeps_luminance():
    rgb = np.array([[-0.1, 0.5, 1.0], [0.2, 0.3, 0.4], [1.0, -0.5, 0.2]])
    out = physics.fit_into_gamut(rgb)
    assert np.all(out >= 0)
    assert np.allclose(out @ physics.LUMA_709, np.maximum(rgb @ physics.LUMA_709, 0))
    assert np.allclose(out[1], rgb[1])


def test_sun_lamp_scale_is_ybar_weighted_irradiance():
    from skymodel import colorimetry, sun
    from skymodel.wavelengths import default_wavelengths

    wl = default_wavelengths(5.0)
    e = sun.solar_irradiance(wl)
    strength, colour = physics.sun_lamp(e, wl)
    y = float(colorimetry.spectral_to_xyz(e, wl)[1])
    assert strength == pytest.approx(y, rel=1e-4)  # Blender's rounded Rec.709 luminance weights
    assert 180 < strength < 195  # ~128 klx / 683 lm/W above the atmosphere
    assert np.dot(colour, physics.LUMA_709) == pytest.approx(1.0)


def test_exposure_rule_puts_a_white_plate_at_one():
    from skymodel.render.cameras import make_camera

    cam = make_camera("equirectangular", 64, center_azimuth_deg=90.0)
    L = 3.0  # uniform sky radiance (Y); E_h = pi L; a white plate then has radiance L
    rgb = np.full(cam.shape + (3,), L)
    e_h = physics.horizontal_illuminance(rgb, cam, 0.0, 10.0)
    assert e_h == pytest.approx(math.pi * L, rel=2e-3)
    ev = physics.exposure_from_illuminance(e_h)
    assert L * 2**ev == pytest.approx(1.0, rel=2e-3)
    assert physics.horizontal_illuminance(rgb * 0, cam, 100.0, 30.0) == pytest.approx(50.0)


def test_balls_and_shells_rebuild_every_layer():
    rng = np.random.default_rng(3)
    c = np.abs(rng.normal(size=(9, 3))) * np.linspace(3, 1, 9)[:, None]
    c[6] += 2.0  # a stratospheric bump
    b, rest = volumetric.split_monotone(c)
    d = volumetric.differences(b)
    assert np.all(d >= 0) and np.all(rest >= 0)
    inside = np.cumsum(d[::-1], axis=0)[::-1]  # layer i lies inside balls i..N-1
    assert np.allclose(inside + rest, c)


def test_rgb_projection_weights():
    from skymodel import sun
    from skymodel.wavelengths import default_wavelengths

    wl = default_wavelengths(10.0)
    w = volumetric.rgb_weights(wl, sun.solar_irradiance(wl))
    assert np.allclose(w.sum(axis=0), 1.0)
    assert np.allclose(volumetric.project(np.full(wl.size, 2e-5), w), 2e-5)
    ray = volumetric.project((wl / 550.0) ** -4, w)
    assert ray[2] > ray[1] > ray[0] > 0  # blue scatters most


def test_tessellation_sag_is_sub_metre_near_the_camera():
    r = volumetric.sag_report()
    assert r["sag_at_0km_m"] <= 0.5 and r["sag_at_5km_m"] <= 0.5
    assert r["sag_at_100km_m"] <= 12.0
    assert r["faces"] < 60_000
    R = 6_360_000.0
    th = volumetric.ring_angles(R)
    verts, top, quads, bot = volumetric.sphere_arrays(R + 1000.0, -R, th)
    assert np.allclose(np.linalg.norm(verts - [0, 0, -R], axis=1), R + 1000.0)
    assert verts[0].tolist() == [0.0, 0.0, 1000.0]  # the pole right above the camera
    n = top.shape[0] + quads.shape[0] + bot.shape[0]
    assert n == r["faces"]
    assert 0 <= quads.min() and quads.max() < len(verts)


def test_volume_layers_stay_in_the_closure_budget():
    plan = physics.resolve(physics.SkyParams(location="urban", month=7, sun_elevation_deg=30, mode="VOLUMETRIC",
                                             n_layers=8))
    vol = volumetric.volume_layers(plan, 8)
    assert len(vol["balls"]) == 8 and vol["closures_at_camera"] <= volumetric.CLOSURE_BUDGET
    assert vol["balls"][-1]["top_m"] == pytest.approx(100_000.0)
    for ball in vol["balls"]:
        for sc in ball["scatter"].values():
            assert min(sc) >= 0  # negative scattering differences render wrong in Cycles
    tau_sh = sum((s["top_m"] - s["bottom_m"]) * np.array(v) for s in vol["shells"] for v in s["scatter"].values())
    assert np.all(np.asarray(tau_sh) >= 0)
    assert vol["phases"]["aerosol0"]["g1"] > 0.5
    many = volumetric.volume_layers(plan, 24)  # falls back to one lobe per aerosol regime
    assert many["closures_at_camera"] <= volumetric.CLOSURE_BUDGET
    assert many["phases"]["aerosol0"]["lobes"] == 1


def test_too_many_closures_are_refused(monkeypatch):
    plan = physics.resolve(physics.SkyParams(location="urban", month=7, sun_elevation_deg=30, n_layers=8))
    monkeypatch.setattr(volumetric, "CLOSURE_BUDGET", 10)
    with pytest.raises(SkymodelInputError) as e:
        volumetric.volume_layers(plan, 8)
    assert e.value.parameter == "n_layers"


def test_closure_split_keeps_totals_and_luminance_and_gives_one_share_per_species():
    """Cycles mixes phase closures with one weight per closure in all channels (docs/blender.md):
    the split must keep each channel's total, give every closure the colour of the total (so that
    mixing is the same in every channel), and keep each species' luminance-weighted scattering."""
    plan = physics.resolve(physics.SkyParams(location="urban", month=7, sun_elevation_deg=30, mode="VOLUMETRIC",
                                             n_layers=6))
    vol = volumetric.volume_layers(plan, 6)
    lay, w = vol["layered"], vol["weights"]
    raw = [volumetric.project(lay.rayleigh_scattering, w)] + [volumetric.project(a, w)
                                                              for a in lay.aerosol_scattering_by_regime]
    split = [vol["closure_scattering"]["rayleigh"]] + [vol["closure_scattering"][f"aerosol{r}"]
                                                       for r in range(len(raw) - 1)]
    total = sum(np.maximum(r, 0.0) for r in raw)
    assert np.allclose(sum(split), total, rtol=1e-12, atol=0)
    u = physics.LUMA_709 * physics.spectrum_rgb(vol["profile"].solar_irradiance, vol["profile"].wavelengths_nm)
    for r, s in zip(raw, split):
        share = (s / np.where(total > 0, total, 1.0))
        assert np.allclose(share, share[:, :1], rtol=1e-10, atol=1e-15)  # the same share in R, G, B
        assert np.allclose(s @ u, np.maximum(r, 0.0) @ u, rtol=1e-10, atol=1e-20)
    # the raw coefficients do differ in colour between species (else the test would prove nothing)
    assert not np.allclose(raw[1][0] / raw[1][0, 1], raw[0][0] / raw[0][0, 1], rtol=0.05)
    # the marcher's RGB model holds exactly the split coefficients
    prof = volumetric.rgb_model_profile(vol)
    assert np.allclose(prof.rayleigh_scattering[:, volumetric.TO_RGB], split[0])
