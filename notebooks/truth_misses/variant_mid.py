"""variant.py with the solver's grid rays on the midpoint transmittance of each step (the
quadrature before step_transmittance), the view rays on the new one: which half moves what.
usage as variant.py"""
import runpy
import sys

import numpy as np

import skymodel.render.multiple_scattering as ms

ms.step_transmittance = lambda tau: np.exp(-(np.cumsum(tau, axis=1) - 0.5 * tau))
sys.argv = [sys.argv[0].replace("variant_mid", "variant")] + sys.argv[1:]
runpy.run_path(sys.argv[0], run_name="__main__")
