"""skymodel.render.threads: the loops on threads, and numpy's BLAS held to one thread in them."""

import json
import os
import subprocess
import sys
import textwrap
import threading

import numpy as np
import pytest
from threadpoolctl import threadpool_info, threadpool_limits

from skymodel.render import threads
from skymodel.render.threads import chunks_in_threads, in_threads, one_blas_thread


def blas_threads() -> list[int]:
    return [lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas"]


@pytest.fixture
def two_blas_threads():
    if not blas_threads():
        pytest.skip("no BLAS library that threadpoolctl controls")
    with threadpool_limits(2, user_api="blas"):  # as on a 2-core machine, whatever this one has
        yield


def test_results_in_order_on_threads():
    assert in_threads(lambda i: i * i, range(7), 2) == [i * i for i in range(7)]
    seen = []
    chunks_in_threads(lambda own: seen.append(list(own)), range(0, 10, 2), 2)
    assert sorted(seen) == [[0, 4, 8], [2, 6]]


def test_blas_on_one_thread_inside_the_loops_only(two_blas_threads):
    inside = in_threads(lambda i: (np.ones((64, 64)) @ np.ones((64, 64)), blas_threads())[1], range(4), 2)
    assert all(set(t) == {1} for t in inside)
    assert set(blas_threads()) == {2}


class FakeController:
    """Stands in for threadpoolctl's controller: records the BLAS thread count it is given."""

    def __init__(self):
        self.threads = 2
        self.lib_controllers = []

    def limit(self, limits, user_api):
        assert user_api == "blas"
        before, self.threads = self.threads, limits
        controller = self

        class Limiter:
            def restore_original_limits(self):
                controller.threads = before

        return Limiter()


def test_concurrent_loops_share_one_limit(monkeypatch):
    # two loops from two threads, the first to start ending first: the limit must outlive it,
    # and the last one out gives BLAS its threads back (a fake controller: what OpenBLAS
    # reports when its count is set from several threads is its own business)
    fake = FakeController()
    monkeypatch.setitem(threads._blas, "controller", fake)
    monkeypatch.setitem(threads._blas, "modules", len(sys.modules))
    first_in, first_out, second_in = threading.Event(), threading.Event(), threading.Event()
    seen = []

    def first(_):
        first_in.set()
        second_in.wait(10)

    def second(_):
        second_in.set()
        first_out.wait(10)
        seen.append(fake.threads)

    a = threading.Thread(target=lambda: (in_threads(first, range(2), 2), first_out.set()))
    a.start()
    first_in.wait(10)
    b = threading.Thread(target=lambda: in_threads(second, range(2), 2))
    b.start()
    a.join(10)
    b.join(10)
    assert seen == [1, 1] and fake.threads == 2 and threads._blas["depth"] == 0


def test_limit_restored_after_an_error(two_blas_threads):
    with pytest.raises(RuntimeError):
        with one_blas_thread():
            assert set(blas_threads()) == {1}
            raise RuntimeError("in the loop")
    assert set(blas_threads()) == {2}


def test_limit_takes_on_a_background_thread_after_a_build_on_the_main_thread():
    """The add-on builds on a background thread, scripts and the CLI on the main one; OpenBLAS
    ignores a count set from another thread once the main thread has set one. In a fresh
    process (that state is the process's): a loop on the main thread, then one on a
    background thread, each sees every BLAS library on one thread (scipy's own OpenBLAS,
    loaded after the first loop, too), and both get their counts back after."""
    script = textwrap.dedent("""
        import json, threading
        import numpy as np
        from threadpoolctl import threadpool_info
        from skymodel.render.threads import in_threads

        def counts():
            return sorted(lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas")

        before = counts()
        seen = {"main": in_threads(lambda i: counts(), range(2), 2)}
        import scipy.linalg  # noqa: F401  (its own OpenBLAS)
        before_bg = counts()
        t = threading.Thread(target=lambda: seen.update(background=in_threads(lambda i: counts(), range(2), 2)))
        t.start()
        t.join()
        print(json.dumps(dict(seen, before=before, before_bg=before_bg, after=counts())))
    """)
    env = dict(os.environ, OPENBLAS_NUM_THREADS="2", OMP_NUM_THREADS="2")
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=120)
    assert out.returncode == 0, out.stderr
    r = json.loads(out.stdout.strip().splitlines()[-1])
    if not r["before"]:
        pytest.skip("no BLAS library that threadpoolctl controls")
    assert all(set(c) == {1} for c in r["main"]), r
    assert all(set(c) == {1} and len(c) == len(r["before_bg"]) for c in r["background"]), r
    assert r["after"] == r["before_bg"] and set(r["before_bg"]) == {2}, r


def test_solver_products_the_same_on_one_thread_and_two(monkeypatch):
    """The solver's transport (gathered_radiance) and the peak term (PeakDiffuse.add_source)
    split their wavelengths over SOLVER_THREADS threads, each with its own work arrays: the
    same numbers on one thread and on two, bit for bit, and the peak term the batched product
    it replaced (all wavelengths in one matmul)."""
    from skymodel import Atmosphere
    from skymodel.render import multiple_scattering as ms
    from skymodel.render import peak_diffuse as pdm
    from skymodel.render.medium import factor_medium

    wavelengths_nm = np.array([450.0, 500.0, 550.0, 650.0, 700.0])
    prof = Atmosphere(location="desert", month=6, aod550=0.5).optical_profile(wavelengths_nm)
    med = factor_medium(prof, 6.0)
    grid = ms.build_table_grid(prof, med, n_altitudes=5, n_mu=16, n_phi=4, n_mus=3)
    rng = np.random.default_rng(8)
    field = (grid.n_wl, grid.n_dir, grid.n_h, grid.n_mus)
    radiance = rng.random(field).astype(np.float32)
    n_rays = grid.n_h * grid.n_mu
    M = rng.random((grid.n_wl, n_rays, n_rays)).astype(np.float32)
    G = rng.random((grid.n_wl, n_rays)).astype(np.float32)
    lg = rng.random((grid.n_mus, grid.n_wl)).astype(np.float32)
    peak = pdm.PeakDiffuse(prof, med, grid)
    assert peak
    got = {}
    for n in (1, 2):
        monkeypatch.setattr(ms, "SOLVER_THREADS", n)
        monkeypatch.setattr(pdm, "SOLVER_THREADS", n)
        target = np.ones(field, dtype=np.float32)
        peak.add_source(radiance, target)
        got[n] = (ms.gathered_radiance(radiance, lg, M, G, grid), target)
    assert np.array_equal(got[1][0], got[2][0]) and np.array_equal(got[1][1], got[2][1])
    want = np.ones(field, dtype=np.float32).reshape(grid.n_wl, grid.n_mu, grid.n_phi, grid.n_h, grid.n_mus)
    flat = radiance.reshape(grid.n_wl, grid.n_mu, -1)
    for d, rows, sig in peak.terms:
        part = np.matmul(d, flat).reshape(grid.n_wl, d.shape[1], grid.n_phi, grid.n_h, grid.n_mus)
        want[:, rows] += part * sig[:, None, None, :, None]
    np.testing.assert_allclose(got[2][1], want.reshape(field), rtol=1e-6)
