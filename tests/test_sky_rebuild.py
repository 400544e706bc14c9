"""Sun-only rebuilds reuse the multiple-scattering solution (issue #23, item 3): the
environment build through its cache folder (memory and disk), render_sky through the
process's shared cache; the images equal a fresh solve's."""

import numpy as np

from skymodel import Atmosphere
from skymodel.render import environment
from skymodel.render.cameras import make_camera
from skymodel.render.sequence import SolutionCache
from skymodel.render.sky import render_sky, shared_solutions
from skymodel.render.environment import render_environment


def test_environment_rebuild_with_another_sun_reuses_the_solve(tmp_path, monkeypatch):
    atm = Atmosphere(location="rural", month=6)
    monkeypatch.setattr(environment, "_SOLUTION_CACHES", {})
    kw = dict(quality="preview", width=32, cache_dir=tmp_path)
    _, first = render_environment(atm, 30.0, 180.0, **kw)
    cache = environment.solution_cache(tmp_path)
    assert cache.stats["solves"] == 1 and len(list((tmp_path / "solutions").glob("*.pickle"))) == 1
    rgb, second = render_environment(atm, 20.0, 170.0, **kw)
    assert cache.stats["solves"] == 1 and cache.stats["memory_hits"] == 1
    # a new session: the solution comes from the disk
    monkeypatch.setattr(environment, "_SOLUTION_CACHES", {})
    rgb_disk, _ = render_environment(atm, 20.0, 170.0, **dict(kw, cache_dir=tmp_path / "other"),
                                     solutions=SolutionCache(tmp_path / "solutions"))
    np.testing.assert_array_equal(rgb_disk, rgb)  # (a fresh solve gives the same: tests/test_sequence.py)


def test_render_sky_shares_the_solve_within_the_process():
    prof = Atmosphere(location="rural", month=6).optical_profile([450.0, 550.0, 650.0])
    cam = make_camera("fisheye", 12, n_wavelengths=3)
    cache = shared_solutions()
    before = dict(cache.stats)
    a = render_sky(prof, cam, 30.0, 180.0, quality="preview")
    b = render_sky(prof, cam, 10.0, 200.0, quality="preview")
    assert cache.stats["solves"] <= before["solves"] + 1
    assert cache.stats["memory_hits"] >= before["memory_hits"] + 1
    alone = render_sky(prof, cam, 10.0, 200.0, quality="preview", solutions=False)
    np.testing.assert_array_equal(b.radiance, alone.radiance)
    assert not np.array_equal(a.radiance, b.radiance)
