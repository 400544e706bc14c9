"""The quality presets: one registry, one dispatcher.

Each preset is a :class:`Quality`: the renderer's :class:`~skymodel.render.marcher.MarchSettings`,
the environment image width and spectral step the Blender add-on renders it at, one
sentence of what it is for, and the targets it was chosen to meet. Its measured error and
time are read from ``skymodel/data/presets/accuracy/measured.json`` (written by
``skymodel bench accuracy``; the prose is in ``docs/accuracy.md``, "Choosing the presets")
by :meth:`Quality.measured`, so the numbers are never copied by hand.

:data:`QUALITIES` is the only place a quality is defined; :func:`quality_settings` is the
dispatcher (it validates the name and names the choices on error). The names and the
default are the ``quality`` parameter of :mod:`skymodel.scene`.

>>> from skymodel.render.quality import quality_settings, QUALITIES
>>> quality_settings("final").table_mus
32
>>> QUALITIES["preview"].environment_width_px
512
"""

from __future__ import annotations

from dataclasses import dataclass, field

from skymodel import scene
from skymodel.data import data_path
from skymodel.errors import SkymodelInputError
from skymodel.render.marcher import MarchSettings

#: Where the measured error and time of the presets come from.
MEASURED = "presets/accuracy/measured.json"


@dataclass(frozen=True)
class Quality:
    """A quality preset.

    Attributes
    ----------
    name : the preset's name (one of the ``quality`` parameter's choices in :mod:`skymodel.scene`).
    settings : the marcher's knobs.
    environment_width_px : width [px] of the Blender add-on's equirectangular environment
        image (height = width / 2) when the user leaves the width at 0.
    wavelength_step_nm : spectral step [nm] of the add-on's render.
    purpose : one sentence: what the preset is for.
    target : the targets it was chosen to meet at 512x256 on the project's 2-core
        machine (issue 3): ``radiance_rel_mean`` [fraction], ``time_s`` [s],
        ``peak_memory_mb`` [MiB]; empty for the reference.
    """

    name: str
    settings: MarchSettings
    environment_width_px: int
    wavelength_step_nm: float
    purpose: str
    target: dict = field(default_factory=dict, compare=False, hash=False)

    def measured(self) -> dict:
        """The preset's worst case over the benchmark scenes (noon, sunset, twilight) from
        ``measured.json``: ``radiance_rel_mean`` [fraction, against the reference],
        ``de2000_mean``, ``time_s`` [s], ``peak_memory_mb`` [MiB], plus ``source`` (the file,
        its date and machine). Empty dict when the file has no entry for the preset."""
        import json

        with open(data_path(*MEASURED.split("/")), encoding="utf-8") as f:
            data = json.load(f)
        per_scene = data.get("presets", {}).get(self.name, {})
        if not per_scene:
            return {}
        keys = ("radiance_rel_mean", "de2000_mean", "time_s", "peak_memory_mb")
        out = {k: max(float(e[k]) for e in per_scene.values()) for k in keys}
        out["scenes"] = sorted(per_scene)
        out["source"] = f"skymodel/data/{MEASURED} ({data.get('date')}, {data.get('machine')})"
        return out


#: The quality presets, name -> :class:`Quality`. The MarchSettings were tuned from the
#: measurement (docs/accuracy.md, "Choosing the presets"): twilight (sun -4 deg) needs more
#: sun-angle and altitude nodes in the multiple-scattering table. preview: table_mus
#: 16 -> 32, table_altitudes 16 -> 24; final: table_mus 24 -> 32, table_altitudes 24 -> 32,
#: table_steps 48 -> 96, ms_wavelength_step_nm 20 -> 10; against the Monte Carlo truth (issue 23,
#: docs/accuracy.md "Against an independent truth"): final sun_exact_deg 8 -> 12 (the direction
#: grid's 3-degree azimuth steps across the steep aureole of coarse dust, 10 degrees from the sun);
#: final and reference peak_diffuse off -> on (the cut forward peaks' scattering of the diffuse light
#: near the horizon: desert 60 degrees, 89 deg views -8 % -> within 1.5 %); preview peak_diffuse off -> on
#: and view_steps 40 -> 64 (the truth table's 7 scenes: median 0.5-1.8 % -> 0.3-1.6 %, worst better in 6;
#: the warm 512x256 rebuild 0.37 -> 0.51 s); final and reference cut a mild aerosol peak at 6 degrees
#: (MarchSettings.delta_m_mild_cutoff_deg: rural 0 / -4 degrees worst -5.6 -> -2.8 % and
#: -4.7 -> -2.0 % in final), preview kept 12 (on its 16 x 8 nodes 6 degrees moved its errors about);
#: reference table_phi 16 -> 24 (the sky's mean moves with the azimuth count, 8/12/14/16/20/24/32 nodes at
#: rural 5 degrees, 550 nm: +0.62/-0.07/+0.17/+0.36/+0.14/+0.06/+0.10 %, the sun's forward lobe in the
#: first-order field falling between nodes; 16 was the worst of them: median 0.30/0.55 -> 0.17/0.33 %
#: at 550/650 nm against the truth, notebooks/phase_cells); final spherical_orders 2 -> 3 with
#: spherical_tail (orders 4.. take order 3's correction for the sun angle along the solver's rays) and
#: reference 2 -> 20 (every order): rural -4 degrees, the sunward horizon in the Earth's shadow,
#: final median 0.82/0.62/0.46 -> 0.50/0.24/0.45 %, worst -2.8 -> -1.4 % against the truth, within
#: 0.25 % of every order spherical for +1.5-2 s of solve (notebooks/spherical_tail); final
#: table_mu 32 -> 40 with 6 of each hemisphere's 20 zenith nodes within 4 degrees of the horizon
#: (MarchSettings.table_mu_horizon_nodes: the glow toward a sun at or below the horizon; desert
#: -4 degrees worst -8.2 -> -3.2 % at 88/0, rural 0 degrees -2.4 -> -2.0 %, the upper sky as before;
#: against table_mu=96 the horizon views' error 3-6x smaller; notebooks/horizon_nodes); reference
#: 8 of its 24 per hemisphere within 4 degrees (the same count: desert -4 worst -4.8 -> +2.7 %,
#: rural 0 -1.1 -> +0.9 %); final table_phi 12 -> 24 with the spherical correction (orders 2-3) on
#: every other azimuth (spherical_coarse_phi) and orders 4.. on every other azimuth
#: (coarse_phi_from_order=4): rural 0 degrees' sunward horizon, the first order's forward lobe
#: sampled 7.5 degrees either side of the sun's azimuth, worst -2.03 -> -0.98 % (650 nm, 89/4.9),
#: desert -4 degrees' 650 nm median 0.73 -> 0.66 %, every other scene within its rules as before
#: (16-20 azimuths alias rural 5 degrees' mean; notebooks/azimuth_count); the two halvings keep it
#: within 0.19 % of every order on 24 azimuths on the truth's views (desert -4; the other scenes 0.1 %);
#: the cold 4096x2048 build 21.3-21.6 -> 26.0-27.1 s, its peak 1.14 -> 1.57 GiB (24 azimuths on every
#: order: 29.7-31.1 s; docs/benchmarks.md); final's solver 20 nm apart outside 440-660 nm
#: (ms_wavelength_outer_step_nm; 32 solver wavelengths instead of 41 for 380-780 nm, the solve
#: 0.75x): CIE XYZ within 0.012 % (max over the views) of the 10-nm solver's in four scenes, the
#: spectral worst 0.46 % at 750 nm, 450-660 nm untouched (docs/accuracy.md, "The solver's
#: wavelengths"); final and reference cut every aerosol's peak at 6 degrees, dust's too (was 12
#: for a sharp peak), with the first scattering's capped phase spread by the peak's turns
#: (MarchSettings.peak_spread; the 6-degree cone without it put the view on its edge 4 % above
#: the truth in dust at sun 5): desert 0 degrees' worst -16.4 -> -6.6 % (650 nm, 89/4.9), its 650
#: nm median 0.63 -> 0.46 %, desert -4 degrees' sunward 88/0 -3.1 -> -1.4 %, desert 5 degrees'
#: worst 1.16 -> 1.02 % (notebooks/sunward_zero); preview kept 12 degrees and no spread until 2026-11-30,
#: then took final's 6-degree cone with the spread on 24 x 12 solver nodes (was 16 x 8; the narrow
#: cone alone on 16 x 8 had moved its errors about): against the truth, its median at most 1.15 -> 0.92 %
#: and lower at 20 of the 30 scene-wavelengths (the other ten up by 0.10 point at most, within the
#: medians' noise), its worst at low sun rural -4 -6.1 -> +2.1 %, desert -4 -12.8 -> -6.3 %, desert 0
#: -19.6 -> -12.9 %, rural 0 -5.7 -> +1.8 %, rural 5 +2.9 -> +1.7 %; the cold
#: 512x256 build 1.6 -> 2.4-2.5 s, the sun-only rebuild 0.38-0.39 -> 0.41-0.44 s (docs/accuracy.md,
#: "The preview's cone").
QUALITIES: dict[str, Quality] = {
    "preview": Quality(
        "preview",
        MarchSettings(view_steps=64, order_tolerance=1e-2, ms_wavelength_step_nm=40.0, table_altitudes=24,
                      table_mu=24, table_phi=12, table_mus=32, table_steps=32, sun_table_altitudes=64,
                      sun_table_x=128, sun_table_steps=96, grid_zenith=64, grid_zenith_ground=16,
                      grid_azimuth=37, peak_diffuse=True, delta_m_cutoff_deg=6.0),
        environment_width_px=512, wavelength_step_nm=10.0,
        purpose=("interactive work: a 512x256 sky in about 3 s cold, 0.4 s when only the sun moves; "
                 "about 1 % median radiance error against a Monte Carlo truth at worst (twilight)"),
        target={"radiance_rel_mean": 0.02, "time_s": 10.0}),
    "final": Quality(
        "final",
        MarchSettings(table_mus=32, table_altitudes=32, table_steps=96, ms_wavelength_step_nm=10.0,
                      ms_wavelength_outer_step_nm=20.0, sun_exact_deg=12.0, peak_diffuse=True, spherical_orders=3, spherical_tail=True,
                      table_mu=40, table_mu_horizon_nodes=6, table_phi=24, spherical_coarse_phi=True,
                      coarse_phi_from_order=4, delta_m_cutoff_deg=6.0),
        environment_width_px=1024, wavelength_step_nm=5.0,
        purpose=("images to keep: 0.1-0.6 % median radiance error against a Monte Carlo truth (haze and "
                 "dust, sun 60 to -4 degrees); about 25 s cold at 512x256, seconds when only the sun moves"),
        target={"radiance_rel_mean": 0.005, "time_s": 60.0, "peak_memory_mb": 2048.0}),
    "reference": Quality(
        "reference",
        MarchSettings(view_steps=128, order_tolerance=1e-4, ms_wavelength_step_nm=10.0, table_altitudes=32,
                      table_mu=48, table_phi=24, table_mus=32, table_steps=96, sun_table_altitudes=128,
                      sun_table_x=256, sun_table_steps=320, grid_zenith=192, grid_zenith_ground=48,
                      grid_azimuth=121, sun_exact_deg=12.0, peak_diffuse=True, spherical_orders=20,
                      table_mu_horizon_nodes=8, delta_m_cutoff_deg=6.0),
        environment_width_px=2048, wavelength_step_nm=5.0,
        purpose="the accuracy benchmark's reference: tight tolerances, minutes per image"),
}

if tuple(QUALITIES) != tuple(scene.parameter("quality").choices):  # pragma: no cover - a packaging error
    raise ImportError("skymodel.render.quality: QUALITIES and scene's quality choices differ")

#: name -> MarchSettings (the settings of :data:`QUALITIES`; kept for older callers).
QUALITY: dict[str, MarchSettings] = {name: q.settings for name, q in QUALITIES.items()}


def quality(name=None) -> Quality:
    """The :class:`Quality` called ``name`` (case-insensitive; None: the default quality of
    :mod:`skymodel.scene`). Raises :class:`~skymodel.errors.SkymodelInputError` naming
    ``quality`` and the choices."""
    key = scene.default("quality") if name is None else str(name).strip().lower()
    if key not in QUALITIES:
        raise SkymodelInputError("quality", name, "one of: " + ", ".join(QUALITIES))
    return QUALITIES[key]


def quality_settings(name=None) -> MarchSettings:
    """The marcher settings of the quality ``name`` (a :class:`MarchSettings` is returned
    as is; None: the default quality of :mod:`skymodel.scene`)."""
    if isinstance(name, MarchSettings):
        return name
    return quality(name).settings


def targets() -> dict[str, dict]:
    """name -> target of every preset that has one (what ``docs/accuracy.md`` checks)."""
    return {name: dict(q.target) for name, q in QUALITIES.items() if q.target}
