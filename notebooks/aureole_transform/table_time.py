"""Time skymodel.render.marcher.peak_aureole_table in the tree on PYTHONPATH, at final's 81
wavelengths (380-780 nm every 5 nm), June, desert AOD 0.5 and rural AOD 0.2.
usage: table_time.py [first]   (first: one call in this fresh process, desert only;
                                else the median of 5 calls after a first one, both skies)
Side by side: git worktree add /tmp/wt_before <rev>, then alternate
    PYTHONPATH=/tmp/wt_before python notebooks/aureole_transform/table_time.py
    PYTHONPATH=$PWD python notebooks/aureole_transform/table_time.py"""
import sys
import time

import numpy as np

import skymodel.render.marcher as marcher
from skymodel.optics.atmosphere import Atmosphere
from skymodel.render.medium import delta_m_cone_deg, factor_medium

first = len(sys.argv) > 1 and sys.argv[1] == "first"
for loc, aod in (("desert", 0.5),) if first else (("desert", 0.5), ("rural", 0.2)):
    prof = Atmosphere(location=loc, month=6, aod550=aod).optical_profile(list(np.arange(380, 781, 5.0)))
    cone = delta_m_cone_deg(prof, 12.0, 6.0, table_phi=12)
    med = factor_medium(prof, cone)
    times = []
    for rep in range(1 if first else 6):
        t = time.perf_counter()
        marcher.peak_aureole_table(prof, med, cone, prof.top_altitude_m)
        times.append(time.perf_counter() - t)
    print(f"{loc}: {times[0] if first else np.median(times[1:]):.3f} s", end="  ")
print()
