"""The paper's aerosol model (Guimera, Gutierrez & Jarabo 2018: Table 1, Eqs. 10-12), the model
choice and the site altitude (the location rule: tests/test_location_rule.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from skymodel import scene
from skymodel.data import load_npz, load_toml
from skymodel.geometry import altitude_grid
from skymodel.numerics import trapezoid
from skymodel.optics import aerosols, mie_lookup
from skymodel.optics.atmosphere import Atmosphere, locations

H = altitude_grid()

#: Table 1 of the paper, typed here from the seed text (../shared/seeds/000_542836ced7646924.txt).
TABLE1 = {
    "polar_antarctic": {"sulfuric_acid": 0.99, "sea_salt": 0.005, "mineral": 0.005},
    "polar_arctic": {"soot": 0.25, "sea_salt": 0.25, "mineral": 0.25, "sulfate": 0.25},
    "background": {"sulfate": 0.5, "sulfuric_acid": 0.5},
    "maritime_clean": {"sea_salt": 0.6, "sulfate": 0.4},
    "maritime_polluted": {"water_soluble": 0.6, "sea_salt": 0.4},
    "continental": {"dust_like": 0.3, "water_soluble": 0.3, "soot": 0.3},
    "desert": {"mineral": 1.0},
    "rural": {"water_soluble": 0.94, "soot": 0.06},
    "urban": {"water_soluble": 0.6, "soot": 0.4},
    "stratospheric_background": {"sulfuric_acid": 1.0},
    "volcanic": {"sulfuric_acid": 0.5, "volcanic_ash": 0.5},
}


def paper():
    return load_toml("presets/aerosols/paper.toml")


# ------------------------------------------------------------------------------ the preset


def test_table1_fractions_read_back_exactly():
    types = paper()["types"]
    assert set(types) == set(TABLE1)
    for name, row in TABLE1.items():
        assert types[name]["table1"] == row, name  # exact floats, as printed
    # the printed continental row sums to 0.9: kept as printed, normalised when mixed
    assert math.isclose(sum(types["continental"]["table1"].values()), 0.9)
    assert "0.9" in types["continental"]["table1_note"]


def test_mixtures_are_table1_by_number_on_one_distribution():
    for name, row in TABLE1.items():
        info = aerosols.type_info(name, model="guimera2018")
        dist = paper()["distributions"][info["distribution"]]
        c0 = sum(m["n_cm3"] for m in dist["modes"])
        total = sum(row.values())
        expected: dict[str, float] = {}
        for comp, w in row.items():
            key = f"{info['distribution']}:{paper()['component_index'][comp]['index']}"
            expected[key] = expected.get(key, 0.0) + c0 * w / total
        assert info["mixture"] == pytest.approx(expected, rel=1e-12), name
        assert sum(info["mixture"].values()) == pytest.approx(c0, rel=1e-12)


def test_every_preset_value_carries_a_source():
    t = paper()
    assert t["source"] and t["w_c_reading"].startswith("by number")
    for name, ty in t["types"].items():
        assert ty["table1_source"].startswith("Guimera et al. 2018 Table 1"), name
        assert ty["distribution_source"], name
        assert ty["profile"]["source"], name
        if "default_aod550" in ty:
            assert ty["default_aod550_source"], name
        # a type on a substituted distribution says so
        if t["distributions"][ty["distribution"]].get("substitution"):
            assert "SUBSTITUTION" in ty["distribution_source"], name
    for name, d in t["distributions"].items():
        assert d["source"] and len(d["modes"]) in (1, 3), name
        if len(d["modes"]) == 1:
            assert d.get("substitution") and "SUBSTITUTION" in d["source"], name
    for comp, e in t["component_index"].items():
        assert e["source"] and e["index"], comp
    # Arctic, polluted maritime: no Jaenicke distribution of their own -> flagged substitutions
    for name in ("polar_arctic", "maritime_polluted"):
        assert "SUBSTITUTION" in t["types"][name]["distribution_source"]
    for name, loc in locations().items():
        if "site_altitude_m" in loc:
            assert loc["site_altitude_source"], name
        if "aod550" in loc:
            assert loc["aod550_source"], name


def test_a_preset_measured_amount_applies_to_its_own_type_only():
    # Mauna Loa: Jaenicke's free-troposphere table amount (AOD550 ~2.8) is far from the measured
    # clean sky; the preset's aod550 applies when its type is used and nothing else sets the amount
    assert aerosols.default_aod550("background") > 1.0
    assert Atmosphere(location="mauna_loa").optical_profile([550.0]).metadata["aod550"] == pytest.approx(0.02)
    assert Atmosphere(location="mauna_loa", turbidity=2.0).aod550 is None
    assert Atmosphere(location="mauna_loa", aerosol="urban").aod550 is None
    assert Atmosphere(location="mauna_loa", aod550=0.1).aod550 == 0.1


def test_polar_widths_resolved():
    # the two transcriptions disagree (Aerosol.jl .164/.521/.420, pyrcel .245/.300/.291); the preset
    # takes pyrcel's and says why
    modes = paper()["distributions"]["polar"]["modes"]
    assert [m["log10_sigma"] for m in modes] == [0.245, 0.300, 0.291]
    assert "pyrcel" in paper()["distributions"]["polar"]["source"]


def test_models_match_the_registry():
    assert tuple(aerosols.MODELS) == scene.parameter("aerosol_model").choices
    assert scene.default("aerosol_model") == "guimera2018"
    assert scene.check("aerosol_model", "Paper") == "guimera2018"
    assert set(aerosols.aerosol_types("guimera2018")) <= set(scene.parameter("aerosol").choices)
    assert set(aerosols.aerosol_types("opac")) <= set(scene.parameter("aerosol").choices)


# --------------------------------------------------------------------------------- Eq. 12


def test_eq12_by_hand_v_plus_one():
    z = np.array([0.0, 500.0, 3000.0, 1e6])
    c = aerosols.eq12_concentration(z, 100.0, 2.0, 1000.0)
    hand = [100.0 * (math.exp(-zz / 1000.0) + 2.0 / 100.0) for zz in z]
    assert c == pytest.approx(hand, rel=1e-13)
    assert c[0] == pytest.approx(102.0, rel=1e-15)  # C(0) = C0 + Cb
    assert c[-1] == pytest.approx(2.0, rel=1e-12)  # the Cb floor aloft
    assert np.all(c >= 2.0) and np.all(np.diff(c) < 0)


def test_eq12_by_hand_v_minus_one():
    z = np.array([0.0, 500.0, 3000.0, 20000.0])
    c = aerosols.eq12_concentration(z, 100.0, 2.0, -1000.0)
    hand = [100.0 * (math.exp(zz / 1000.0) + 100.0 / 2.0) ** -1 for zz in z]
    assert c == pytest.approx(hand, rel=1e-13)
    assert c[0] == pytest.approx(100.0 * 2.0 / 102.0, rel=1e-15)  # C(0) = C0 Cb / (C0 + Cb)
    # Cb is a ceiling (plateau near the ground), and the profile decays aloft: it does not grow
    assert np.all(c <= 2.0) and np.all(np.diff(c) < 0)
    assert c[-1] == pytest.approx(100.0 * math.exp(-20.0), rel=1e-6)


def test_eq12_infinite_scale_height_is_uniform():
    c = aerosols.eq12_concentration([0.0, 5e4], 50.0, 1.0, math.inf)
    assert c == pytest.approx([51.0, 51.0], rel=1e-15)


def test_paper_profiles_are_eq12_relative_to_c0_without_a_top():
    for name in ("urban", "desert", "polar_antarctic"):
        info = aerosols.type_info(name, model="guimera2018")
        c0 = info["c0_cm3"]
        cb = info["profile"]["background_cm3"]
        hp = float(info["profile"]["scale_height_km"]) * 1e3
        f = aerosols.vertical_profile(name, H, model="guimera2018")
        assert f == pytest.approx(aerosols.eq12_concentration(H, c0, cb, hp) / c0, rel=1e-12)
        assert f[0] == pytest.approx(1.0 + cb / c0, rel=1e-12)
        assert np.all(f > 0)  # no cut at 12 km
    # background (free troposphere, no height dependence): uniform up to the tropopause, the one top
    fb = aerosols.vertical_profile("background", [0.0, 11_999.0, 12_001.0], model="guimera2018")
    assert fb[0] == pytest.approx(fb[1], rel=1e-15) and fb[2] == 0.0
    f = aerosols.vertical_profile("polar_arctic", [12_001.0, 50_000.0], model="guimera2018")
    assert f == pytest.approx(np.exp(-np.array([12_001.0, 50_000.0]) / 30_000.0), rel=1e-9)


# ------------------------------------------------------------------------- the Mie lookup


def test_paper_lookup_holds_every_entry_and_is_normalised():
    lk = load_npz(aerosols.MODELS["guimera2018"][1])
    assert sorted(map(str, lk["components"])) == sorted(mie_lookup.paper_entries())
    assert np.array_equal(lk["wavelengths_nm"], mie_lookup.PAPER_WAVELENGTHS_NM)
    assert np.array_equal(lk["angles_deg"], mie_lookup.default_angles_deg())
    assert np.all(lk["sca"] <= lk["ext"] * (1 + 1e-12)) and np.all(lk["sca"] > 0)
    assert np.max(np.abs(lk["phase_norm_raw"] - 1.0)) < 5e-3
    mu = np.cos(np.radians(lk["angles_deg"]))
    for i in range(lk["components"].size):
        g_tab = mie_lookup.phase_integral(lk["phase"][i] * mu[:, None], lk["angles_deg"])
        assert np.max(np.abs(g_tab - lk["g"][i])) < 5e-3, lk["components"][i]


def test_paper_lookup_reproduces():
    lk = load_npz(aerosols.MODELS["guimera2018"][1])
    names = [str(n) for n in lk["components"]]
    col = int(np.flatnonzero(lk["wavelengths_nm"] == 540.0)[0])
    # a fine, a marine, and the two coarse entries that take the large-particle limit (the desert
    # coarse mode, x up to 580 at 540 nm, and the polar 8.6 um mode): about 4 s
    entries = ["urban:soot", "marine:sea_salt", "desert:mineral", "polar:sea_salt"]
    new = mie_lookup.build_paper_tables(entries, [540.0])
    for i, name in enumerate(entries):
        c = names.index(name)
        for key in ("ext", "sca", "g", "phase"):
            assert np.allclose(new[key][i], lk[key][c][..., [col]], rtol=1e-6, atol=0), (name, key)


def test_three_mode_cross_section_against_miepython():
    miepython = pytest.importorskip("miepython")
    # rural water-soluble at 540 nm: the number-weighted sum of Jaenicke's three rural modes,
    # integrated independently (even ln r grid, miepython's m = n - ik). The grid ends 7 ln(sigma)
    # above each mode radius: the cross section's weight (r^2 dn) peaks 2 ln(sigma) above it, so
    # the cut leaves out < 1e-5 of it, and the coarse mode's largest spheres (x 3e4 at 9 ln(sigma))
    # cost 95 % of miepython's time (8000 points to 9 ln(sigma): 78 s, ratio - 1 = 3.2e-6; 4000 to
    # 7: 4.6 s, 4.5e-6)
    entry = mie_lookup.paper_entries()["rural:water_soluble"]
    m = mie_lookup.refractive_index_file("water_soluble.csv", [540.0])[0]
    n_tot = sum(n for n, _, _ in entry["modes"])
    c_ext = 0.0
    for n, r_mod, sigma in entry["modes"]:
        u = np.linspace(np.log(r_mod) - 6 * np.log(sigma), np.log(r_mod) + 7 * np.log(sigma), 4000)
        r = np.exp(u)
        qext = miepython.efficiencies_mx(np.conj(m), 2 * np.pi * r / 0.54)[0]
        dn = aerosols.lognormal_number_distribution(r, n / n_tot, r_mod, sigma)
        c_ext += trapezoid(qext * np.pi * (r * 1e-6) ** 2 * dn, u)
    lk = load_npz(aerosols.MODELS["guimera2018"][1])
    c = [str(n) for n in lk["components"]].index("rural:water_soluble")
    j = int(np.flatnonzero(lk["wavelengths_nm"] == 540.0)[0])
    assert lk["ext"][c, j] / c_ext == pytest.approx(1.0, rel=1e-3, abs=0)


def test_area_tail_is_the_lognormal_moment():
    # the geometric cross section beyond r of a lognormal, against a direct quadrature
    r_mod, sigma, r_cut = 10.8, 2.7416, 50.0
    u = np.linspace(np.log(r_cut), np.log(r_mod) + 14 * np.log(sigma), 200001)
    r = np.exp(u)
    dn = aerosols.lognormal_number_distribution(r, 1.0, r_mod, sigma)
    direct = trapezoid(np.pi * (r * 1e-6) ** 2 * dn, u)
    assert mie_lookup.lognormal_area_tail(r_mod, sigma, r_cut) == pytest.approx(direct, rel=1e-6)


@pytest.mark.slow
def test_large_particle_limit_changes_the_desert_coarse_mode_little():
    # Jaenicke's desert coarse mode (r 10.8 um, sigma 2.74) at 780 nm: holding the optics of
    # spheres above 50 um at their 50 um value vs at 100 um changes ext and sca by < 1 %
    m = mie_lookup.refractive_index_file("mineral.csv", [780.0])
    a = mie_lookup.integrate_component(m, [780.0], 10.8, 2.7416, r_max_um=50.0)
    b = mie_lookup.integrate_component(m, [780.0], 10.8, 2.7416, r_max_um=100.0)
    for key in ("ext", "sca", "g"):
        assert a[key][0] == pytest.approx(b[key][0], rel=1e-2), key


# ------------------------------------------------------------------------- hard cases


@pytest.mark.parametrize("name", ["desert", "polar_antarctic", "polar_arctic"])
def test_hard_cases_coarse_modes_stable(name):
    # desert coarse mode (x up to 827 at 380 nm, then the large-particle limit) and the polar
    # 8.6 um mode: finite, bounded, normalised at both ends of the spectrum
    o = aerosols.aerosol_optics(name, H, [380.0, 550.0, 780.0], stratospheric="none", model="guimera2018")
    for arr in (o.scattering_by_regime, o.absorption, o.phase, o.optical_depth):
        assert np.all(np.isfinite(arr)) and np.all(arr >= 0)
    assert np.all((o.single_scattering_albedo > 0) & (o.single_scattering_albedo <= 1))
    assert np.all((o.asymmetry > 0) & (o.asymmetry < 1))
    assert np.allclose(mie_lookup.phase_integral(o.phase[0], o.angles_deg, axis=0), 1.0, atol=1e-9)
    assert o.aod550 == pytest.approx(aerosols.default_aod550(name, model="guimera2018"), rel=1e-2)


def test_every_paper_type_builds():
    for name in aerosols.aerosol_types("guimera2018"):
        for strat in ("background", "volcanic"):
            o = aerosols.aerosol_optics(name, H, [400.0, 550.0, 700.0], stratospheric=strat, model="guimera2018")
            assert o.aerosol_model == "guimera2018" and o.aod550 > 0 and np.all(np.isfinite(o.phase))


def test_models_differ_and_the_default_is_the_paper():
    paper_ = aerosols.aerosol_optics("urban", H, [550.0], stratospheric="none")
    opac = aerosols.aerosol_optics("urban", H, [550.0], stratospheric="none", model="opac")
    assert paper_.aerosol_model == "guimera2018" and opac.aerosol_model == "opac"
    assert paper_.single_scattering_albedo[0] != pytest.approx(opac.single_scattering_albedo[0], abs=1e-3)
    assert Atmosphere(location="urban").aerosol_model == "guimera2018"
    assert Atmosphere(location="urban", aerosol_model="opac").optical_profile([550.0]).metadata["aerosol_model"] == "opac"
    # a type only the OPAC model has: refused by the paper's model named explicitly (naming the
    # parameter); given without a model it selects the OPAC model
    from skymodel.errors import SkymodelInputError

    with pytest.raises(SkymodelInputError) as e:
        Atmosphere(location="urban", aerosol="continental_polluted", aerosol_model="guimera2018")
    assert e.value.parameter == "aerosol" and "guimera2018" in str(e.value)
    assert Atmosphere(location="urban", aerosol="continental_polluted").aerosol_model == "opac"
    assert Atmosphere(location="urban", aerosol="continental_polluted", aerosol_model="opac").aerosol == \
        "continental_polluted"


# ------------------------------------------------------------------------- site altitude


def _ussa76_pressure_ratio(z_m: float) -> float:
    """p(z)/p0 of the USSA76 troposphere by hand: geopotential height, lapse rate 6.5 K/km."""
    r0 = 6_356_766.0
    hgp = r0 * z_m / (r0 + z_m)
    g0, m_air, r_gas, lapse, t0 = 9.80665, 0.0289644, 8.3144598, 0.0065, 288.15
    return (1.0 - lapse * hgp / t0) ** (g0 * m_air / (r_gas * lapse))


def _bodhaine_tau(lam_um: float) -> float:
    """Bodhaine et al. 1999 Eq. 30: Rayleigh optical depth at sea level (1013.25 hPa, 360 ppm CO2)."""
    l2 = lam_um**2
    return 0.0021520 * (1.0455996 - 341.29061 / l2 - 0.90230850 * l2) / (1.0 + 0.0027059889 / l2 - 85.968563 * l2)


def test_site_altitude_rayleigh_depth_scales_with_pressure():
    sea = Atmosphere(location="mauna_loa", site_altitude_m=0.0).optical_profile([550.0])
    ml = Atmosphere(location="mauna_loa").optical_profile([550.0])
    assert ml.metadata["site_altitude_m"] == 3397.0
    expected = _bodhaine_tau(0.55) * _ussa76_pressure_ratio(3397.0)
    tau = ml.metadata["rayleigh_optical_depth_550"]
    assert tau == pytest.approx(expected, rel=1e-2)
    assert sea.metadata["rayleigh_optical_depth_550"] == pytest.approx(_bodhaine_tau(0.55), rel=1e-2)
    assert 0.6 < tau / sea.metadata["rayleigh_optical_depth_550"] < 0.7  # "about two thirds"
    # the ground is at the site: radius and top move, heights stay above the ground
    assert ml.planet_radius_m == pytest.approx(sea.planet_radius_m + 3397.0)
    assert ml.top_altitude_m == pytest.approx(sea.top_altitude_m - 3397.0)
    assert ml.altitudes_m[0] == 0.0
    # aerosols at their ground concentration at the site (a type's table amount; Mauna Loa's own is
    # a measured AOD, which the column sets)
    a_sea, a_ml = (Atmosphere(location="mauna_loa", aerosol="rural", site_altitude_m=s).optical_profile([550.0])
                   for s in (0.0, None))
    assert a_ml.aerosol_scattering_by_regime[0, 0] == pytest.approx(a_sea.aerosol_scattering_by_regime[0, 0],
                                                                    rel=1e-9)


def test_site_altitude_is_checked_and_explicit_wins():
    from skymodel.errors import SkymodelInputError

    with pytest.raises(SkymodelInputError) as e:
        Atmosphere(location="rural", site_altitude_m=-500.0)  # below the Dead Sea shore (-430 m)
    assert e.value.parameter == "site_altitude"
    with pytest.raises(SkymodelInputError):
        Atmosphere(location="rural", site_altitude_m=9_001.0)
    # the lowest and the highest ground: Rayleigh depth with the pressure there (USSA76)
    for z in (-430.0, 8849.0):
        tau = Atmosphere(location="rural", site_altitude_m=z).optical_profile([550.0]).metadata["rayleigh_optical_depth_550"]
        assert tau == pytest.approx(_bodhaine_tau(0.55) * _ussa76_pressure_ratio(z), rel=1e-2), z
    assert Atmosphere(location="denver").site_altitude_m == 1609.0
    assert Atmosphere(location="denver", site_altitude_m=0.0).site_altitude_m == 0.0
    assert Atmosphere(location="rural").site_altitude_m == 0.0


# ------------------------------------------------------------------ the paper's desert against Monte Carlo


@pytest.mark.slow
@pytest.mark.parametrize("aod550", [0.27, None])  # OPAC's table amount, and the paper's (2.33)
def test_marcher_vs_monte_carlo_paper_desert(aod550):
    # The paper's desert (Jaenicke coarse dust: g 0.94, ssa 0.57, p(0) = 1.7e4 /sr at 550 nm,
    # 86 % of the scattering within 12 deg) has a diffraction peak the Monte Carlo tracer cannot
    # converge on: with the raw phase function its NEE estimate is heavy-tailed (runs of 1e4..6.4e5
    # paths scatter from -55 % to +117 % around the value below, with standard errors that
    # understate it), which issue 20 read as the marcher being 15-50 % high. The reference is
    # the same tracer on the medium with the peak inside 3 deg cut (delta-M): it converges (se ~1 %)
    # and agrees with the 12-deg cut within noise away from the sun (docs/accuracy.md, "Known
    # limits"). Sun 20 deg, the views of test_marcher's MC comparison; the
    # one 10 deg from the sun is outside the 3-deg cone.
    from skymodel.render.marcher import MarchSettings, SkyMarcher
    from skymodel.render.rays import direction_from_angles
    from skymodel.validation.delta_m_medium import delta_m_profile
    from skymodel.validation.montecarlo import trace_radiance

    prof = Atmosphere(location="desert", month=6, aod550=aod550).optical_profile((450.0, 650.0))
    views = ((0.0, 0.0), (45.0, 0.0), (45.0, 180.0), (80.0, 0.0), (80.0, 180.0), (88.0, 180.0))
    d = direction_from_angles(np.array([v[0] for v in views]), np.array([180.0 + v[1] for v in views]))
    mc = trace_radiance(delta_m_profile(prof, 3.0), d, 20.0, 180.0, n_paths=20000, seed=31)
    r = SkyMarcher(prof, 20.0, 180.0, 0.0, MarchSettings(exact=True)).radiance(d).radiance
    rel = r / mc.radiance - 1.0
    assert np.all(np.abs(rel) <= 4.0 * mc.stderr / mc.radiance + 0.02), np.round(100 * rel, 1)
