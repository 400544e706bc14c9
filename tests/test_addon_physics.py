"""The add-on's computations that need no Blender: parameters, colour scale, exposure,
volume layering and tessellation."""

import math

import numpy as np
import pytest

from blender_addon import physics, volumetric
from skymodel.errors import SkymodelInputError


def test_resolve_validates_through_the_core():
    sky = physics.resolve(physics.SkyParams(location="desert", month=1, sun_elevation_deg=5, sun_azimuth_deg=-90))
    assert sky.atmosphere.aerosol == "desert" and sky.sun_azimuth_deg == pytest.approx(270.0)
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
    sky = physics.resolve(physics.SkyParams(location="zaragoza", month=1, time_utc=(2026, 6, 21, 12, 0)))
    assert sky.atmosphere.month == 6 and sky.atmosphere.day_of_year == 172  # the date's ozone (#19)
    assert 60 < sky.sun_elevation_deg < 75 and 150 < sky.sun_azimuth_deg < 200
    assert sky.sun_angular_diameter_deg() == pytest.approx(0.524, abs=0.003)  # aphelion


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


def test_layer_volumes_never_overlap_and_keep_each_layer_optical_depth():
    edges = [0.0, 150.0, 543.0, 1535.0, 100_000.0]
    vols = volumetric.layer_volumes(edges)
    assert vols[0][0] is None  # the lowest layer is a ball around the camera
    bounds = [0.0] + [x for bottom, top, _ in vols for x in ((bottom,) if bottom is not None else ()) + (top,)]
    assert all(b > a for a, b in zip(bounds, bounds[1:]))  # strictly increasing: no overlap, no shared surface
    for i, (bottom, top, scale) in enumerate(vols):
        lo, hi = edges[i], edges[i + 1]
        inset = min(volumetric.SHELL_INSET_M, 0.1 * (hi - lo))
        assert top == pytest.approx(hi - inset)
        assert (bottom is None) == (i == 0) and (bottom is None or bottom == pytest.approx(lo + inset))
        assert scale * (top - (lo if bottom is None else bottom)) == pytest.approx(hi - lo)


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


def test_volume_layers_hold_each_layer_in_one_volume():
    sky = physics.resolve(physics.SkyParams(location="urban", month=7, sun_elevation_deg=30, mode="VOLUMETRIC",
                                            n_layers=8))
    vol = volumetric.volume_layers(sky, 8)
    assert len(vol["volumes"]) == 8 and vol["closures_per_volume"] <= volumetric.MAX_PHASE_CLOSURES
    assert vol["volumes"][-1]["top_m"] == pytest.approx(100_000.0 - volumetric.SHELL_INSET_M)
    assert vol["phases"]["aerosol0"]["g1"] > 0.5 and vol["phases"]["aerosol0"]["lobes"] == 2
    lay, w = vol["layered"], vol["weights"]
    thick = np.diff(lay.edges_m)
    for v in vol["volumes"]:
        inner = v["top_m"] - (0.0 if v["bottom_m"] is None else v["bottom_m"])
        i = v["layer"]
        for name, sc in v["scatter"].items():  # each species' optical depth through the layer kept
            assert np.allclose(np.array(sc) * inner, vol["closure_scattering"][name][i] * thick[i], rtol=1e-9)
    # the marcher's model (volumes and empty gaps) has the layered medium's vertical optical depth
    prof = volumetric.rgb_model_profile(vol)
    ext = prof.rayleigh_scattering + prof.aerosol_scattering_by_regime.sum(axis=0) + prof.ozone_absorption
    want = (sum(vol["closure_scattering"].values()) + np.maximum(
        volumetric.project(lay.ozone_absorption + lay.aerosol_absorption, w), 0.0))[:, volumetric.TO_RGB]
    assert np.allclose(prof.vertical_optical_depth(ext), (want * thick[:, None]).sum(axis=0), rtol=1e-9)
    many = volumetric.volume_layers(sky, 24)  # any number of layers: still one volume at a point
    assert many["closures_per_volume"] <= volumetric.MAX_PHASE_CLOSURES
    assert many["phases"]["aerosol0"]["lobes"] == 2


def test_too_many_closures_are_refused(monkeypatch):
    sky = physics.resolve(physics.SkyParams(location="urban", month=7, sun_elevation_deg=30, n_layers=8))
    monkeypatch.setattr(volumetric, "MAX_PHASE_CLOSURES", 2)
    with pytest.raises(SkymodelInputError) as e:
        volumetric.volume_layers(sky, 8)
    assert e.value.parameter == "n_layers"


def test_closure_split_keeps_totals_and_luminance_and_gives_one_share_per_species():
    """Cycles mixes phase closures with one weight per closure in all channels (docs/blender.md):
    the split must keep each channel's total, give every closure the colour of the total (so that
    mixing is the same in every channel), and keep each species' luminance-weighted scattering."""
    sky = physics.resolve(physics.SkyParams(location="urban", month=7, sun_elevation_deg=30, mode="VOLUMETRIC",
                                            n_layers=6))
    vol = volumetric.volume_layers(sky, 6)
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
    inner = prof.rayleigh_scattering[::2, volumetric.TO_RGB]  # layers and gaps alternate
    scale = np.array([v["scale"] for v in vol["volumes"]])
    assert np.allclose(inner, split[0] * scale[:, None])
    assert np.all(prof.rayleigh_scattering[1::2] == 0)


def test_moon_lamp_from_the_core_info_and_from_astro():
    """The moon lamp the core's environment render records (issue 24: ``info["moon"]``) is
    taken as it is; the add-on's own (skymodel.astro) gives the same kind of numbers."""
    moon = {"elevation_deg": 30.0, "azimuth_deg": 200.0, "strength": 2e-4, "colour": [1.2, 0.95, 0.7],
            "angle_deg": 0.52, "phase_angle_deg": 10.0, "illuminated_fraction": 0.99, "visible_fraction": 1.0}
    got = physics.moon_from_info({"moon": moon})
    assert got["colour"] == (1.2, 0.95, 0.7) and got["illuminance_lux"] == pytest.approx(683 * 2e-4)
    assert physics.moon_from_info({"moon": dict(moon, strength=0.0)}) is None  # set
    assert physics.moon_from_info({"moon": {"elevation_deg": 3.0}}) is None and physics.moon_from_info({}) is None
    sky = physics.resolve(physics.SkyParams(location="zaragoza", time_utc=(2026, 6, 21, 20, 0), timezone="UTC"))
    lamp = physics.moon_lamp(sky)
    top = physics.moon_lamp(sky, above_atmosphere=True)
    assert 30 < lamp["elevation_deg"] < 45 and 0.4 < lamp["illuminated_fraction"] < 0.6
    assert 0.48 < lamp["angle_deg"] < 0.57 and top["strength"] > lamp["strength"] > 0
    assert physics.moon_lamp(physics.resolve(physics.SkyParams())) is None  # no date, no moon
