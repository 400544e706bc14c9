"""notebooks/truth_misses/variant.py with module constants of skymodel.render.peak_paths set
from the environment: PP_SET="NAME=value,..." (each value cast to the constant's own type;
for a bool write "NAME=" for False).
usage: PP_SET=MAX_TURNS=3 python notebooks/peak_multi/set_constants.py scenes tag ['field=value,...'] [preset]"""
import os
import runpy

import skymodel.render.peak_paths as pp

for item in os.environ.get("PP_SET", "").split(","):
    if item:
        name, value = item.split("=", 1)
        setattr(pp, name, type(getattr(pp, name))(value))
        print(f"peak_paths.{name} = {getattr(pp, name)!r}", flush=True)
runpy.run_path(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "truth_misses", "variant.py"),
               run_name="__main__")
