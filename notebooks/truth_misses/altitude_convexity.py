"""How much a straight line between the solver's altitude nodes overestimates the column
of the (delta-M scaled) scattering coefficient, the altitude shape of the multiple-
scattering source J (the reason for MarchSettings.source_by_scattering).

    python notebooks/truth_misses/altitude_convexity.py

Prints, for rural AOD 0.2 and desert AOD 0.5 (June) at 450/550/650 nm and 32 / 64 nodes
(``multiple_scattering.table_altitudes``, as the solver places them): the column below
20 km of the linear interpolant over the true coefficient, minus 1, plain and weighted by
exp(-h / 3 km) (the low air a low sun's light crosses); and the nodes below 5 km."""
import numpy as np

from skymodel import Atmosphere
from skymodel.render.medium import delta_m_cone_deg, factor_medium
from skymodel.render.multiple_scattering import scattering_reference, table_altitudes
from skymodel.render.quality import QUALITIES

WL = [450.0, 550.0, 650.0]
fine = np.linspace(0.0, 20000.0, 20001)
weight = np.exp(-fine / 3000.0)[:, None]
for loc, aod in (("rural", 0.2), ("desert", 0.5)):
    prof = Atmosphere(location=loc, month=6, aod550=aod).optical_profile(WL)
    fin = QUALITIES["final"].settings
    med = factor_medium(prof, delta_m_cone_deg(prof, fin.delta_m_cutoff_deg, fin.delta_m_mild_cutoff_deg))
    sigma = scattering_reference(med)
    for n in (32, 64):
        nodes = table_altitudes(med, n, prof.top_altitude_m * (1 - 1e-9))
        true, at_nodes = sigma.at(fine), sigma.at(nodes)
        lin = np.stack([np.interp(fine, nodes, at_nodes[:, w]) for w in range(len(WL))], axis=-1)
        col = 100 * (np.trapz(lin, fine, axis=0) / np.trapz(true, fine, axis=0) - 1)
        low = 100 * (np.trapz(lin * weight, fine, axis=0) / np.trapz(true * weight, fine, axis=0) - 1)
        print(f"{loc} {n} nodes: column +{'/'.join(f'{x:.2f}' for x in col)} %, "
              f"low-weighted +{'/'.join(f'{x:.2f}' for x in low)} % (450/550/650 nm)")
        print("   nodes below 5 km [m]:", np.round(nodes[nodes < 5000]).astype(int).tolist())
