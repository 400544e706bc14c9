"""The delta-M medium as an optical profile, for checks against the Monte Carlo tracer.

The renderer's solver works on each aerosol's phase function with its forward peak cut at a
cone and renormalised, p* = min(p, p(cutoff)) / (1 - f), and the aerosol's scattering times
1 - f (:func:`skymodel.render.medium.truncate_forward_peak`): light scattered inside the cone
goes on as unscattered. Handing that medium itself to both the tracer and the marcher (which
then cuts nothing more) tests the solver's transport alone, or gives the tracer a phase
function it can converge on; the difference of a true and a delta-M run is what the cut peak
adds (notebooks/truth_misses, notebooks/aureole_transform).
"""

from __future__ import annotations

from dataclasses import replace

from skymodel.render.medium import truncate_forward_peak


def delta_m_profile(profile, cutoff_deg: float):
    """``profile`` (smooth or layered) with every aerosol regime's forward peak inside
    ``cutoff_deg`` (degrees) cut away: its phase function p*, its scattering x (1 - f)."""
    f, p_star = truncate_forward_peak(profile.aerosol_phase_angles_deg, profile.aerosol_phase, cutoff_deg)
    return replace(profile, aerosol_phase=p_star,
                   aerosol_scattering_by_regime=profile.aerosol_scattering_by_regime * (1.0 - f[:, None, :]))
