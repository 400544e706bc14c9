"""The quality presets against an independent truth, the Monte Carlo path tracer (issue 23).

For rural AOD 0.2 and desert AOD 0.5 (the default paper aerosol model, month 6, the
locations' own ground albedo) at sun 60, 20, 5, 0 and -4 deg, the marcher at ``preview``,
``final`` and ``reference`` and :func:`~skymodel.validation.montecarlo.trace_radiance` see the
same optical profile and the same sky directions (:func:`skymodel.validation.truth.view_set`);
the table gives per scene, quality and wavelength the median and the worst |marcher / MC - 1|
with the noise the MC puts on each, and the marcher's time; a second table counts, per scene,
which of two presets is closer to the truth where its noise can tell (``which_is_closer``).
Statistics: :mod:`skymodel.validation.truth`.

The marcher's profile is 440-660 nm every 10 nm (so each preset's multiple-scattering
solver uses its own wavelength spacing: preview solves every 40 nm and interpolates), the
comparison at 450, 550, 650 nm; the MC traces those three. Both radiances are divided by
the profile's solar irradiance at the wavelength (the two profiles' band-averaged spectra
differ slightly; the transfer is linear in it).

MC: the NEE estimator with the sun up (``ESTIMATOR_SUN_UP``), the ``"proxy"`` estimator (line
integrals toward the sunlit air, densities from tabulated optical depths) below the
horizon (``ESTIMATOR_LOW_SUN``, sun < ``LOW_SUN_DEG``); ``--estimator`` overrides both. For
the desert with ``sun_guide`` (new directions partly drawn around the sun: the coarse dust's
forward peak, p(0) ~ 2e4 sr^-1, makes plain NEE heavy-tailed). Paths per direction from a pilot, for a relative standard error of
``--target-se`` (default 0.5 %) in every direction, capped by ``--max-paths``. Results are
cached under ``--cache`` (default .cache/truth/), keyed by the scene, the views and the
profile, and grow: a re-run adds paths where the target is not met yet. Runs copied into
``benchmarks/truth/`` (committed) are read when the cache has none of a scene, so
``report`` works from a fresh checkout after ``march`` (an ``mc`` run grows such a run
and writes it to the cache). Each scene's run draws from a block of seeds of its own
(``scene_seed_base``; the committed runs, traced before that, all but desert -4 deg's from seed 1).

    nice -n 5 python benchmarks/bench_truth.py mc --scenes all           # trace (cached, resumable)
    OMP_NUM_THREADS=1 python benchmarks/bench_truth.py mc --scenes desert:0 --workers 16   # a process a core
    python benchmarks/bench_truth.py mc --scenes desert:-4 --seed-from 400001 --cache /elsewhere  # meanwhile,
    python benchmarks/bench_truth.py pool --scenes desert:-4 --runs /elsewhere/mc_desert_-4_....npz  # then pool
    nice -n 5 python benchmarks/bench_truth.py march --scenes all        # the presets (cached)
    python benchmarks/bench_truth.py report --write-docs                 # docs/accuracy.md + img/
    python benchmarks/bench_truth.py pilot --scenes desert:20            # per-path noise and time
    python benchmarks/bench_truth.py views --scenes rural:20             # every view's error, per preset
    nice -n 5 python benchmarks/bench_truth.py knobs --scenes rural:20 --base final \
        --variants "table_mu=64;table_phi=48;table_altitudes=48;exact=1"  # one knob at a time vs MC

Scenes: ``all`` or a comma list of ``<aerosol>:<sun elevation>``.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import sys
import time

import numpy as np

_HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:0] = [_HERE, os.path.join(_HERE, "..")]

from common import git_revision, machine  # noqa: E402

from skymodel import Atmosphere  # noqa: E402
from skymodel.render.marcher import SkyMarcher  # noqa: E402
from skymodel.render.quality import QUALITIES  # noqa: E402
from skymodel.render.rays import sun_direction  # noqa: E402
from skymodel.validation.montecarlo import trace_radiance  # noqa: E402
from skymodel.validation.truth import (CLOSER_SIGMAS, EXCLUDE_DEG, angle_to_sun_deg,  # noqa: E402
                                       paths_for_noise, truth_statistics, view_directions, view_set,
                                       which_is_closer)

AEROSOLS = {"rural": 0.2, "desert": 0.5}
SUN_ELEVATIONS = (60.0, 20.0, 5.0, 0.0, -4.0)
MONTH = 6
SUN_AZIMUTH = 180.0
MC_WAVELENGTHS_NM = (450.0, 550.0, 650.0)
MARCH_WAVELENGTHS_NM = tuple(np.arange(440.0, 661.0, 10.0))
#: sun_guide of trace_radiance per aerosol (0: plain NEE); the "proxy" estimator: the same
#: (desert -4 with none: single paths carry 47-75 % of a direction's mean at 550 nm after
#: 14 000 paths, the other directions' means 3-15 % low; with 0.2 no such path, projection
#: to 0.5 % ~7x shorter, 0.4 no better than 0.2 within the noise: docs/accuracy.md)
SUN_GUIDE = {"rural": 0.0, "desert": 0.2}
SUN_GUIDE_PROXY = {"rural": 0.0, "desert": 0.2}
#: trace_radiance's estimator per scene: NEE with the sun up and on the horizon, "proxy"
#: below LOW_SUN_DEG (measured: docs/accuracy.md, "A cheaper estimator for the twilight
#: scenes": 5.6-8.5x faster than NEE at -4 deg, no faster at 0 deg)
ESTIMATOR_SUN_UP, ESTIMATOR_LOW_SUN, LOW_SUN_DEG = "nee", "proxy", 0.0
QUALITY_NAMES = ("preview", "final", "reference")
TOL_MEDIAN, TOL_WORST = 0.005, 0.015
DOC = os.path.join(_HERE, "..", "docs", "accuracy.md")
#: The Monte Carlo runs kept in git (copies of the cache's mc_*.npz, a few kB each), read
#: when ``--cache`` has no run of a scene: the report regenerates without re-tracing.
TRUTH_DIR = os.path.join(_HERE, "truth")
BEGIN = "<!-- BEGIN generated by benchmarks/bench_truth.py -->"
END = "<!-- END generated by benchmarks/bench_truth.py -->"


def scenes_from(arg):
    if arg == "all":
        return [(a, e) for a in AEROSOLS for e in SUN_ELEVATIONS]
    out = []
    for item in arg.split(","):
        a, e = item.split(":")
        out.append((a, float(e)))
    return out


def atmosphere(aerosol):
    return Atmosphere(location=aerosol, month=MONTH, aod550=AEROSOLS[aerosol])


def _profile_hash(prof):
    h = hashlib.sha1()
    for arr in (prof.wavelengths_nm, prof.altitudes_m, prof.aerosol_phase, prof.solar_irradiance, prof.ground_albedo):
        h.update(np.ascontiguousarray(np.asarray(arr, dtype=float)).tobytes())
    s = prof.sample(np.asarray(prof.altitudes_m, dtype=float))
    for arr in (s.rayleigh_scattering, s.aerosol_scattering_by_regime, s.ozone_absorption, s.aerosol_absorption):
        h.update(np.ascontiguousarray(arr).tobytes())
    return h.hexdigest()[:12]


def sources_hash(root=None):
    """Hash of the renderer's sources (every skymodel/**/*.py but the validation wing and
    the CLI): the key of the cached marcher results, so a re-run re-marches exactly when
    the code that renders changed. (Until 2026-11-27 the walk was sorted before it was
    pruned, so the two wings counted too and a change to the tracer re-marched.)"""
    root = os.path.join(_HERE, "..", "skymodel") if root is None else root
    h = hashlib.sha1()
    for dirpath, dirnames, files in os.walk(root):  # top-down: pruning dirnames skips the wings
        dirnames[:] = sorted(d for d in dirnames if d not in ("validation", "cli", "__pycache__"))
        for f in sorted(files):
            if f.endswith(".py"):
                with open(os.path.join(dirpath, f), "rb") as fh:
                    h.update(f.encode() + fh.read())
    return h.hexdigest()[:10]


def estimator_for(elev, override=None):
    """The Monte Carlo estimator of a scene at sun elevation ``elev`` (deg)."""
    if override:
        return override
    return ESTIMATOR_LOW_SUN if float(elev) < LOW_SUN_DEG else ESTIMATOR_SUN_UP


def view_label(view):
    """A view as the tables and the notebooks name it: (zenith, azimuth from the sun) in degrees
    -> 'zenith/azimuth', e.g. (89, 4.899) -> '89/4.899'."""
    return f"{view[0]:g}/{view[1]:g}"


class Scene:
    def __init__(self, aerosol, elev, cache, estimator=None, sun_guide=None):
        self.aerosol, self.elev, self.cache = aerosol, float(elev), cache
        self.estimator = estimator_for(elev, estimator)
        self.sun_guide = (SUN_GUIDE_PROXY if self.estimator == "proxy" else SUN_GUIDE)[aerosol] \
            if sun_guide is None else float(sun_guide)
        self.atm = atmosphere(aerosol)
        self.views = view_set(self.elev)
        self.dirs = view_directions(self.views, SUN_AZIMUTH)
        self.angle = angle_to_sun_deg(self.dirs, sun_direction(self.elev, SUN_AZIMUTH))
        self.name = f"{aerosol}_{self.elev:g}"

    def view_rows(self, names):
        """Rows of the views named (:func:`view_label`; a list or a comma-separated string), in
        the scene's order; an unknown name raises KeyError listing the scene's names."""
        names = names.split(",") if isinstance(names, str) else list(names)
        labels = [view_label(v) for v in self.views]
        missing = [n for n in names if n not in labels]
        if missing:
            raise KeyError(f"{self.name} has no view {', '.join(missing)}; its views: {', '.join(labels)}")
        return sorted(labels.index(n) for n in names)

    def mc_profile(self):
        return self.atm.optical_profile(list(MC_WAVELENGTHS_NM))

    def mc_file(self, prof):
        key = hashlib.sha1(np.round(self.views, 3).tobytes()).hexdigest()[:8]
        est = "" if self.estimator == "nee" else f"_{self.estimator}"  # NEE runs keep their names
        return os.path.join(self.cache, f"mc_{self.name}_{key}_{_profile_hash(prof)}_g{self.sun_guide:g}{est}.npz")

    def load_mc(self):
        prof = self.mc_profile()
        f = self.mc_file(prof)
        if not os.path.exists(f):  # the committed runs (TRUTH_DIR) when the cache has none
            f = os.path.join(TRUTH_DIR, os.path.basename(f))
        if not os.path.exists(f):
            return prof, None
        return prof, read_run(f)

    def save_mc(self, prof, mc):
        os.makedirs(self.cache, exist_ok=True)
        f = self.mc_file(prof)
        tmp = f + ".tmp.npz"
        np.savez(tmp, **mc)
        os.replace(tmp, f)

    def march_file(self, quality):
        return os.path.join(self.cache, f"march_{self.name}_{quality}_{sources_hash()}.npz")


def read_run(path):
    """A Monte Carlo run file (.npz) as the dict ``run_mc`` keeps: mean, se, n, seconds, seeds, views."""
    with np.load(path) as z:
        return {k: z[k] for k in z.files}


def run_summary(mc):
    """One line on a run: its paths per direction and relative standard errors."""
    rel = mc["se"] / mc["mean"]
    return (f"paths {mc['n'].min()}..{mc['n'].max()}; rel se median {100 * np.median(rel):.2f} % "
            f"max {100 * rel.max():.2f} %")


def _pooled(mean_a, se_a, n_a, mean_b, se_b, n_b):
    """Two independent estimates of the same means (per direction and wavelength) from
    ``n_a`` and ``n_b`` paths (per direction, (D, 1), or one count) pooled as one of
    n_a + n_b paths: (mean, se). Directions with no paths in either keep 0."""
    tot = np.maximum(n_a + n_b, 1.0)
    return (mean_a * n_a + mean_b * n_b) / tot, np.sqrt((se_a * n_a) ** 2 + (se_b * n_b) ** 2) / tot


def _merge(mc, rows, res, n_paths, seed):
    """Add a run (rows of the directions, MCResult with n_paths paths) to the pooled estimate."""
    mc["mean"][rows], mc["se"][rows] = _pooled(mc["mean"][rows], mc["se"][rows],
                                               mc["n"][rows].astype(float)[:, None],
                                               res.radiance, res.stderr, float(n_paths))
    mc["n"][rows] += n_paths
    mc["seconds"] = mc["seconds"] + res.time_s
    mc["seeds"] = np.append(mc["seeds"], seed)


def pool_runs(mc, other):
    """Pool ``other`` into ``mc`` (two runs of one scene: same views, estimator and sun guide)
    direction by direction, weighted by their paths, as :func:`_merge` pools a batch. Two runs
    traced apart (another machine, ``mc --seed-from``) are independent only if no seed was
    used by both: a shared seed raises ``ValueError``, as do other views."""
    if not np.array_equal(np.round(mc["views"], 3), np.round(other["views"], 3)):
        raise ValueError("pool: the runs have different views")
    shared = np.intersect1d(mc["seeds"], other["seeds"])
    if shared.size:
        raise ValueError(f"pool: seeds {shared[:5].tolist()} were used by both runs: not independent")
    mc["mean"], mc["se"] = _pooled(mc["mean"], mc["se"], mc["n"].astype(float)[:, None],
                                   other["mean"], other["se"], other["n"].astype(float)[:, None])
    mc["n"] = mc["n"] + other["n"]
    mc["seconds"] = np.float64(mc["seconds"] + other["seconds"])
    mc["seeds"] = np.append(mc["seeds"], other["seeds"])
    return mc


def plan_round(n, more, todo, seconds_per_path, left_s):
    """One round of paths: [(rows, paths)], the directions that need most first.

    Each direction in ``todo`` gets up to the ``more`` paths it needs (at most 4x the ``n``
    it has), scaled down to what the ``left_s`` seconds of budget allow at
    ``seconds_per_path`` (all wavelengths; one number, or one per direction), in thousands.
    Directions whose paths lie within a factor 2 of each other run as one batch of the
    batch's largest count (what that raises is counted against the budget too). The batches
    run in order of that count, largest first: with the budget running out, the directions
    that are furthest from the noise target (most often the same few grazing ones) are the
    ones served, not skipped after the many small top-ups (a rural 0 deg run with
    ``--max-paths`` had left its 0.87 % directions untouched that way)."""
    per_path = np.broadcast_to(np.asarray(seconds_per_path, float), np.shape(n))
    want = np.where(todo, np.minimum(more, 4 * n), 0)
    scale, batches = 1.0, []
    for _ in range(4):  # scale down until the batches, each at its largest count, fit
        add = want if scale >= 1.0 else np.floor(want * scale / 1000.0).astype(int) * 1000
        live = todo & (add > 0)
        if not np.any(live):
            return []
        exp = np.ceil(np.log2(np.maximum(add, 1)))
        batches = [(np.flatnonzero(live & (exp == g)), int(np.max(add[live & (exp == g)])))
                   for g in np.unique(exp[live])[::-1]]
        cost = sum(paths * float(np.sum(per_path[rows])) for rows, paths in batches)
        if cost <= left_s:
            return batches
        scale *= max(left_s, 0.0) / cost
    return batches


#: What the worker processes of :func:`run_mc` trace with (set before the pool forks).
_WORK = {}


def _trace_chunk(task):
    """One worker's share of a batch: (rows, paths, seed) -> (rows, paths, seed, MCResult)."""
    rows, n, seed = task
    w = _WORK
    res = trace_radiance(w["prof"], w["dirs"][rows], w["elev"], SUN_AZIMUTH, n_paths=n, seed=seed,
                         sun_guide=w["guide"], estimator=w["estimator"])
    return rows, n, seed, res


#: Longest a chunk of a round should take (seconds of one core at the directions' cost per
#: path): the run is saved and its budget checked after every chunk.
CHUNK_S = 300.0


def split_batches(batches, workers, seed, seconds_per_path=None, chunk_s=CHUNK_S):
    """Each batch (rows, paths) as ``workers`` chunks of whole thousands of paths (the batch's
    paths rounded up to thousands, shared as evenly as that allows) with their own seeds
    from ``seed`` on, so a round keeps every worker busy, and more chunks where one would
    take longer than ``chunk_s`` at ``seconds_per_path`` (per direction; None: no limit):
    [(rows, paths, seed)]."""
    tasks = []
    for rows, n in batches:
        m = max(1, -(-int(n) // 1000))  # thousands
        k = min(m, max(1, workers))
        if seconds_per_path is not None:
            sp = np.asarray(seconds_per_path, float)
            cost = n * (float(sp) * len(rows) if sp.ndim == 0 else float(np.sum(sp[rows])))
            k = min(m, max(k, int(np.ceil(cost / chunk_s))))
        q, r = divmod(m, k)
        for i in range(k):
            tasks.append((rows, 1000 * (q + (i < r)), seed))
            seed += 1
    return tasks


#: Seeds per scene: a new run of a scene starts at :func:`scene_seed_base`, one block of this
#: many seeds per (aerosol, sun elevation), so no two scenes' runs share random numbers.
SCENE_SEED_BLOCK = 1_000_000


def scene_seed_base(aerosol, elev):
    """The first seed of a new Monte Carlo run of the scene (aerosol, sun elevation in deg):
    its own block of :data:`SCENE_SEED_BLOCK` seeds. Until 2026-11-30 a run started at seed 1
    in every scene (all committed runs but desert -4 deg's), so the scenes' runs began from the
    same random numbers and partly share their fluctuations (each scene's statistics stand;
    patterns across scenes need care); a block per scene keeps future runs apart. A run resumed
    goes on in its scene's block. Elevations -18..90 deg in tenths;
    the aerosols in the order of :data:`AEROSOLS`."""
    if not -18.0 <= float(elev) <= 90.0:
        raise ValueError(f"sun elevation {elev} deg outside -18..90")
    k = list(AEROSOLS).index(aerosol)
    e = int(round(10.0 * float(elev))) + 200  # -18..90 deg -> 20..1100 of a span of 2000
    return 1 + SCENE_SEED_BLOCK * (2000 * k + e)


def run_mc(scene, target_se, max_paths, pilot_paths, budget_s, log=None, workers=1, seed_from=None, min_top_up=0.1):
    """Trace ``scene`` until every direction's relative standard error is ``target_se`` (or
    it has ``max_paths`` paths, or ``budget_s`` wall-clock seconds have passed: checked after
    every chunk; with workers the chunks still running then are dropped), saving after
    every chunk of a round (:func:`split_batches`: at most :data:`CHUNK_S` of one core each,
    so a long round is not lost when the run is stopped). ``workers`` > 1 splits each round's
    batches into chunks with their own seeds over that many processes (forked; each process
    single-threaded numpy); the run's
    ``seconds`` counts the processes' tracing time (CPU-seconds), its plan the wall-clock.
    Seeds start at ``seed_from`` (default: the scene's own block, :func:`scene_seed_base`) or
    after the run's last, whichever is larger: a run traced elsewhere from other seeds can be
    pooled with this one (:func:`pool_runs`). A direction is
    traced again only when it needs more than ``min_top_up`` times the paths it has (rounds
    of a few paths cost more in overhead than they buy; lower it to clear the last ones)."""
    log = log or (lambda line: print(line, flush=True))
    prof, mc = scene.load_mc()
    nd, nw = scene.dirs.shape[0], prof.n_wavelengths
    if mc is None:
        mc = dict(mean=np.zeros((nd, nw)), se=np.zeros((nd, nw)), n=np.zeros(nd, dtype=np.int64),
                  seconds=np.float64(0.0), seeds=np.zeros(0, dtype=np.int64), views=scene.views)
    guide = scene.sun_guide
    t0 = time.perf_counter()
    # seconds per path of each direction (all wavelengths): the run's average until a batch of
    # this session has timed the direction. The grazing views' paths cost more than the
    # average (desert -4 deg: 88-89 deg views 1.4-1.7x the zenith's), and the rounds serve
    # them most: a 72-minute budget planned on the average ran 78 minutes.
    per_dir = np.full(nd, float(mc["seconds"]) / max(1.0, float(mc["n"].sum())))
    if seed_from is None:
        seed_from = scene_seed_base(scene.aerosol, scene.elev)
    seed = max(int(seed_from), int(mc["seeds"].max()) + 1 if mc["seeds"].size else 1)
    if mc["n"].min() == 0:
        rows = np.flatnonzero(mc["n"] == 0)
        res = trace_radiance(prof, scene.dirs[rows], scene.elev, SUN_AZIMUTH, n_paths=pilot_paths, seed=seed,
                             sun_guide=guide, estimator=scene.estimator)
        _merge(mc, rows, res, pilot_paths, seed)
        per_dir[:] = float(mc["seconds"]) / max(1.0, float(mc["n"].sum()))
        per_dir[rows] = res.time_s / (pilot_paths * rows.size)
        scene.save_mc(prof, mc)
        seed += 1
    _WORK.update(prof=prof, dirs=scene.dirs, elev=scene.elev, guide=guide, estimator=scene.estimator)
    pool = None
    if workers > 1:
        import multiprocessing

        pool = multiprocessing.get_context("fork").Pool(workers)
    try:
        while True:
            rel = mc["se"] / mc["mean"]
            need = paths_for_noise(rel * np.sqrt(mc["n"])[:, None], 1, target_se, min_paths=0, max_paths=max_paths)
            more = need - mc["n"]
            todo = more > min_top_up * mc["n"]
            if not np.any(todo) or time.perf_counter() - t0 > budget_s:
                break
            left = (budget_s - (time.perf_counter() - t0)) * max(1, workers)
            batches = plan_round(mc["n"], more, todo, per_dir, left)
            if not batches:
                break
            tasks = split_batches(batches, max(1, workers), seed, per_dir)
            seed = max(t[2] for t in tasks) + 1
            done = pool.imap_unordered(_trace_chunk, tasks) if pool else map(_trace_chunk, tasks)
            for rows, n, s, res in done:
                _merge(mc, rows, res, n, s)
                per_dir[rows] = res.time_s / (n * rows.size)
                scene.save_mc(prof, mc)
                log(f"  {scene.name}: {rows.size} directions +{n} paths (seed {s}, {res.time_s:.0f} s); "
                    f"worst rel se now {100 * np.max(mc['se'] / mc['mean']):.2f} %")
                # over the budget: stop (with a pool the chunks still in flight are lost, at
                # most one CHUNK_S chunk per worker; what finished is saved above)
                if time.perf_counter() - t0 > budget_s:
                    break
    finally:
        if pool is not None:
            pool.terminate()
    return prof, mc


def run_march(scene, quality):
    f = scene.march_file(quality)
    if os.path.exists(f):
        with np.load(f) as z:
            return z["radiance"], float(z["seconds"]), float(z["cpu"])
    prof = scene.atm.optical_profile(list(MARCH_WAVELENGTHS_NM))
    t, c = time.perf_counter(), time.process_time()
    m = SkyMarcher(prof, scene.elev, SUN_AZIMUTH, 0.0, QUALITIES[quality].settings)
    rad = m.radiance(scene.dirs).radiance
    secs, cpu = time.perf_counter() - t, time.process_time() - c
    wl = np.asarray(prof.wavelengths_nm)
    idx = [int(np.argmin(np.abs(wl - w))) for w in MC_WAVELENGTHS_NM]
    out = rad[:, idx] / np.asarray(prof.solar_irradiance)[idx][None, :]
    os.makedirs(scene.cache, exist_ok=True)
    np.savez(f, radiance=out, seconds=secs, cpu=cpu)
    return out, secs, cpu


def _parse_variant(text):
    """``"table_mu=64,table_phi=48"`` -> dict of MarchSettings fields (ints, floats, bools)."""
    out = {}
    for item in filter(None, text.split(",")):
        k, v = item.split("=")
        k = k.strip()
        default = getattr(QUALITIES["final"].settings, k)
        out[k] = (v.strip() not in ("0", "false", "False")) if isinstance(default, bool) else type(default)(float(v)) \
            if isinstance(default, (int, float)) and default is not None else float(v)
    return out


def knobs(scene, base, variants):
    """The marcher at ``base`` and at each variant (MarchSettings fields changed from the
    base, one ``;``-separated variant each) against the cached MC of the scene: median and
    worst |rel| per wavelength, and the time. Nothing cached."""
    from dataclasses import replace

    prof_mc, mc = scene.load_mc()
    if mc is None:
        raise SystemExit(f"no MC for {scene.name}: run `bench_truth.py mc` first")
    e0 = np.asarray(prof_mc.solar_irradiance)[None, :]
    truth, se = mc["mean"] / e0, mc["se"] / e0
    prof = scene.atm.optical_profile(list(MARCH_WAVELENGTHS_NM))
    wl = np.asarray(prof.wavelengths_nm)
    idx = [int(np.argmin(np.abs(wl - w))) for w in MC_WAVELENGTHS_NM]
    print(f"{scene.name}, base {base}; MC rel se median {100 * np.median(se / truth):.2f} % max "
          f"{100 * np.max(se / truth):.2f} %")
    print("| variant | median abs (%) | median signed (%) | worst (%) | at | zenith (%) | time (s) |")
    zen = int(np.argmin(scene.views[:, 0]))
    for v in [""] + variants.split(";"):
        st_ = replace(QUALITIES[base].settings, **_parse_variant(v))
        t = time.perf_counter()
        rad = SkyMarcher(prof, scene.elev, SUN_AZIMUTH, 0.0, st_).radiance(scene.dirs).radiance
        secs = time.perf_counter() - t
        rad = rad[:, idx] / np.asarray(prof.solar_irradiance)[idx][None, :]
        st = truth_statistics(rad, truth, se, scene.angle)
        rel = rad / truth - 1
        print(f"| {v or base} | " + "/".join(f"{100 * x:.2f}" for x in st["median"]) + " | "
              + "/".join(f"{100 * x:+.2f}" for x in st["median_signed"]) + " | "
              + "/".join(f"{100 * x:+.2f}" for x in st["worst"]) + " | "
              + ", ".join(sorted({f"{scene.views[i][0]:g}/{scene.views[i][1]:g}" for i in st["worst_index"]})) + " | "
              + "/".join(f"{100 * x:+.2f}" for x in rel[zen]) + f" | {secs:.1f} |", flush=True)


def views_table(scene):
    """Per view: marcher / MC - 1 (%) at each preset (cached march of these sources) and the
    MC's relative standard error."""
    prof, mc = scene.load_mc()
    e0 = np.asarray(prof.solar_irradiance)[None, :]
    truth, se = mc["mean"] / e0, mc["se"] / e0
    rels = {q: run_march(scene, q)[0] / truth - 1.0 for q in QUALITY_NAMES if os.path.exists(scene.march_file(q))}
    print(f"{scene.name}: view (zenith/az. from sun) | angle to sun | " + " | ".join(rels) + " (%, 450/550/650) | MC se (%)")
    for i, v in enumerate(scene.views):
        cells = " | ".join("/".join(f"{100 * x:+.2f}" for x in r[i]) for r in rels.values())
        print(f"{view_label(v)} | {scene.angle[i]:.1f} | {cells} | "
              + "/".join(f"{100 * x:.2f}" for x in se[i] / truth[i]))


def pilot(scene, n_paths, estimators=None, guides=None):
    """Per estimator (default: the scene's), sun guide (default: 0 and the aerosol's) and
    seed (1, 2): the time per path, the relative standard errors and the paths (and
    minutes) the 0.5 % target needs, all directions of the scene."""
    prof = scene.mc_profile()
    guides = sorted({0.0, scene.sun_guide}) if guides is None else guides
    for estimator, guide, seed in ((e, g, s) for e in (estimators or [scene.estimator]) for g in guides for s in (1, 2)):
        res = trace_radiance(prof, scene.dirs, scene.elev, SUN_AZIMUTH, n_paths=n_paths, seed=seed, sun_guide=guide,
                             estimator=estimator)
        rel = res.stderr / res.radiance
        per_path_us = 1e6 * res.time_s / (n_paths * scene.dirs.shape[0] * prof.n_wavelengths)
        need = paths_for_noise(rel, n_paths, 0.005, min_paths=0)
        print(f"{scene.name} {estimator} guide {guide} seed {seed}: {res.time_s:.1f} s ({per_path_us:.1f} us per path), "
              f"rel se median {100 * np.median(rel):.2f} % max {100 * rel.max():.2f} %; paths for 0.5 %: "
              f"median {int(np.median(need))}, max {need.max()}, total {need.sum()} "
              f"(~{need.sum() * prof.n_wavelengths * per_path_us / 1e6 / 60:.1f} min)", flush=True)
        worst = np.argsort(-rel.max(axis=1))[:3]
        for i in worst:
            print(f"    view {scene.views[i]} rel se {np.round(100 * rel[i], 2)} radiance {res.radiance[i]}")


# ---------------------------------------------------------------------------------------
# report
# ---------------------------------------------------------------------------------------

def collect(scenes):
    rows = []
    for sc in scenes:
        prof, mc = sc.load_mc()
        if mc is None or mc["n"].min() == 0:
            print(f"no MC for {sc.name}: run `bench_truth.py mc --scenes {sc.aerosol}:{sc.elev:g}`")
            continue
        e0 = np.asarray(prof.solar_irradiance)[None, :]
        truth, se = mc["mean"] / e0, mc["se"] / e0
        for q in QUALITY_NAMES:
            f = sc.march_file(q)
            if not os.path.exists(f):
                print(f"no {q} march for {sc.name} at this revision: run `bench_truth.py march`")
                continue
            rad, secs, cpu = run_march(sc, q)
            st = truth_statistics(rad, truth, se, sc.angle)
            rel = rad / truth - 1.0
            rows.append(dict(aerosol=sc.aerosol, aod=AEROSOLS[sc.aerosol], elev=sc.elev, quality=q, seconds=secs,
                             cpu=cpu, n_views=int(sc.views.shape[0]), paths_min=int(mc["n"].min()),
                             paths_max=int(mc["n"].max()), mc_seconds=float(mc["seconds"]),
                             stats={k: np.asarray(v).tolist() for k, v in st.items()},
                             worst_view=[sc.views[int(i)].tolist() for i in st["worst_index"]],
                             rel=rel.tolist(), views=sc.views.tolist(), rel_se=(se / truth).tolist(),
                             angle=sc.angle.tolist()))
    return rows


#: Pairs of presets compared by :func:`closer_table`: (the cheaper, the dearer).
CLOSER_PAIRS = (("preview", "final"), ("final", "reference"))


def closer_table(rows):
    """Markdown: per scene and pair of presets (``CLOSER_PAIRS``), of the direction-wavelengths
    the truth resolves (:func:`~skymodel.validation.truth.which_is_closer`), how many the dearer
    preset is closer at; the medians and worsts of :func:`report` cannot tell presets apart that
    differ by less than the truth's noise."""
    by = {(r["aerosol"], r["elev"], r["quality"]): r for r in rows}
    scenes = list(dict.fromkeys((r["aerosol"], r["elev"]) for r in rows))
    pairs = [p for p in CLOSER_PAIRS if any((a, e, q) in by for a, e in scenes for q in p)]
    head = " | ".join(f"`{b}` closer than `{a}`" for a, b in pairs)
    lines = [f"| aerosol | sun (°) | {head} |", "|---|---|" + "---|" * len(pairs)]
    totals = {p: [0, 0] for p in pairs}
    for aer, elev in scenes:
        cells = []
        for a, b in pairs:
            ra, rb = by.get((aer, elev, a)), by.get((aer, elev, b))
            if ra is None or rb is None:
                cells.append("")
                continue
            one = np.ones_like(np.asarray(ra["rel"]))
            c = which_is_closer(1.0 + np.asarray(ra["rel"]), 1.0 + np.asarray(rb["rel"]), one,
                                np.asarray(ra["rel_se"]), np.asarray(ra["angle"]), EXCLUDE_DEG)
            totals[(a, b)][0] += c["b_closer"]
            totals[(a, b)][1] += c["resolved"]
            cells.append(f"{c['b_closer']} of {c['resolved']} (of {c['compared']})")
        lines.append(f"| {aer} {AEROSOLS[aer]:g} | {elev:g} | " + " | ".join(cells) + " |")
    lines.append("| all | | " + " | ".join(f"**{t[0]} of {t[1]}**" for t in totals.values()) + " |")
    return "\n".join(lines)


def _f(x, nd=2):
    return f"{100 * x:+.{nd}f}"


def report(rows, plot_path):
    lines = []
    wl = "/".join(f"{w:g}" for w in MC_WAVELENGTHS_NM)
    lines.append(f"| aerosol | sun (°) | quality | median abs {wl} nm (%) | ± | mean {wl} nm (%) | ± "
                 f"| worst {wl} nm (%) | ± | worst at (zenith/az. from sun) | marcher (s) | MC paths | met |")
    lines.append("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        st = r["stats"]

        def trip(key, fmt="{:.2f}", scale=100.0):
            return "/".join(fmt.format(scale * v) for v in st[key])

        where = ", ".join(sorted({view_label(v) for v in r["worst_view"]}))
        ok_m = max(st["median"]) <= TOL_MEDIAN
        ok_w = max(abs(v) for v in st["worst"]) <= TOL_WORST
        met = "yes" if ok_m and ok_w else ("median only" if ok_m else ("worst only" if ok_w else "no"))
        noisy = max(st["median_noise"]) > TOL_MEDIAN / 3 or max(st["noise_max"]) > TOL_WORST / 3
        if noisy:
            met += " (noise > 1/3 tol.)"
        lines.append(f"| {r['aerosol']} {r['aod']:g} | {r['elev']:g} | {r['quality']} | {trip('median')} | "
                     f"{trip('median_noise')} | {trip('mean_signed', '{:+.2f}')} | {trip('mean_noise')} | "
                     f"{trip('worst', '{:+.1f}')} | {trip('worst_noise')} | {where} | {r['seconds']:.1f} | "
                     f"{r['paths_min'] // 1000}k–{r['paths_max'] // 1000}k | {met} |")
    lines += ["", f"Which preset is closer to the truth where its noise can tell (a direction and wavelength "
              f"counts when the truth lies more than {CLOSER_SIGMAS:g} standard errors from the midpoint of the "
              "two presets' radiances: `skymodel.validation.truth.which_is_closer`): of those, how many the "
              "dearer preset is closer at (of all compared).", "", closer_table(rows)]
    if plot_path:
        _plot(rows, plot_path)
    return "\n".join(lines)


def _plot(rows, path):
    import matplotlib
    import matplotlib.ticker
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4), sharex=True)
    colours = dict(preview="C0", final="C1", reference="C2")
    for ax, key, noise, tol, title in ((axes[0], "median", "median_noise", TOL_MEDIAN, "median |rel| over the sky"),
                                       (axes[1], "worst", "noise_max", TOL_WORST, "worst |rel| (outside disc + 2°)")):
        for q in QUALITY_NAMES:
            rs = [r for r in rows if r["quality"] == q]
            if not rs:
                continue
            x = np.array([r["seconds"] for r in rs])
            y = np.array([100 * max(abs(v) for v in r["stats"][key]) for r in rs])
            # rows whose truth is noisier than a third of the panel's tolerance: faint crosses
            noisy = np.array([max(r["stats"][noise]) > tol / 3 for r in rs])
            ax.scatter(x[~noisy], y[~noisy], c=colours[q], label=q, marker="o")
            ax.scatter(x[noisy], y[noisy], c=colours[q], marker="x", alpha=0.4)
            for r, xx, yy, nz in zip(rs, x, y, noisy):
                if r["aerosol"] == "desert" and not nz:
                    ax.scatter([xx], [yy], facecolors="none", edgecolors="k", s=60)
        ax.axhline(100 * tol, color="k", ls="--", lw=0.8)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("marcher time per scene (s)")
        ax.set_ylabel("error against Monte Carlo (%), worst wavelength")
        ax.set_title(title)
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(title="ringed: desert; x: noisy truth", fontsize=8)
    for ax in axes:
        ax.yaxis.set_major_formatter(matplotlib.ticker.FormatStrFormatter("%g"))
        ax.yaxis.set_minor_formatter(matplotlib.ticker.FormatStrFormatter("%g"))
    fig.tight_layout()
    os.makedirs(os.path.dirname(path), exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def write_doc(body, doc=DOC):
    text = open(doc, encoding="utf-8").read()
    block = BEGIN + "\n\n" + body.rstrip() + "\n\n" + END
    if BEGIN in text and END in text:
        i, j = text.index(BEGIN), text.index(END) + len(END)
        text = text[:i] + block + text[j:]
    else:
        raise SystemExit(f"{doc} has no {BEGIN!r} ... {END!r} markers")
    with open(doc, "w", encoding="utf-8") as f:
        f.write(text)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("what", choices=("pilot", "mc", "pool", "march", "report", "knobs", "views"))
    ap.add_argument("--base", default="final", help="knobs: the preset the variants change")
    ap.add_argument("--variants", default="", help="knobs: ';'-separated 'field=value,...' variants")
    ap.add_argument("--scenes", default="all")
    ap.add_argument("--pilot-estimators", default=None, help="pilot: comma list of estimators to compare")
    ap.add_argument("--pilot-guides", default=None, help="pilot: comma list of sun_guide values (default 0 and the "
                    "aerosol's)")
    ap.add_argument("--estimator", default=None, help="Monte Carlo estimator of every scene (default: nee with "
                    f"the sun up, {ESTIMATOR_LOW_SUN} below {LOW_SUN_DEG:g} deg)")
    ap.add_argument("--sun-guide", type=float, default=None, help="sun_guide of every scene's Monte Carlo "
                    "(default: SUN_GUIDE / SUN_GUIDE_PROXY per aerosol; the run's file name records it)")
    ap.add_argument("--cache", default=os.path.join(_HERE, "..", ".cache", "truth"))
    ap.add_argument("--target-se", type=float, default=0.005, help="relative MC standard error per direction")
    ap.add_argument("--max-paths", type=int, default=400_000, help="paths per direction and wavelength, at most")
    ap.add_argument("--pilot-paths", type=int, default=3000)
    ap.add_argument("--workers", type=int, default=1, help="mc: processes tracing each round's batches in chunks "
                    "with their own seeds (one per core; set OMP_NUM_THREADS=1)")
    ap.add_argument("--seed-from", type=int, default=None, help="mc: the first seed at least (default: the scene's "
                    "own block of seeds, scene_seed_base; a run traced elsewhere at the same time takes seeds far "
                    "from this one's, to be pooled with it)")
    ap.add_argument("--runs", default="", help="pool: comma list of run files (.npz) of the one scene given, "
                    "traced apart from other seeds, to pool into its cached run")
    ap.add_argument("--min-top-up", type=float, default=0.1, help="mc: trace a direction again only when it "
                    "needs more than this share of the paths it has (default 0.1)")
    ap.add_argument("--budget-min", type=float, default=60.0, help="MC minutes per scene, at most (then stop)")
    ap.add_argument("--qualities", default=",".join(QUALITY_NAMES))
    ap.add_argument("--write-docs", action="store_true", help="write docs/accuracy.md's section and its plot")
    ap.add_argument("--json", default=None, help="write the rows here")
    a = ap.parse_args(argv)
    scenes = [Scene(aer, el, a.cache, a.estimator, a.sun_guide) for aer, el in scenes_from(a.scenes)]
    if a.what == "pilot":
        for sc in scenes:
            pilot(sc, a.pilot_paths, a.pilot_estimators and a.pilot_estimators.split(","),
                  a.pilot_guides and [float(g) for g in a.pilot_guides.split(",")])
    elif a.what == "views":
        for sc in scenes:
            views_table(sc)
    elif a.what == "knobs":
        for sc in scenes:
            knobs(sc, a.base, a.variants)
    elif a.what == "mc":
        for sc in scenes:
            t = time.perf_counter()
            _, mc = run_mc(sc, a.target_se, a.max_paths, a.pilot_paths, 60.0 * a.budget_min, workers=a.workers,
                           seed_from=a.seed_from, min_top_up=a.min_top_up)
            print(f"{sc.name}: {time.perf_counter() - t:.0f} s; {run_summary(mc)}", flush=True)
    elif a.what == "pool":
        if len(scenes) != 1 or not a.runs:
            raise SystemExit("pool: give one scene (--scenes) and the runs to pool into it (--runs)")
        sc = scenes[0]
        prof, mc = sc.load_mc()
        for f in a.runs.split(","):
            other = read_run(f)
            mc = other if mc is None else pool_runs(mc, other)
            print(f"{sc.name} + {os.path.basename(f)}: {run_summary(mc)}", flush=True)
        sc.save_mc(prof, mc)
    elif a.what == "march":
        for sc in scenes:
            for q in a.qualities.split(","):
                _, secs, cpu = run_march(sc, q)
                print(f"{sc.name} {q}: {secs:.1f} s (CPU {cpu:.1f} s)", flush=True)
    else:
        rows = collect(scenes)
        img = os.path.join(os.path.dirname(DOC), "img", "accuracy_truth.png") if a.write_docs else None
        body = report(rows, img)
        mc_s = sum(r["mc_seconds"] for r in rows if r["quality"] == QUALITY_NAMES[0])
        head = (f"Measured {time.strftime('%Y-%m-%d', time.gmtime())} on {machine()}; renderer revision "
                f"{git_revision()} (sources {sources_hash()}); `python benchmarks/bench_truth.py report --write-docs` "
                f"from the cached runs (MC: {mc_s / 60:.0f} core-minutes of tracing in all, where: the text above; "
                f"load average {os.getloadavg()[0]:.1f} now).")
        body = head + "\n\n" + body
        print(body)
        if a.json:
            with open(a.json, "w") as f:
                json.dump(rows, f)
        if a.write_docs:
            write_doc(body + "\n")


if __name__ == "__main__":
    main()
