"""`preview` as it was before 2026-11-30, with the 6-degree cone and the spread on 16 x 12 solver nodes,
and on 24 x 12 (what it is now): render_environment at 512x256, a cold build then four sun-only rebuilds, the three
alternated, three rounds; medians.

usage: preview_time.py location   e.g. rural"""
import os, sys, tempfile, time, statistics
from dataclasses import replace
from skymodel import Atmosphere
from skymodel.render import quality as q
from skymodel.render.environment import render_environment
sys.path[:0] = [os.path.dirname(os.path.abspath(__file__))]
from preview_vs_final import preview_before  # noqa: E402

base = q.QUALITIES["preview"]  # as it is now
was = preview_before(base.settings)  # as it was before d40ed5f
cfg = {"as it was": replace(base, settings=was),
       "6 deg + spread, 16 x 12": replace(base, settings=replace(was, delta_m_cutoff_deg=6.0, peak_spread=True,
                                                                 table_phi=12)),
       "as it is (6 deg + spread, 24 x 12)": base}
loc = sys.argv[1]
atm = Atmosphere(location=loc, month=6)
res = {k: {"cold": [], "warm": []} for k in cfg}
render_environment(atm, 30.0, 180.0, quality="preview", width=512, cache_dir=tempfile.mkdtemp())
for rep in range(3):
    for tag, qq in cfg.items():
        q.QUALITIES["preview"] = qq
        with tempfile.TemporaryDirectory() as tmp:
            for k, sun in enumerate((30.0, 25.0, 20.0, 2.0, -3.0)):
                t = time.perf_counter()
                render_environment(atm, sun, 180.0, quality="preview", width=512, cache_dir=tmp)
                res[tag]["cold" if k == 0 else "warm"].append(time.perf_counter() - t)
q.QUALITIES["preview"] = base
for tag in res:
    print(loc, tag, "cold median %.2f s" % statistics.median(res[tag]["cold"]), "warm median %.2f s (max %.2f)" % (statistics.median(res[tag]["warm"]), max(res[tag]["warm"])), flush=True)
