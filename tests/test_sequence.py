"""One multiple-scattering solve shared by the frames of a sequence (issue #19)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from skymodel import Atmosphere, scene
from skymodel.render.cameras import make_camera
from skymodel.render.marcher import SkyMarcher, optics_key, solve_sky
from skymodel.render.quality import quality_settings
from skymodel.errors import SkymodelInputError
from skymodel.render.sequence import SolutionCache, render_frame, render_frame_reduced
from skymodel.render.sky import render_sky, render_sky_reduced

# small tables so that the test is quick; the sharing does not depend on their size
SETTINGS = replace(quality_settings("preview"), table_altitudes=10, table_mu=12, table_phi=6, table_mus=10,
                   table_steps=16, sun_table_altitudes=24, sun_table_x=32, sun_table_steps=32, grid_zenith=16,
                   grid_zenith_ground=6, grid_azimuth=9, max_orders=4)
WL = np.linspace(400.0, 700.0, 7)


def _profile(sun=None, day=172):
    prof = Atmosphere(location="zaragoza", month=6, day_of_year=day, n_altitudes=64).optical_profile(WL)
    if sun is not None and sun.earth_sun_distance_au != 1.0:
        prof = replace(prof, solar_irradiance=prof.solar_irradiance / sun.earth_sun_distance_au**2)
    return prof


def test_three_frames_equal_three_independent_renders():
    cam = make_camera("equirectangular", 16, 8, n_wavelengths=WL.size)
    cache = SolutionCache()
    for local in ("2026-06-21T19:00", "2026-06-21T21:00", "2026-06-21T21:40"):
        sun = scene.place_sun(41.65, -0.88, local, timezone="Europe/Madrid")
        prof = _profile(sun)
        alone = render_sky(prof, cam, sun.elevation_deg, sun.azimuth_deg, 0.0, SETTINGS, solutions=False)  # own solve
        frame = render_frame(prof, cam, sun.elevation_deg, sun.azimuth_deg, 0.0, SETTINGS, cache=cache)
        # the same arithmetic on the same arrays: equal to the bit, not only to round-off
        assert np.array_equal(alone.radiance, frame.radiance), local
        assert np.array_equal(alone.sun_irradiance, frame.sun_irradiance)
    assert cache.stats["solves"] == 1 and cache.stats["memory_hits"] == 2


def test_the_solution_ignores_the_sun_and_the_solar_scale_but_not_the_optics():
    prof = _profile()
    sol = solve_sky(prof, SETTINGS)
    brighter = replace(prof, solar_irradiance=prof.solar_irradiance * 1.03)
    assert optics_key(brighter, SETTINGS) == sol.key
    m = SkyMarcher(brighter, 5.0, 250.0, 0.0, SETTINGS, solution=sol)
    assert m.timings["reused_solution"] and m.field is sol.field
    winter = _profile(day=355)  # another ozone column: another solve
    assert optics_key(winter, SETTINGS) != sol.key
    with pytest.raises(ValueError, match="another optical profile"):
        SkyMarcher(winter, 5.0, 250.0, 0.0, SETTINGS, solution=sol)


def test_disk_cache_round_trip_and_a_corrupt_file_is_solved_again(tmp_path):
    prof = _profile()
    first = SolutionCache(tmp_path)
    sol = first.get(prof, SETTINGS)
    path = first.path(sol.key)
    assert path.is_file() and not list(tmp_path.glob("*.tmp"))
    again = SolutionCache(tmp_path)
    loaded = again.get(prof, SETTINGS)
    assert again.stats["disk_hits"] == 1 and again.stats["solves"] == 0
    assert np.array_equal(loaded.field.source, sol.field.source)
    path.write_bytes(path.read_bytes()[:100])  # truncated
    third = SolutionCache(tmp_path)
    third.get(prof, SETTINGS)
    assert third.stats["corrupt"] == 1 and third.stats["solves"] == 1
    assert SolutionCache(tmp_path).get(prof, SETTINGS) is not None  # rewritten, readable


def test_a_solution_stored_by_other_code_is_not_read(tmp_path, monkeypatch):
    """The cache file's name carries skymodel.render.provenance.package_tag: after any change to
    the package's code or data (the optics key, profile and settings, would not see one) the
    old file is left alone and the sky solved again."""
    from skymodel.render import provenance

    prof = _profile()
    first = SolutionCache(tmp_path)
    sol = first.get(prof, SETTINGS)
    assert provenance.package_tag() in first.path(sol.key).name
    monkeypatch.setattr(provenance, "package_tag", lambda: "0123456789")
    other = SolutionCache(tmp_path)
    other.get(prof, SETTINGS)
    assert other.stats["disk_hits"] == 0 and other.stats["solves"] == 1
    assert len(list(tmp_path.glob("solution-v*.pickle"))) == 2


def test_reduced_frames_share_the_solve_and_bad_input_is_refused_before_it():
    cam = make_camera("equirectangular", 16, 8, n_wavelengths=WL.size)
    prof = _profile()
    cache = SolutionCache()

    def reduce(rad, wl):
        return rad[:, [1, 3, 5]]

    for el in (12.0, -3.0):
        alone, irr_a, _ = render_sky_reduced(prof, cam, el, reduce, 3, 250.0, 0.0, SETTINGS, band_pixels=50,
                                             solutions=False)
        frame, irr_f, info = render_frame_reduced(prof, cam, el, reduce, 3, 250.0, 0.0, SETTINGS, band_pixels=50,
                                                  cache=cache)
        assert np.array_equal(alone, frame) and np.array_equal(irr_a, irr_f)
    assert cache.stats["solves"] == 1 and info["solve_reused"]
    with pytest.raises(SkymodelInputError, match="sun_elevation"):
        render_frame(prof, cam, -19.0, 180.0, 0.0, SETTINGS, cache=cache)
    assert cache.stats["solves"] == 1



def test_memory_cache_is_safe_under_threads(monkeypatch):
    """The add-on reads the cache from a new build's thread while a cancelled build's thread
    may store into it: with keep=1 and two keys alternating, every get returns the solution
    of its own key and nothing raises. The dictionary's move_to_end sleeps, which widens the
    window in which a get without the lock (check, move, read) lost its key to the other
    thread's eviction (KeyError in 3 of 3 runs without the lock)."""
    import threading
    import time as _time
    from collections import OrderedDict

    import skymodel.render.sequence as seq

    class Sol:
        def __init__(self, key):
            self.key = key

    class SlowDict(OrderedDict):
        def move_to_end(self, key, last=True):
            _time.sleep(0.0005)
            super().move_to_end(key, last)

    monkeypatch.setattr(seq, "optics_key", lambda profile, s: profile)
    monkeypatch.setattr(seq, "solve_sky", lambda profile, s, progress=None: Sol(profile))
    cache = SolutionCache(keep=1)
    cache._memory = SlowDict()
    errors, wrong = [], []

    def work(keys):
        try:
            for k in keys:
                if cache.get(k, "preview").key != k:
                    wrong.append(k)
        except Exception as exc:  # the failure this test looks for
            errors.append(exc)

    threads = [threading.Thread(target=work, args=(["a", "a", "b"] * 100,)),
               threading.Thread(target=work, args=(["b", "b", "a"] * 100,))]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors and not wrong, (errors[:1], wrong[:3])
    assert cache.stats["memory_hits"] + cache.stats["solves"] == 600
