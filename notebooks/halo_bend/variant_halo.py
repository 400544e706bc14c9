"""notebooks/truth_misses/variant.py with the prototype's bent beam (halo_patch.py) in every
sun table it builds; run it with "peak_paths=0" (the renderer's own version, on by default,
would be applied as well).
usage: variant_halo.py scenes tag 'peak_paths=0[,field=value,...]' [preset]"""
import os
import runpy
import sys

sys.path[:0] = [os.path.dirname(os.path.abspath(__file__))]
import halo_patch  # noqa: E402
from skymodel.render import marcher  # noqa: E402

_solve = marcher.solve_sky


def solve_sky(profile, settings=None, progress=None):
    halo_patch.install(profile, settings or marcher.MarchSettings())
    return _solve(profile, settings, progress)


marcher.solve_sky = solve_sky
runpy.run_path(os.path.join(os.path.dirname(__file__), "..", "truth_misses", "variant.py"), run_name="__main__")
