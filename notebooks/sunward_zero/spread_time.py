"""The warm (sun-only) rebuild with and without the peak spread (MarchSettings.peak_spread), alternated:
usage: spread_time.py QUALITY WIDTH [LOCATION]; prints each build and the medians of builds 2-4 (the first of each untimed)."""
import sys, time, tempfile
from dataclasses import replace
import numpy as np
from skymodel import Atmosphere
from skymodel.render import quality as q
from skymodel.render.environment import render_environment
qual, size = sys.argv[1], int(sys.argv[2])
atm = Atmosphere(location=sys.argv[3] if len(sys.argv) > 3 else "rural", month=6)
orig = q.QUALITIES[qual]
res = {True: [], False: []}
with tempfile.TemporaryDirectory() as tmp:
    for rep in range(4):
        for sp in (True, False):
            q.QUALITIES[qual] = replace(orig, settings=replace(orig.settings, peak_spread=sp))
            sun = 20.0 + rep + (0.5 if sp else 0.0)
            t = time.perf_counter()
            _, env = render_environment(atm, sun, 180.0, quality=qual, width=size, cache_dir=tmp)
            dt = time.perf_counter() - t
            if rep > 0:
                res[sp].append(dt)
            print(rep, sp, f"{dt:.2f}", env.info.get("solution_s"), flush=True)
print({k: np.median(v) for k, v in res.items()})
