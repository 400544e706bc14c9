"""How far the accuracy bench's reference is from converged in the delta-M cone and the
table nodes: the ``reference`` quality preset (12-degree cone, 48 x 16 zenith x azimuth
table nodes, 32 altitudes) against the same with a 3-degree cone and 64 x 48 nodes (or
the values given), every direction marched exactly, on the bench's rural sky (README.md beside it, "Is the bench reference converged?").

Prints reference / narrow-cone - 1 (%) at 450, 550 and 650 nm for the sun at 60, 5 and
-4 degrees: five views 2-15 degrees above the sun along its vertical, then the zenith,
mid sky away from the sun, both horizons and the side.

    nice -n 5 python notebooks/sunward_horizon/reference_cone.py     # about 15 minutes on 2 cores
    nice -n 5 python notebooks/sunward_horizon/reference_cone.py --mu 96 --phi 72 --altitudes 48   # the MC comparison's tables
"""

from __future__ import annotations

import argparse
from dataclasses import replace

import numpy as np

from skymodel.validation.accuracy import atmosphere  # noqa: E402
from skymodel.render.marcher import SkyMarcher  # noqa: E402
from skymodel.render.rays import direction_from_angles  # noqa: E402
from skymodel.render.sky import QUALITY  # noqa: E402

WAVELENGTHS_NM = (450.0, 550.0, 650.0)
SUN_AZIMUTH = 180.0
OFFSETS_DEG = (2.0, 4.0, 7.0, 10.0, 15.0)  # above the sun, along its vertical
FIXED_VIEWS = ((0.0, 0.0), (45.0, 180.0), (88.0, 0.0), (88.0, 180.0), (70.0, 90.0))  # zenith angle, azimuth from sun


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cone", type=float, default=3.0, help="delta-M cone of the comparison (degrees)")
    ap.add_argument("--mu", type=int, default=64, help="zenith nodes of the comparison's tables")
    ap.add_argument("--phi", type=int, default=48, help="azimuth nodes of the comparison's tables")
    ap.add_argument("--altitudes", type=int, default=None, help="altitude nodes (default: the reference's)")
    a = ap.parse_args(argv)
    prof = atmosphere().optical_profile(list(WAVELENGTHS_NM))
    ref = replace(QUALITY["reference"], exact=True)
    narrow = replace(ref, table_mu=a.mu, table_phi=a.phi, delta_m_cutoff_deg=a.cone,
                     table_altitudes=a.altitudes or ref.table_altitudes)
    print("| sun (deg) | view | " + " | ".join(f"{w:g} nm (%)" for w in WAVELENGTHS_NM) + " |")
    print("|---|---|" + "---|" * len(WAVELENGTHS_NM))
    for elev in (60.0, 5.0, -4.0):
        zen = np.concatenate([np.clip(90.0 - elev - np.array(OFFSETS_DEG), 0.5, 89.5), [v[0] for v in FIXED_VIEWS]])
        rel = np.concatenate([np.zeros(len(OFFSETS_DEG)), [v[1] for v in FIXED_VIEWS]])
        d = direction_from_angles(zen, SUN_AZIMUTH + rel)
        a = SkyMarcher(prof, elev, SUN_AZIMUTH, 0.0, ref).radiance(d).radiance
        b = SkyMarcher(prof, elev, SUN_AZIMUTH, 0.0, narrow).radiance(d).radiance
        for z, r, x in zip(zen, rel, a / b - 1.0):
            print(f"| {elev:g} | {z:.1f} / {r:g} | " + " | ".join(f"{100 * v:+.2f}" for v in x) + " |", flush=True)


if __name__ == "__main__":
    main()
