"""skymodel.wavelengths.spread_indices: the probe wavelengths of the peak paths and of the
solver's spherical correction, one rule for both."""
import numpy as np

from skymodel.wavelengths import default_wavelengths, spread_indices


def test_even_grid_every_step_and_both_ends():
    wl = default_wavelengths(5.0)
    np.testing.assert_array_equal(wl[spread_indices(wl, 50.0)], np.arange(380.0, 780.1, 50.0))
    # a step that does not divide the range: more probes, closer than the step
    got = wl[spread_indices(wl, 60.0)]
    assert got[0] == 380.0 and got[-1] == 780.0 and np.max(np.diff(got)) <= 60.0


def test_uneven_grid_takes_the_nearest_wavelength_to_each_target():
    wl = np.array([380.0, 420.0, 460.0, 500.0, 510.0, 520.0, 530.0, 560.0, 640.0, 700.0, 780.0])
    idx = spread_indices(wl, 100.0)
    targets = np.linspace(380.0, 780.0, 5)
    want = [int(np.argmin(np.abs(wl - t))) for t in targets]
    np.testing.assert_array_equal(idx, np.unique(want))
    # a tie (680 nm between 640 and 720, indices 3 and 4) goes to the even index
    tie = np.array([380.0, 480.0, 580.0, 640.0, 720.0, 780.0])
    assert tie[spread_indices(tie, 100.0)].tolist() == [380.0, 480.0, 580.0, 720.0, 780.0]


def test_few_wavelengths():
    assert spread_indices(np.array([550.0]), 50.0).tolist() == [0]
    assert spread_indices(np.array([450.0, 650.0]), 50.0).tolist() == [0, 1]
    # a step wider than the range: the two ends
    assert spread_indices(np.array([440.0, 550.0, 660.0]), 500.0).tolist() == [0, 2]
