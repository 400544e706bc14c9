"""The marcher with ``orders=N`` against the Monte Carlo tracer with ``max_bounces=N``, per
view of bench_truth's view set (issue 23: where does the aerosol horizon error live?).

usage: orders.py scene bounces paths [albedo] [variant] [tag] [dm]
  scene    e.g. rural:60
  bounces  1, 2, 3 ... or 'all' (MC max_bounces 64, marcher orders None = to tolerance)
  paths    MC paths per view and wavelength (one run, seed 7; cached in $TRUTH_MISSES_OUT)
  albedo   '' = the scene's own ground; a number = a grey ground of that albedo, in both
  variant  MarchSettings fields changed from final, 'a=1,b=2' (bench_truth's syntax)
  (env VIEWS=0/0,70/45: only these views of the set; env ESTIMATOR=proxy|sunlit: the MC's
  estimator, default nee; below the horizon use proxy, the file names get its name)
  tag      name of the saved marcher result (var_<scene>_<tag>.npz; '' = not saved)
  dm       'dm': both run on the delta-M medium itself (each aerosol's phase function
           truncated at final's 12-degree cone and renormalised, its scattering times
           1 - f), so the marcher cuts nothing more (f = 0) and orders=N and max_bounces=N
           count exactly the same paths: a test of the solver's transport alone

What ``orders=N`` is: the marcher's total counts single scattering and the directly lit
ground (bounce 1, true extinction in ``single`` / ``ground``; in the total the delta-M
first scattering, the difference going to ``multiple``), then the solver's orders 2..N
(each order scatters the last order's radiance, the ground's reflection of it included,
as the tracer counts a ground reflection as a bounce). For sky views (all of the view
set) the two count the same paths, except that delta-M treats a scattering inside the
cut forward peak as no scattering, so at N >= 2 the marcher also holds paths with more
than N events when all but N are inside the peak (and the peak aureole adds the
peak's own 2+ scatterings of sunlight). With N=1 the two are the same quantity.
"""
import hashlib
import os
import sys
import time
from dataclasses import replace

import numpy as np

sys.path[:0] = ["benchmarks"]
import bench_truth as bt  # noqa: E402
from skymodel.optics.atmosphere import Atmosphere  # noqa: E402
from skymodel.render.marcher import SkyMarcher  # noqa: E402
from skymodel.render.medium import delta_m_cone_deg  # noqa: E402
from skymodel.render.quality import QUALITIES  # noqa: E402
from skymodel.validation.delta_m_medium import delta_m_profile  # noqa: E402
from skymodel.validation.montecarlo import trace_radiance  # noqa: E402

OUT = os.environ.get("TRUTH_MISSES_OUT", ".cache/truth_misses")
os.makedirs(OUT, exist_ok=True)
args = sys.argv[1:] + [""] * 6
scene, bounces, paths, albedo, variant, tag = args[0], args[1], int(args[2]), args[3], args[4], args[5]
dm = args[6] == "dm"
a, e = scene.split(":")
sc = bt.Scene(a, float(e), os.environ.get("TRUTH_CACHE", ".cache/truth"))
if os.environ.get("VIEWS"):  # a subset of the view set, e.g. VIEWS=0/0,70/45 (the file names get its hash)
    keep = sc.view_rows(os.environ["VIEWS"])
    sc.views, sc.dirs, sc.angle = sc.views[keep], sc.dirs[keep], sc.angle[keep]
    sc.name += "_v" + hashlib.sha1(os.environ["VIEWS"].encode()).hexdigest()[:6]
atm = bt.atmosphere(a) if albedo == "" else Atmosphere(location=a, month=bt.MONTH, aod550=bt.AEROSOLS[a],
                                                        albedo=float(albedo))
nb = 64 if bounces == "all" else int(bounces)
est = os.environ.get("ESTIMATOR", "nee")
mc_f = (f"{OUT}/mcb_{sc.name}_b{bounces}_a{albedo or 'x'}_n{paths}{'_dm' if dm else ''}"
        f"{'' if est == 'nee' else '_' + est}.npz")


def delta_m(prof):
    """The profile with final's delta-M truncation applied to its aerosols."""
    if not dm:
        return prof
    fin = QUALITIES["final"].settings
    cone = delta_m_cone_deg(prof, fin.delta_m_cutoff_deg, fin.delta_m_mild_cutoff_deg)  # final's cone for this sky
    return delta_m_profile(prof, cone)


prof_mc = delta_m(atm.optical_profile(list(bt.MC_WAVELENGTHS_NM)))
if os.path.exists(mc_f):
    z = np.load(mc_f)
    mc, se, mc_s = z["mean"], z["se"], float(z["seconds"])
else:
    res = trace_radiance(prof_mc, sc.dirs, sc.elev, bt.SUN_AZIMUTH, n_paths=paths, max_bounces=nb, seed=7,
                         sun_guide=bt.SUN_GUIDE[a] if est == "nee" else 0.0, estimator=est)
    mc, se, mc_s = res.radiance, res.stderr, res.time_s
    np.savez(mc_f, mean=mc, se=se, seconds=mc_s)
e0 = np.asarray(prof_mc.solar_irradiance)[None, :]
mc, se = mc / e0, se / e0
prof = delta_m(atm.optical_profile(list(bt.MARCH_WAVELENGTHS_NM)))
wl = np.asarray(prof.wavelengths_nm)
idx = [int(np.argmin(np.abs(wl - w))) for w in bt.MC_WAVELENGTHS_NM]
s = replace(QUALITIES["final"].settings, **bt._parse_variant(variant))
s = replace(s, orders=None if bounces == "all" else nb)
t = time.perf_counter()
m = SkyMarcher(prof, sc.elev, bt.SUN_AZIMUTH, 0.0, s)
sr = m.radiance(sc.dirs)
secs = time.perf_counter() - t
norm = np.asarray(prof.solar_irradiance)[idx][None, :]
r = sr.radiance[:, idx] / norm
if tag:
    np.savez(f"{OUT}/var_{sc.name}_{tag}.npz", r=r, views=sc.views, angle=sc.angle, secs=secs)
rel = r / mc - 1
print(f"{sc.name} bounces {bounces} albedo {albedo or 'scene'} variant '{variant}'{' delta-M medium' if dm else ''}: MC {paths} paths {mc_s:.0f} s, "
      f"marcher {secs:.0f} s (orders solved {m.field.orders})")
print(f"median |rel| " + "/".join(f"{100 * x:.2f}" for x in np.median(np.abs(rel), axis=0))
      + "  mean " + "/".join(f"{100 * x:+.2f}" for x in rel.mean(axis=0))
      + "  MC se median " + "/".join(f"{100 * x:.2f}" for x in np.median(se / mc, axis=0)))
print("view | angle | marcher/MC-1 (%, 450/550/650) | MC se (%) | multiple share of marcher (%)")
ms = (sr.multiple[:, idx] / norm) / r
for i, v in enumerate(sc.views):
    print(f"{bt.view_label(v)} | {sc.angle[i]:.1f} | " + "/".join(f"{100 * x:+.2f}" for x in rel[i]) + " | "
          + "/".join(f"{100 * x:.2f}" for x in se[i] / mc[i]) + " | " + "/".join(f"{100 * x:.0f}" for x in ms[i]))
