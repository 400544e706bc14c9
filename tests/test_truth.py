"""The statistics of the accuracy-against-truth benchmark (skymodel.validation.truth):
median and worst relative error with their Monte Carlo noise, the exclusion of the sun's
disc and first 2 degrees of aureole, the view set, the path budget; bench_truth's committed runs
and its planning of rounds. No tracing here but one two-view run of its parallel rounds."""

from __future__ import annotations

import importlib.util
import os
import sys

import numpy as np
import pytest

from skymodel.errors import SkymodelInputError
from skymodel.render.rays import sun_direction
from skymodel.validation.truth import (EXCLUDE_DEG, MEDIAN_NOISE_FACTOR, angle_to_sun_deg, paths_for_noise,
                                       truth_statistics, view_directions, view_set, which_is_closer)

BENCHMARKS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "benchmarks")


def _bench_truth(monkeypatch=None):
    """benchmarks/bench_truth.py as a module; with ``monkeypatch`` also registered in
    sys.modules for the test's duration (a process pool pickles its task by module name)."""
    spec = importlib.util.spec_from_file_location("bench_truth", os.path.join(BENCHMARKS, "bench_truth.py"))
    bt = importlib.util.module_from_spec(spec)
    if monkeypatch is not None:
        monkeypatch.setitem(sys.modules, "bench_truth", bt)
    spec.loader.exec_module(bt)
    return bt


def _two_view_scene(bt, cache):
    """bench_truth's rural 60 deg scene cut to its first two views (no committed run matches
    them, so a test traces its own), caching under ``cache``."""
    sc = bt.Scene("rural", 60.0, cache)
    sc.views, sc.dirs = sc.views[:2], sc.dirs[:2]
    return sc


def test_statistics_of_known_errors():
    mc = np.ones((5, 2))
    marcher = mc * (1.0 + np.array([[0.01, -0.02], [-0.03, 0.0], [0.002, 0.004], [0.5, 0.5], [-0.004, 0.001]]))
    se = np.full((5, 2), 0.002)
    se[3] = 0.5  # the excluded direction must not count anywhere
    angle = np.array([40.0, 90.0, 10.0, 1.0, 120.0])
    st = truth_statistics(marcher, mc, se, angle)
    assert np.all(st["n"] == 4)
    np.testing.assert_allclose(st["median"], [np.median([0.01, 0.03, 0.002, 0.004]), np.median([0.02, 0, 0.004, 0.001])])
    np.testing.assert_allclose(st["median_signed"], [np.median([0.01, -0.03, 0.002, -0.004]),
                                                     np.median([-0.02, 0.0, 0.004, 0.001])])
    np.testing.assert_allclose(st["worst"], [-0.03, -0.02])  # signed, the largest |rel|
    np.testing.assert_array_equal(st["worst_index"], [1, 0])
    np.testing.assert_allclose(st["worst_noise"], [0.002, 0.002])
    np.testing.assert_allclose(st["median_noise"], MEDIAN_NOISE_FACTOR * 0.002 / 2.0)
    np.testing.assert_allclose(st["noise_max"], 0.002)
    np.testing.assert_allclose(st["mean_signed"], [np.mean([0.01, -0.03, 0.002, -0.004]),
                                                   np.mean([-0.02, 0.0, 0.004, 0.001])])
    np.testing.assert_allclose(st["mean_noise"], 0.002 / 2.0)


def test_noise_is_relative_to_the_truth_and_falls_as_one_over_sqrt_n():
    rng = np.random.default_rng(0)
    mc = rng.uniform(0.5, 2.0, (64, 3))
    se = 0.01 * mc
    a = truth_statistics(mc, mc, se)
    np.testing.assert_allclose(a["median"], 0.0)
    np.testing.assert_allclose(a["median_noise"], MEDIAN_NOISE_FACTOR * 0.01 / 8.0)
    b = truth_statistics(mc[:16], mc[:16], se[:16])
    np.testing.assert_allclose(b["median_noise"], 2.0 * a["median_noise"])


def test_median_noise_matches_the_spread_of_sample_medians():
    """1.2533 sigma / sqrt(N) is what repeated noisy truths actually do to the median."""
    rng = np.random.default_rng(1)
    n, sigma = 31, 0.004
    bias = rng.uniform(-0.01, 0.01, n)  # the marcher's own errors, fixed
    meds = [np.median(bias + sigma * rng.standard_normal(n)) for _ in range(4000)]
    st = truth_statistics(np.ones((n, 1)), np.ones((n, 1)), np.full((n, 1), sigma))
    # the spread depends on the density of the biases at their median; for biases spread
    # much wider than sigma the formula is an upper bound within a factor ~2
    assert np.std(meds) < 2.0 * st["median_noise"][0]


def test_exclusion_of_the_disc_and_aureole():
    sun = sun_direction(20.0, 180.0)
    d = np.stack([sun, view_directions([[70.0, 2.0]])[0], view_directions([[70.0, 10.0]])[0]])
    ang = angle_to_sun_deg(d, sun)
    assert ang[0] == pytest.approx(0.0, abs=1e-6)
    assert ang[1] == pytest.approx(2.0 * np.sin(np.radians(70.0)), abs=0.01)  # ~1.88 deg, inside
    mc = np.ones((3, 1))
    marcher = np.array([[10.0], [2.0], [1.01]])
    st = truth_statistics(marcher, mc, 0.001 * mc, ang)
    assert st["n"][0] == 1 and st["worst"][0] == pytest.approx(0.01)
    with pytest.raises(SkymodelInputError, match="angle_to_sun"):
        truth_statistics(marcher[:2], mc[:2], mc[:2], ang[:2])


@pytest.mark.parametrize("elev", [60.0, 20.0, 5.0, 0.0, -4.0])
def test_view_set_is_sky_only_and_outside_the_excluded_cone(elev):
    v = view_set(elev)
    assert 20 <= len(v) <= 40
    assert np.all((v[:, 0] >= 0.0) & (v[:, 0] <= 89.0))
    assert len(np.unique(np.round(v, 3), axis=0)) == len(v)
    ang = angle_to_sun_deg(view_directions(v), sun_direction(elev, 180.0))
    assert np.all(ang > EXCLUDE_DEG)
    assert np.any(ang < 12.0)  # the aureole beyond 2 degrees is measured
    assert [0.0, 0.0] in v.tolist()


def test_which_is_closer_counts_only_what_the_truth_can_tell():
    mc = np.ones((5, 1))
    se = np.full((5, 1), 0.001)
    a = np.array([[1.010], [1.002], [0.990], [1.0004], [1.5]])
    b = np.array([[1.005], [1.003], [1.004], [0.9996], [1.5]])
    # row 0: midpoint 1.0075, 7.5 se above the truth: b closer; row 1: midpoint 1.0025, a closer;
    # row 2: midpoint 0.997, 3 se below: b closer; row 3: a and b 0.4 se either side, unresolved
    # (equally close); row 4: inside the excluded cone around the sun
    angle = np.array([30.0, 60.0, 90.0, 120.0, 1.0])
    c = which_is_closer(a, b, mc, se, angle)
    assert c == dict(compared=4, resolved=3, b_closer=2, a_closer=1)
    assert which_is_closer(a, a, mc, se)["resolved"] == 0  # equal marchers: neither is closer
    assert which_is_closer(b, a, mc, se, angle)["a_closer"] == 2  # the roles swap
    # a noisy truth: b truly closer everywhere (0.2 % against 2 % off, truth noise 0.3 %);
    # where the truth decides, it must name b nearly always, and a marcher pair equally far on
    # either side of the truth is resolved only at the 2-sigma rate, as often one way as the other
    rng = np.random.default_rng(5)
    t = np.ones((4000, 1))
    noisy = t * (1.0 + 0.003 * rng.standard_normal(t.shape))
    c = which_is_closer(t * 1.02, t * 1.002, noisy, np.full(t.shape, 0.003))
    assert c["resolved"] > 0.9 * t.size and c["a_closer"] <= 0.001 * t.size
    c = which_is_closer(t * 0.995, t * 1.005, noisy, np.full(t.shape, 0.003))
    assert 0.03 * t.size < c["resolved"] < 0.065 * t.size
    assert abs(c["a_closer"] - c["b_closer"]) < 0.4 * c["resolved"]
    with pytest.raises(SkymodelInputError, match="sigmas"):
        which_is_closer(a, b, mc, se, sigmas=0.0)
    with pytest.raises(SkymodelInputError, match="shapes"):
        which_is_closer(a[:2], b, mc, se)


def test_bad_inputs():
    with pytest.raises(SkymodelInputError, match="mc"):
        truth_statistics(np.ones((2, 1)), np.zeros((2, 1)), np.ones((2, 1)))
    with pytest.raises(SkymodelInputError):
        truth_statistics(np.ones((2, 1)), np.ones((3, 1)), np.ones((3, 1)))
    with pytest.raises(SkymodelInputError, match="sun_elevation"):
        view_set(95.0)
    with pytest.raises(SkymodelInputError, match="target_rel"):
        paths_for_noise(np.ones((2, 1)), 100, 0.0)


def test_paths_for_noise():
    rel = np.array([[0.02, 0.01], [0.005, 0.004], [0.1, 0.1]])
    n = paths_for_noise(rel, 1000, 0.005, min_paths=2000, max_paths=50_000)
    np.testing.assert_array_equal(n, [16000, 2000, 50000])


def test_committed_truth_runs_are_read_when_the_cache_has_none(tmp_path):
    """benchmarks/truth/ keeps the Monte Carlo runs of the report (a few kB each): each holds
    its views, positive means and the noise the benchmark asks for (sun 60 and 20: <= 0.65 %
    per direction), and bench_truth finds them with an empty cache."""
    import glob

    files = sorted(glob.glob(os.path.join(BENCHMARKS, "truth", "mc_*.npz")))
    assert len(files) >= 4
    for f in files:
        with np.load(f) as z:
            assert np.all(z["mean"] > 0) and np.all(z["n"] > 0) and z["views"].shape == (z["mean"].shape[0], 2)
            if "_60_" in f or "_20_" in f:
                assert np.max(z["se"] / z["mean"]) <= 0.0065, f
            if "_5_" in f:  # topped up to 0.52 % (2026-11-27)
                assert np.max(z["se"] / z["mean"]) <= 0.0055, f
            if "_0_" in f:  # sun 0: topped up to the rule (rural 2026-11-27, desert 2026-11-27 on 16 cores)
                assert np.max(z["se"] / z["mean"]) <= 0.005, f
            if "rural_-4_" in f:  # topped up to the rule (0.5 % per direction)
                assert np.max(z["se"] / z["mean"]) <= 0.005, f
            if "desert_-4_" in f:  # short of the rule: the dim horizon views' spread (docs/accuracy.md)
                assert np.median(z["se"] / z["mean"]) <= 0.006, f
                # traced with the proxy's roulette weighed by the sun guide (2f6ebe8, seeds from
                # 300001); the run before it read low at 550/650 nm (notebooks/proxy_tail)
                assert z["seeds"].min() >= 300001, f
            assert np.unique(z["seeds"]).size == z["seeds"].size, f  # pooled runs: independent seeds
    bt = _bench_truth()
    _, mc = bt.Scene("desert", 60.0, str(tmp_path)).load_mc()
    assert mc is not None and mc["mean"].shape == (view_set(60.0).shape[0], 3)
    # a run's file records its estimator and sun guide (--sun-guide overrides the table's)
    prof = bt.Scene("desert", -4.0, str(tmp_path)).mc_profile()
    assert bt.Scene("desert", -4.0, str(tmp_path)).mc_file(prof).endswith("_g0.2_proxy.npz")
    assert bt.Scene("desert", -4.0, str(tmp_path), "proxy", 0.0).mc_file(prof).endswith("_g0_proxy.npz")


def test_a_round_of_paths_serves_the_directions_furthest_from_the_target_first():
    """bench_truth's round planning: with the budget short, every direction's top-up is
    scaled down alike and the largest batch (the noisiest directions) runs first."""
    bt = _bench_truth()
    n = np.array([375_000, 375_000, 100_000, 100_000, 100_000])
    more = np.array([760_000, 700_000, 20_000, 30_000, 5_000])
    todo = more > 0.1 * n
    plenty = bt.plan_round(n, more, todo, 1e-6, 1e9)
    assert [r.tolist() for r, _ in plenty] == [[0, 1], [2, 3]] and [p for _, p in plenty] == [760_000, 30_000]

    def spent(plan, cost):
        planned = np.zeros(5)
        for rows, paths in plan:
            planned[rows] = paths
        return float(np.sum(planned * cost))

    left = 0.5 * 1e-3 * 1_510_000  # half of what the round needs
    short = bt.plan_round(n, more, todo, 1e-3, left)
    assert short[0][0].tolist() == [0, 1] and 340_000 <= short[0][1] <= 380_000
    # each batch runs at its largest count: that is within the budget too
    assert 0.95 * left <= spent(short, 1e-3) <= left
    assert all(p % 1000 == 0 for _, p in short)
    assert bt.plan_round(n, more, np.zeros(5, bool), 1e-6, 1e9) == []
    # each direction's own cost per path: the noisiest (grazing) directions cost 3x the
    # others; a round planned on the run's average cost overruns the budget, one planned on
    # the directions' own costs fills it
    cost = np.array([3e-3, 3e-3, 1e-3, 1e-3, 1e-3])
    left = 0.5 * float(np.sum(np.minimum(more, 4 * n) * cost))

    assert 0.95 * left <= spent(bt.plan_round(n, more, todo, cost, left), cost) <= left
    average = float(np.sum(cost * n) / n.sum())  # what the run's seconds / paths say
    assert spent(bt.plan_round(n, more, todo, average, left), cost) > 1.15 * left  # a fifth over


def test_a_parallel_round_pools_chunks_with_their_own_seeds(tmp_path, monkeypatch):
    """bench_truth mc --workers: each batch of a round is split into chunks of whole thousands
    of paths with seeds never used before, traced in forked processes and pooled; the
    pooled estimate agrees with a serial run of other seeds within their noise."""
    bt = _bench_truth(monkeypatch)
    tasks = bt.split_batches([(np.array([0, 1]), 7000), (np.array([2]), 1500)], 4, 11)
    assert [t[1] for t in tasks] == [2000, 2000, 2000, 1000, 1000, 1000]  # 7000 and 2000 (from 1500) shared
    assert [t[2] for t in tasks] == [11, 12, 13, 14, 15, 16]
    # a chunk takes at most CHUNK_S at the directions' cost per path (a long round is saved
    # and its budget checked chunk by chunk): 7000 paths of 2 directions at 0.05 s, 700 s
    cost = np.array([0.05, 0.05, 0.01])
    tasks = bt.split_batches([(np.array([0, 1]), 7000), (np.array([2]), 1500)], 1, 11, cost, chunk_s=300.0)
    assert [t[1] for t in tasks] == [3000, 2000, 2000, 2000] and [t[2] for t in tasks] == [11, 12, 13, 14]
    assert all(t[1] * 0.1 <= 300.0 for t in tasks[:3])

    runs = {}
    for workers in (1, 2):
        sc = _two_view_scene(bt, str(tmp_path / f"w{workers}"))
        _, mc = bt.run_mc(sc, 0.03, 6000, 1000, 60.0, log=lambda *_: None, workers=workers)
        assert np.all(mc["n"] > 1000) and len(set(mc["seeds"].tolist())) == mc["seeds"].size
        assert mc["seeds"].min() == bt.scene_seed_base("rural", 60.0)  # the scene's own block
        assert os.path.exists(sc.mc_file(sc.mc_profile()))
        runs[workers] = mc
    a, b = runs[1], runs[2]
    assert np.all(np.abs(a["mean"] - b["mean"]) < 5.0 * np.hypot(a["se"], b["se"]))


def test_every_scene_draws_from_a_block_of_seeds_of_its_own(monkeypatch):
    """bench_truth mc: a new run starts at its scene's seed block, so two scenes never trace a
    view with the same random numbers (their noise would be shared: the committed runs but
    desert -4 deg's, traced before 2026-11-30, all started at seed 1)."""
    bt = _bench_truth(monkeypatch)
    scenes = [(a, e) for a in bt.AEROSOLS for e in (-18.0, -4.0, -0.1, 0.0, 0.1, 5.0, 20.0, 60.0, 90.0)]
    bases = sorted(bt.scene_seed_base(a, e) for a, e in scenes)
    assert len(set(bases)) == len(scenes) and bases[0] >= 1
    assert min(np.diff(bases)) >= bt.SCENE_SEED_BLOCK  # whole blocks apart
    for bad in (200.0, 90.1, -18.1):
        with pytest.raises(ValueError, match="elevation"):
            bt.scene_seed_base("rural", bad)


def test_mc_with_workers_stops_at_the_budget_within_a_round(tmp_path, monkeypatch):
    """bench_truth mc --workers: the budget is checked after every chunk, as without workers,
    so a round whose chunks outrun it stops there (what finished is saved; the chunks still
    running are dropped) instead of running all its chunks."""
    import types

    bt = _bench_truth(monkeypatch)
    clock = types.SimpleNamespace(now=0.0)
    monkeypatch.setattr(bt, "time", types.SimpleNamespace(perf_counter=lambda: clock.now))

    def fake_chunk(task):  # a chunk traced at once (the pool's processes run this copy)
        rows, n, seed = task
        nw = bt._WORK["prof"].n_wavelengths
        return rows, n, seed, types.SimpleNamespace(radiance=np.ones((rows.size, nw)),
                                                    stderr=np.full((rows.size, nw), 1e-3), time_s=1.0)

    fake_chunk.__module__, fake_chunk.__qualname__ = "bench_truth", "_trace_chunk"
    monkeypatch.setattr(bt, "_trace_chunk", fake_chunk)
    merge, merged = bt._merge, []

    def merge_then_late(mc, rows, res, n, seed):  # the budget runs out with the first chunk
        merge(mc, rows, res, n, seed)
        merged.append(seed)
        if len(merged) == 2:  # the pilot, then the round's first chunk
            clock.now = 1e9

    monkeypatch.setattr(bt, "_merge", merge_then_late)

    sc = _two_view_scene(bt, str(tmp_path))
    tasks, split = [], bt.split_batches

    def split_and_record(*args, **kwargs):
        out = split(*args, **kwargs)
        tasks.extend(out)
        return out

    monkeypatch.setattr(bt, "split_batches", split_and_record)
    _, mc = bt.run_mc(sc, 0.01, 200000, 1000, 3600.0, log=lambda *_: None, workers=2)
    assert len(tasks) >= 2  # the round had more chunks than the one that finished in time
    assert len(merged) == 2 and mc["seeds"].size == 2
    assert bt.read_run(sc.mc_file(sc.mc_profile()))["seeds"].size == 2


def test_runs_traced_apart_pool_as_one_run_and_shared_seeds_are_refused():
    """bench_truth pool: two runs of one scene from disjoint seeds (``mc --seed-from``) pool
    into the estimate that merging their batches one by one gives; a seed used by both
    (the runs would not be independent) or other views are refused."""
    bt = _bench_truth()
    rng = np.random.default_rng(3)
    views = np.array([[80.0, 0.0], [60.0, 90.0], [30.0, 180.0]])

    class Res:
        def __init__(self, k):
            self.radiance, self.stderr, self.time_s = rng.random((k, 2)) + 1.0, 0.01 * rng.random((k, 2)), 2.0

    def empty():
        return dict(mean=np.zeros((3, 2)), se=np.zeros((3, 2)), n=np.zeros(3, dtype=np.int64),
                    seconds=np.float64(0.0), seeds=np.zeros(0, dtype=np.int64), views=views)

    batches = [(np.array([0, 1, 2]), 1000, 1, Res(3)), (np.array([1]), 3000, 2, Res(1)),
               (np.array([0, 2]), 2000, 100001, Res(2)), (np.array([2]), 5000, 100002, Res(1))]
    serial, a, b = empty(), empty(), empty()
    for rows, n, seed, res in batches:
        bt._merge(serial, rows, res, n, seed)
        bt._merge(a if seed < 100001 else b, rows, res, n, seed)
    pooled = bt.pool_runs(a, b)
    assert np.array_equal(pooled["n"], serial["n"]) and pooled["seconds"] == serial["seconds"] == 8.0
    np.testing.assert_allclose(pooled["mean"], serial["mean"], rtol=1e-12)
    np.testing.assert_allclose(pooled["se"], serial["se"], rtol=1e-12)
    c = empty()
    bt._merge(c, np.array([0]), Res(1), 1000, 2)
    with pytest.raises(ValueError, match="seeds"):
        bt.pool_runs(pooled, c)
    c["views"] = views[::-1]
    with pytest.raises(ValueError, match="views"):
        bt.pool_runs(empty(), c)


def test_the_march_cache_key_ignores_the_validation_wing_and_the_cli(tmp_path):
    """bench_truth keys cached marcher results by the renderer's sources: a change to the
    tracer (validation/) or the CLI keeps them, a change to the renderer re-marches."""
    bt = _bench_truth()
    root = tmp_path / "skymodel"
    for sub in ("render", "validation", "cli"):
        (root / sub).mkdir(parents=True)
        (root / sub / "m.py").write_text(f"X = '{sub}'\n")
    (root / "top.py").write_text("Y = 1\n")
    key = bt.sources_hash(str(root))
    for sub in ("validation", "cli"):
        (root / sub / "m.py").write_text("X = 'changed'\n")
        (root / sub / "new.py").write_text("Z = 2\n")
    assert bt.sources_hash(str(root)) == key
    (root / "render" / "m.py").write_text("X = 'changed'\n")
    assert bt.sources_hash(str(root)) != key
    (root / "render" / "m.py").write_text("X = 'render'\n")
    assert bt.sources_hash(str(root)) == key
    (root / "top.py").write_text("Y = 2\n")
    assert bt.sources_hash(str(root)) != key


def test_views_are_found_by_the_names_the_tables_print(tmp_path):
    """bench_truth names a view 'zenith/azimuth from the sun' (the tables' first column); the
    notebooks pick views by those names: rows in the scene's order, an unknown name refused
    with the scene's names rather than skipped."""
    bt = _bench_truth()
    assert bt.view_label((89.0, 4.899)) == "89/4.899" and bt.view_label(np.array([0.0, 0.0])) == "0/0"
    sc = bt.Scene("rural", 0.0, str(tmp_path))
    labels = [bt.view_label(v) for v in sc.views]
    assert len(set(labels)) == len(labels)  # the names tell the views apart
    pick = [labels[5], labels[2]]
    assert sc.view_rows(pick) == [2, 5] and sc.view_rows(",".join(pick)) == [2, 5]
    assert np.allclose(sc.views[sc.view_rows("89/4.899")[0]], (89.0, 4.899))
    with pytest.raises(KeyError, match="no view 89/3.*its views: 0/0"):
        sc.view_rows(["0/0", "89/3"])
