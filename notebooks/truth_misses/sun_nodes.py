"""variant.py with another share of the solver's sun-angle nodes below the horizon
(multiple_scattering.sun_elevation_nodes, monkeypatched; ``final``), saved as variant.py
saves, for cmp.py:

    TRUTH_CACHE=/work/cache/truth TRUTH_MISSES_OUT=/tmp/tm python notebooks/truth_misses/sun_nodes.py rural:-4,rural:5 neg45 0.45
    TRUTH_CACHE=... TRUTH_MISSES_OUT=/tmp/tm python notebooks/truth_misses/cmp.py rural:-4 fin,neg45

(the share was 10/32 = 0.31 before SUN_NODES_BELOW_SHARE; ``fin`` from
``variant.py <scene> fin "" final``)."""
import sys
from functools import partial

import numpy as np

from skymodel.render import multiple_scattering as msm
from skymodel.render.quality import QUALITIES

SHARE = float(sys.argv.pop(3))
msm.sun_elevation_nodes = partial(msm.sun_elevation_nodes, below_share=SHARE)
print("final's sun nodes:", np.round(msm.sun_elevation_nodes(QUALITIES["final"].settings.table_mus), 2).tolist())
sys.argv = sys.argv[:3] + [""]
exec(open("notebooks/truth_misses/variant.py").read())
