"""Both aerosol models per type at 550 nm: default AOD, single-scattering albedo, asymmetry g,
Angstrom exponent 440/870 nm (the docs/physics.md table).

    .venv/bin/python notebooks/aerosol_models_vs_aeronet/compare.py [MODEL ...]

AOD, SSA and g: ``skymodel.optics.aerosols.aerosol_optics`` of the type alone (stratospheric
"none"), at the type's default number densities, on the default 0-100 km grid of 401 altitudes
(what ``skymodel profile --aerosol-model M --aerosol T --stratospheric none`` reports). The
Angstrom exponent 440/870 needs 870 nm, outside the Mie lookups (380-780 nm): the mixtures'
extinction is integrated directly at 440 and 870 nm here (same size grids and indices; the
profile does not depend on wavelength, so the column ratio is the mixture's).
"""

from __future__ import annotations

import math

import numpy as np

from skymodel.geometry import altitude_grid
from skymodel.optics import aerosols, mie_lookup

H = altitude_grid()
PAIR = (440.0, 870.0)


def ext_pair_paper(entry: str) -> np.ndarray:
    e = mie_lookup.paper_entries()[entry]
    m = mie_lookup.refractive_index_file(e["index"] + ".csv", PAIR)
    return mie_lookup.integrate_modes(m, PAIR, e["modes"])["ext"]


def ext_pair_opac(component: str) -> np.ndarray:
    c = mie_lookup.components_table()[component]
    m = mie_lookup.refractive_index(component, PAIR)
    return mie_lookup.integrate_component(m, PAIR, float(c["r_mod_um"]), float(c["sigma"]))["ext"]


def angstrom_440_870(model: str, name: str) -> float:
    info = aerosols.type_info(name, model=model)
    f = ext_pair_paper if model == "guimera2018" else ext_pair_opac
    ext = sum(n * f(c) for c, n in info["mixture"].items())
    return -math.log(ext[0] / ext[1]) / math.log(PAIR[0] / PAIR[1])


def main(models=None) -> None:
    print(f"{'model':12s} {'type':18s} {'AOD550':>8s} {'SSA550':>7s} {'g550':>6s} {'a440/870':>9s} {'a440/675':>9s}")
    for model in models or aerosols.MODELS:
        for name in aerosols.aerosol_types(model):
            o = aerosols.aerosol_optics(name, H, [550.0], stratospheric="none", model=model)
            a = angstrom_440_870(model, name)
            print(f"{model:12s} {name:18s} {o.aod550:8.4f} {o.single_scattering_albedo[0]:7.3f} "
                  f"{o.asymmetry[0]:6.3f} {a:9.2f} {o.angstrom_exponent:9.2f}", flush=True)


if __name__ == "__main__":
    import sys

    main(sys.argv[1:] or None)
