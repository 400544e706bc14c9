"""Aerosol types, vertical profiles, the Mie lookup and the optics per height (skymodel.optics.aerosols)."""

from __future__ import annotations

import numpy as np
import pytest

from skymodel.optics import aerosols, mie_lookup
from skymodel.data import load_npz
from skymodel.errors import SkymodelInputError
from skymodel.geometry import altitude_grid
from skymodel.numerics import trapezoid
from skymodel.wavelengths import default_wavelengths

H = altitude_grid()  # 401 altitudes, 0-100 km
WL = default_wavelengths()  # 81 wavelengths
J550 = int(np.argmin(np.abs(WL - 550.0)))
FINE = ["continental", "rural", "urban"]
COARSE = ["desert", "maritime_clean"]


def lookup():
    return load_npz(aerosols.LOOKUP)


def column(coefficient, h=H):
    return trapezoid(coefficient, h, axis=0)


# ------------------------------------------------------------------------------- the tables


def test_type_and_component_lists():
    types = aerosols.aerosol_types()
    for name in ["polar_antarctic", "polar_arctic", "background", "maritime_clean", "maritime_polluted",
                 "continental", "desert", "rural", "urban"]:
        assert name in types
    assert "volcanic" not in types and "stratospheric_background" not in types
    comps = aerosols.components()
    for name in ["insoluble", "water_soluble", "soot", "sea_salt_accumulation", "sea_salt_coarse",
                 "mineral_nucleation", "mineral_accumulation", "mineral_coarse", "sulfuric_acid",
                 "volcanic_ash", "meteoric", "sulfate", "biogenic"]:
        assert name in comps
    assert aerosols.stratospheric_types() == ["background", "volcanic", "none"]


def test_every_type_names_known_components_and_a_source():
    # the OPAC model (the paper's: tests/test_aerosols_paper.py)
    comps = set(aerosols.components())
    for name in aerosols.aerosol_types("opac") + ["stratospheric_background", "volcanic"]:
        info = aerosols.type_info(name, model="opac")
        assert set(info["mixture"]) <= comps, name
        assert all(v > 0 for v in info["mixture"].values()), name
        assert info["mixture_source"] and info["profile"]["source"]


def test_refractive_indices_cover_the_range_with_k_nonnegative():
    for name in aerosols.components():
        m = mie_lookup.refractive_index(name, np.arange(350.0, 801.0, 5.0))
        assert np.all(m.imag >= 0) and np.all((m.real > 1.3) & (m.real < 2.0)), name


def test_lognormal_number_distribution_integrates_to_total():
    u = np.linspace(np.log(1e-4), np.log(1e3), 20001)
    dn = aerosols.lognormal_number_distribution(np.exp(u), 250.0, 0.0212, 2.24)
    assert trapezoid(dn, u) == pytest.approx(250.0, rel=1e-9)
    assert np.argmax(dn) == np.argmin(np.abs(np.exp(u) - 0.0212))
    with pytest.raises(SkymodelInputError) as e:
        aerosols.lognormal_number_distribution([0.1], 1.0, 0.1, 0.9)
    assert e.value.parameter == "sigma"


# --------------------------------------------------------------------------------- profiles


def test_vertical_profile_eq12():
    # the OPAC model's form (v = 1, normalised at the ground, cut at 12 km); the paper's full Eq. 12:
    # tests/test_aerosols_paper.py
    h = np.array([0.0, 730.0, 5000.0, 11999.0, 12001.0, 50000.0])
    f = aerosols.vertical_profile("urban", h, model="opac")
    assert f[0] == pytest.approx(1.0)
    assert f[1] == pytest.approx(np.exp(-1.0), rel=1e-3)  # Hp = 0.73 km, tiny background term
    assert np.all(np.diff(f) <= 0) and f[4] == 0 and f[5] == 0
    # background: uniform up to the tropopause
    fb = aerosols.vertical_profile("Background", h, model="opac")
    assert np.allclose(fb[:4], 1.0) and fb[4] == 0
    # polar: 30 km scale height
    assert aerosols.vertical_profile("polar_arctic", [10000.0], model="opac")[0] == pytest.approx(np.exp(-1 / 3), rel=2e-3)
    # stratospheric layer: 1 at the peak, symmetric
    s = aerosols.vertical_profile("stratospheric_background", [16000.0, 20000.0, 24000.0])
    assert s[1] == pytest.approx(1.0) and s[0] == pytest.approx(s[2]) and s[0] == pytest.approx(np.exp(-0.5))


# ------------------------------------------------------------------------------- the optics


@pytest.mark.parametrize("name", aerosols.aerosol_types() + ["none"])
def test_every_type_builds_on_the_default_grid(name):
    o = aerosols.aerosol_optics(name, H, WL)
    n_ang = o.angles_deg.size
    assert o.scattering_by_regime.shape == (2, H.size, WL.size)
    assert o.absorption.shape == (H.size, WL.size)
    assert o.phase.shape == (2, n_ang, WL.size)
    for arr in (o.scattering_by_regime, o.absorption, o.phase, o.optical_depth, o.single_scattering_albedo,
                o.asymmetry):
        assert np.all(np.isfinite(arr)) and np.all(arr >= 0)
    assert np.isfinite(o.aod550) and np.isfinite(o.angstrom_exponent)
    if name != "none":
        assert o.aod550 > 0 and np.all(o.scattering_by_regime[0, 0] > 0)
        assert o.aod550 == pytest.approx(aerosols.default_aod550(name), rel=1e-2)
        # the reported column AOD is what the coefficients integrate to
        ext = o.scattering_by_regime.sum(axis=0) + o.absorption
        assert column(ext)[J550] == pytest.approx(o.optical_depth[J550], rel=1e-9)


def test_phase_tables_normalised_over_4pi():
    # accurate integral of the piecewise-linear table (exact quadrature) ...
    for name in aerosols.aerosol_types() + ["none"]:
        for strat in ("background", "volcanic"):
            o = aerosols.aerosol_optics(name, H, WL, stratospheric=strat)
            norm = mie_lookup.phase_integral(o.phase, o.angles_deg, axis=1)
            assert np.max(np.abs(norm - 1.0)) < 1e-3, (name, strat)
    # ... and an independent check: resample on a fine grid in cos(theta), Simpson in mu
    o = aerosols.aerosol_optics("desert", H, WL)
    mu = np.cos(np.radians(np.linspace(0.0, 180.0, 180001)))
    th = np.degrees(np.arccos(mu))
    p = np.array([np.interp(th, o.angles_deg, o.phase[0, :, j]) for j in (0, J550, WL.size - 1)])
    from scipy.integrate import simpson

    norm = 2 * np.pi * simpson(p[:, ::-1], x=mu[::-1], axis=1)
    assert np.allclose(norm, 1.0, atol=1e-3)


def test_lookup_angle_grid_samples_the_phase_functions():
    # before renormalisation the phase functions already integrate to 1 within 1e-3 on the grid
    lk = lookup()
    assert np.max(np.abs(lk["phase_norm_raw"] - 1.0)) < 1e-3
    # and the asymmetry parameter of the tables matches the Mie g
    mu = np.cos(np.radians(lk["angles_deg"]))
    for i in range(lk["components"].size):
        g_tab = mie_lookup.phase_integral(lk["phase"][i] * mu[:, None], lk["angles_deg"])
        assert np.max(np.abs(g_tab - lk["g"][i])) < 2e-3, lk["components"][i]


def test_aod_setting_gives_the_column():
    o = aerosols.aerosol_optics("rural", H, WL, aod550=0.3, stratospheric="none")
    ext = o.scattering_by_regime.sum(axis=0) + o.absorption
    assert column(ext)[J550] == pytest.approx(0.3, rel=5e-3)
    assert o.aod550 == pytest.approx(0.3, rel=1e-9)
    # with the stratospheric layer the tropospheric part alone is 0.3
    o2 = aerosols.aerosol_optics("rural", H, WL, aod550=0.3)
    trop_ext = o2.scattering_by_regime[0] + o.absorption  # o has the same troposphere and no stratosphere
    assert column(trop_ext)[J550] == pytest.approx(0.3, rel=5e-3)
    assert o2.optical_depth[J550] == pytest.approx(0.3 + 0.005, rel=5e-3)
    assert o2.stratospheric_aod550 == pytest.approx(0.005)
    # a coarse, uneven grid and an off-grid wavelength list
    h = np.array([0.0, 200.0, 1000.0, 3000.0, 8000.0, 15000.0, 30000.0, 100000.0])
    o3 = aerosols.aerosol_optics("desert", h, [450.0, 550.0, 701.3], aod550=0.3, stratospheric="none")
    assert column(o3.scattering_by_regime.sum(axis=0) + o3.absorption, h)[1] == pytest.approx(0.3, rel=5e-3)
    # zero is allowed
    o4 = aerosols.aerosol_optics("urban", H, WL, aod550=0.0, stratospheric="none")
    assert np.all(o4.scattering_by_regime == 0) and np.all(o4.absorption == 0)


def test_turbidity_round_trip():
    tau_r = 0.0971
    for t in (1.0, 2.0, 3.5, 10.0):
        o = aerosols.aerosol_optics("urban", H, WL, turbidity=t, rayleigh_optical_depth_550=tau_r)
        assert (tau_r + o.aod550) / tau_r == pytest.approx(t, rel=1e-9)
    o = aerosols.aerosol_optics("urban", H, WL, turbidity=3.0, rayleigh_optical_depth_550=tau_r,
                                stratospheric="none")
    ext = o.scattering_by_regime.sum(axis=0) + o.absorption
    assert (tau_r + column(ext)[J550]) / tau_r == pytest.approx(3.0, rel=5e-3)
    same = aerosols.aerosol_optics("urban", H, WL, aod550=2 * tau_r, stratospheric="none")
    assert np.allclose(same.scattering_by_regime, o.scattering_by_regime, rtol=1e-12)
    # without the argument the standard-atmosphere Rayleigh depth is used
    o_default = aerosols.aerosol_optics("urban", H, WL, turbidity=2.0)
    assert 0.08 < o_default.aod550 < 0.11


def test_angstrom_fine_versus_coarse():
    # the OPAC model's types (the paper's: tests/test_aerosols_paper.py)
    alpha = {n: aerosols.aerosol_optics(n, H, WL, stratospheric="none", model="opac").angstrom_exponent
             for n in FINE + COARSE}
    for fine in FINE:
        for coarse in COARSE:
            assert alpha[fine] > alpha[coarse] + 0.5, (fine, coarse, alpha)
    assert all(alpha[n] > 1.0 for n in FINE)  # fine-mode (pollution/sulfate) aerosol
    assert all(alpha[n] < 0.8 for n in COARSE)  # dust and sea salt
    # the exponent is the 440/675 nm slope of the column AOD
    o = aerosols.aerosol_optics("rural", H, WL, stratospheric="none")
    tau = dict(zip(WL, o.optical_depth))
    assert o.angstrom_exponent == pytest.approx(-np.log(tau[440.0] / tau[675.0]) / np.log(440 / 675), rel=1e-9)


def test_single_scattering_albedo():
    # the OPAC model's types (the paper's: tests/test_aerosols_paper.py)
    ssa = {n: aerosols.aerosol_optics(n, H, WL, stratospheric="none", model="opac").single_scattering_albedo[J550]
           for n in ("maritime_clean", "urban", "rural", "polar_antarctic")}
    assert ssa["maritime_clean"] > 0.95
    assert ssa["polar_antarctic"] > 0.95  # sulfate
    assert ssa["urban"] < 0.8 and ssa["urban"] < ssa["rural"] < ssa["maritime_clean"]  # soot


def test_none_gives_zero():
    o = aerosols.aerosol_optics("none", H, WL, stratospheric="none")
    assert np.all(o.scattering_by_regime == 0) and np.all(o.absorption == 0) and np.all(o.optical_depth == 0)
    assert o.aod550 == 0 and o.angstrom_exponent == 0
    assert np.allclose(mie_lookup.phase_integral(o.phase, o.angles_deg, axis=1), 1.0, atol=1e-12)
    # "none" empties the troposphere only; the stratospheric layer is chosen separately
    o2 = aerosols.aerosol_optics("NONE", H, WL)
    assert np.all(o2.scattering_by_regime[0] == 0) and o2.stratospheric_aod550 == pytest.approx(0.005)


def test_stratospheric_choices():
    bg = aerosols.aerosol_optics("none", H, WL)
    vo = aerosols.aerosol_optics("none", H, WL, stratospheric="Volcanic")
    assert bg.optical_depth[J550] == pytest.approx(0.005, rel=5e-3)
    assert vo.optical_depth[J550] == pytest.approx(0.1, rel=5e-3)
    vo2 = aerosols.aerosol_optics("none", H, WL, stratospheric="volcanic", stratospheric_aod550=0.3)
    assert vo2.optical_depth[J550] == pytest.approx(0.3, rel=5e-3)
    # the layer is in the stratosphere
    k = int(np.argmax(vo.scattering_by_regime[1, :, J550]))
    assert 18000 < H[k] < 26000
    assert vo.scattering_by_regime[1, 0, J550] < 1e-6 * vo.scattering_by_regime[1, k, J550]


def test_case_insensitive_names_and_aliases():
    a = aerosols.aerosol_optics("URBAN", H, WL)
    b = aerosols.aerosol_optics("urban", H, WL)
    assert a.aerosol_type == "urban" and np.array_equal(a.scattering_by_regime, b.scattering_by_regime)
    assert aerosols.resolve_type("Continental_Average", model="opac") == "rural"
    assert aerosols.resolve_type("Antarctic") == "polar_antarctic"


@pytest.mark.parametrize(
    "kwargs, parameter",
    [
        ({"aerosol_type": "smog"}, "aerosol_type"),
        ({"aerosol_type": "volcanic"}, "aerosol_type"),  # stratospheric, not a tropospheric type
        ({"aod550": 11.0}, "aod550"),
        ({"aod550": -0.1}, "aod550"),
        ({"aod550": float("nan")}, "aod550"),
        ({"turbidity": 0.5}, "turbidity"),
        ({"turbidity": 65.0}, "turbidity"),
        ({"aod550": 0.1, "turbidity": 2.0}, "aod550"),
        ({"stratospheric": "heavy"}, "stratospheric"),
        ({"stratospheric_aod550": 3.0}, "stratospheric_aod550"),
        ({"altitudes_m": [0.0, 1000.0, 500.0]}, "altitudes_m"),
        ({"altitudes_m": [0.0]}, "altitudes_m"),
        ({"wavelengths_nm": [300.0]}, "wavelengths"),
        ({"turbidity": 2.0, "rayleigh_optical_depth_550": -1.0}, "rayleigh_optical_depth_550"),
    ],
)
def test_bad_inputs_name_the_parameter(kwargs, parameter):
    args = {"aerosol_type": "rural", "altitudes_m": H, "wavelengths_nm": WL}
    args.update(kwargs)
    with pytest.raises(SkymodelInputError) as e:
        aerosols.aerosol_optics(**args)
    assert e.value.parameter == parameter
    if parameter == "aerosol_type":
        assert "urban" in str(e.value) and "none" in str(e.value)


def test_off_grid_wavelengths_are_linear_in_wavelength():
    o = aerosols.aerosol_optics("desert", H, [550.0, 552.0, 555.0])
    s = o.scattering_by_regime[0, 0]
    assert s[1] == pytest.approx(0.6 * s[0] + 0.4 * s[2], rel=1e-12, abs=0)
    p = o.phase[0]
    assert np.allclose(p[:, 1], (0.6 * p[:, 0] * s[0] + 0.4 * p[:, 2] * s[2]) / s[1], rtol=1e-3)


# ------------------------------------------------------------------------------- the lookup


def test_lookup_grids():
    lk = lookup()
    assert np.array_equal(lk["wavelengths_nm"], WL)
    assert np.array_equal(lk["angles_deg"], mie_lookup.default_angles_deg())
    assert lk["angles_deg"][0] == 0 and lk["angles_deg"][-1] == 180 and lk["angles_deg"].size <= 400
    assert sorted(map(str, lk["components"])) == sorted(aerosols.components())
    assert np.all(lk["sca"] <= lk["ext"] * (1 + 1e-12)) and np.all(lk["sca"] > 0)


def test_lookup_reproduces():
    lk = lookup()
    names = [str(n) for n in lk["components"]]
    wl = [400.0, 550.0, 700.0]
    cols = [int(np.flatnonzero(WL == w)[0]) for w in wl]
    new = mie_lookup.build_tables(["soot", "sulfate"], wl)
    for i, name in enumerate(["soot", "sulfate"]):
        c = names.index(name)
        for key in ("ext", "sca", "g", "phase"):
            old = lk[key][c][..., cols]
            assert np.allclose(new[key][i], old, rtol=1e-6, atol=0), (name, key)


def test_size_integral_against_miepython():
    miepython = pytest.importorskip("miepython")
    # water-soluble component at 550 nm: independent integral over an even ln r grid with miepython
    # (which uses m = n - ik)
    comp = mie_lookup.components_table()["water_soluble"]
    m = mie_lookup.refractive_index("water_soluble", [550.0])[0]
    r_mod, sigma = comp["r_mod_um"], comp["sigma"]
    u = np.linspace(np.log(r_mod) - 6 * np.log(sigma), np.log(r_mod) + 9 * np.log(sigma), 6000)
    r = np.exp(u)
    qext = miepython.efficiencies_mx(np.conj(m), 2 * np.pi * r / 0.55)[0]
    dn = aerosols.lognormal_number_distribution(r, 1.0, r_mod, sigma)
    c_ext = trapezoid(qext * np.pi * (r * 1e-6) ** 2 * dn, u)
    lk = lookup()
    c = [str(n) for n in lk["components"]].index("water_soluble")
    assert lk["ext"][c, J550] / c_ext == pytest.approx(1.0, rel=1e-3, abs=0)  # (values ~4e-15 m^2)
