"""The reliability table (issue 22): every user parameter of the registry
(:mod:`skymodel.scene`) tried at its bounds and just outside them, as NaN, infinities, text
and the empty string, through each entry point; each case is classed as

* refused correctly: a :class:`~skymodel.errors.SkymodelInputError` (the CLI: exit 2 and
  one line, no traceback) naming the parameter (or its flag), in under a second;
* accepted correctly: a value inside the documented range gives an answer of the right
  shape, finite and non-negative (the CLI: exit 0 and the file written);
* silently wrong: an out-of-range value accepted (clamped, truncated or ignored), or an
  accepted value giving non-finite or negative radiance — the failure a scientific tool
  must never have;
* wrong failure: anything else (a raw exception or traceback, the wrong parameter named,
  a documented value refused, a refusal that took a second or more).

    python benchmarks/bench_reliability.py            # the table on stdout
    python benchmarks/bench_reliability.py --write    # ... and into docs/reliability.md

Entry points: the command line (``skymodel profile`` / ``render`` / ``sun``, in-process),
the Python API (``Atmosphere``, ``render_sky``, ``scene.place_sun``, the wavelength grids,
the writers) and the headless Blender entry's option check (``blender_addon.render``,
when ``bpy`` is installed: its options are checked, Blender does not render). Renders
use tiny tables (a few pixels at 3 wavelengths, MarchSettings below) so the whole table
takes about a minute: the validation and the writers are the real ones; the physics is
reduced (its accuracy is docs/accuracy.md's subject)."""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import sys
import tempfile
import time
from collections import Counter, defaultdict

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(1, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

from common import command_line, git_revision, machine, update_section  # noqa: E402

DOC = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "docs", "reliability.md")
HEADING = "## Reliability table"
WL = [450.0, 550.0, 650.0]
OUTCOMES = ("refused correctly", "accepted correctly", "silently wrong", "wrong failure")


def tiny_settings():
    from skymodel.render.marcher import MarchSettings

    return MarchSettings(view_steps=12, orders=2, table_altitudes=8, table_mu=8, table_phi=4, table_mus=8,
                         table_steps=12, sun_table_altitudes=16, sun_table_x=16, sun_table_steps=24, grid_zenith=8,
                         grid_zenith_ground=4, grid_azimuth=5, spherical_orders=0, peak_aureole=False)


def bad_values(p):
    """Values parameter ``p`` must refuse (as text, the CLI's form)."""
    out = ["nan", "inf", "-inf", "abc", ""]
    if p.choices:
        return ["no_such_" + p.name, ""]
    span = (p.maximum - p.minimum) if (p.minimum is not None and p.maximum is not None) else 1.0
    if p.minimum is not None:
        out.append(repr(float(p.minimum)) if p.exclusive_minimum else repr(p.minimum - max(1e-3 * span, 1e-6)))
    if p.maximum is not None:
        out.append(repr(p.maximum + max(1e-3 * span, 1e-6)))
    if p.integer and p.minimum is not None:
        out.append(repr(p.minimum + 0.5))
    return out


def good_values(p):
    """Documented values parameter ``p`` must accept: its bounds (text) and its choices and aliases."""
    if p.choices:
        return list(p.choices) + [a for a, _ in p.aliases][:3]
    vals = []
    if p.minimum is not None and not p.exclusive_minimum:
        vals.append(p.minimum)
    elif p.minimum is not None:
        vals.append(p.minimum + 1e-3)
    if p.maximum is not None:
        vals.append(p.maximum)
    return [f"{int(v)}" if p.integer else repr(float(v)) for v in vals]


class Table:
    def __init__(self):
        self.counts = defaultdict(Counter)
        self.failures = []

    def add(self, entry, case, outcome, detail=""):
        self.counts[entry][outcome] += 1
        if outcome in ("silently wrong", "wrong failure"):
            self.failures.append(f"{entry}: {case}: {outcome}: {detail}"[:300])


def _finite_non_negative(a) -> bool:
    a = np.asarray(a, dtype=float)
    return bool(np.all(np.isfinite(a)) and np.all(a >= 0))


def python_case(table, entry, case, fn, names, valid, check=None):
    """Run ``fn()``; class the outcome (``valid``: the input is documented as allowed)."""
    from skymodel.errors import SkymodelInputError

    t0 = time.perf_counter()
    try:
        result = fn()
    except SkymodelInputError as exc:
        took = time.perf_counter() - t0
        if valid:
            table.add(entry, case, "wrong failure", f"refused: {exc}")
        elif exc.parameter not in names:
            table.add(entry, case, "wrong failure", f"names {exc.parameter!r}, not {sorted(names)}")
        elif took >= 1.0:
            table.add(entry, case, "wrong failure", f"refused after {took:.1f} s")
        else:
            table.add(entry, case, "refused correctly")
        return
    except Exception as exc:  # noqa: BLE001 - the point is to catch what should not happen
        table.add(entry, case, "wrong failure", f"{type(exc).__name__}: {exc}")
        return
    ok = check(result) if check else True
    if not valid:
        table.add(entry, case, "silently wrong", f"accepted, gave {str(result)[:60]}")
    elif not ok:
        table.add(entry, case, "silently wrong", "non-finite, negative or mis-shaped result")
    else:
        table.add(entry, case, "accepted correctly")


def cli_case(table, case, argv, names, valid, out=None):
    """``skymodel argv`` in-process: exit 2 + one line naming the parameter, or exit 0 (+ ``out`` written)."""
    from skymodel.cli import main

    err = io.StringIO()
    t0 = time.perf_counter()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            code = main(argv)
        except SystemExit as exc:
            code = exc.code
        except BaseException as exc:  # noqa: BLE001
            table.add("command line", case, "wrong failure", f"{type(exc).__name__}: {exc}")
            return
    took, text = time.perf_counter() - t0, err.getvalue().strip()
    if code == 0:
        wrote = out is None or os.path.exists(out)
        if not valid:
            table.add("command line", case, "silently wrong", "exit 0")
        else:
            table.add("command line", case, "accepted correctly" if wrote else "silently wrong",
                      "" if wrote else "exit 0 without the output")
        return
    lines = text.splitlines()
    if valid:
        table.add("command line", case, "wrong failure", f"exit {code}: {text[:200]}")
    elif code != 2 or len(lines) != 1 or "Traceback" in text:
        table.add("command line", case, "wrong failure", f"exit {code}, {len(lines)} lines: {text[:200]}")
    elif not any(n in text for n in names):
        table.add("command line", case, "wrong failure", f"does not name {sorted(names)}: {text}")
    elif took >= 1.0:
        table.add("command line", case, "wrong failure", f"refused after {took:.1f} s")
    else:
        table.add("command line", case, "refused correctly")


ATMOSPHERE = ("location", "latitude", "longitude", "month", "aerosol", "aod550", "turbidity", "stratospheric",
              "ozone_du", "albedo", "n_altitudes")
SUN = ("sun_elevation", "sun_azimuth", "observer_altitude")
RENDER = ("quality", "camera", "wavelength_step", "exposure_ev")


def run(table, folder):
    from skymodel import Atmosphere, scene
    from skymodel.render import image_io
    from skymodel.render import sky as sky_module
    from skymodel.render.cameras import make_camera
    from skymodel.wavelengths import as_wavelengths, default_wavelengths

    tiny = tiny_settings()
    real_render = sky_module.render_sky

    def tiny_render(profile, camera, el, az=180.0, alt=0.0, quality=None, **kw):
        return real_render(profile, camera, el, az, alt, tiny, **kw)

    sky_module.render_sky = tiny_render  # the CLI's renders with tiny tables (module doc)
    prof = Atmosphere().optical_profile(WL)
    cam = make_camera("equirectangular", 8, 4, n_wavelengths=len(WL))
    n = 0

    def out_path(ext=".exr"):
        nonlocal n
        n += 1
        return os.path.join(folder, f"case{n}{ext}")

    def profile_ok(atm):
        p = atm.optical_profile(WL)
        return all(_finite_non_negative(a) for a in (p.rayleigh_scattering, p.ozone_absorption,
                                                      p.aerosol_scattering_by_regime, p.aerosol_absorption,
                                                      p.solar_irradiance, p.ground_albedo))

    def image_ok(img):
        return img.radiance.shape == cam.shape + (len(WL),) and _finite_non_negative(img.radiance)

    try:
        for name in ATMOSPHERE + SUN + RENDER:
            p = scene.parameter(name)
            names = {name, p.flag} | ({"location"} if name in ("latitude", "longitude") else set())
            for valid, values in ((False, bad_values(p)), (True, good_values(p))):
                for v in values:
                    case = f"{name}={v!r}"
                    # --- command line
                    extra = ["--lat", "10", "--lon", "10", "--aerosol", "rural"] if name in ("latitude", "longitude") \
                        else []
                    if name == "turbidity":
                        extra = ["--aerosol", "rural"]
                    if name in ATMOSPHERE:
                        cli_case(table, case, ["profile", "--wavelengths", "550", "--json", *extra, f"{p.flag}={v}"],
                                 names, valid)
                    else:
                        o = out_path()
                        # a limit above the 1 nm grid's estimate (4 GiB at preview): the guard has its own cases
                        cli_case(table, case, ["render", "--size", "8", "--wavelength-step", "50", "--max-memory", "64",
                                               "--quiet", "--out", o, f"{p.flag}={v}"], names, valid, out=o)
                    # --- Python API (values as numbers where they are numbers)
                    try:
                        value = float(v) if p.is_number and v not in ("", "abc") else v
                        if p.integer and valid:
                            value = int(v)
                    except ValueError:
                        value = v
                    if name in ATMOSPHERE:
                        kw = {name: value}
                        if name in ("latitude", "longitude"):
                            kw = {"latitude": 10.0, "longitude": 10.0, "aerosol": "rural", name: value}
                        python_case(table, "Python API", f"Atmosphere({case})", lambda: Atmosphere(**kw), names,
                                    valid, profile_ok)
                    elif name in SUN:
                        args = {"sun_elevation": 30.0, "sun_azimuth": 180.0, "observer_altitude": 0.0, name: value}
                        python_case(table, "Python API", f"render_sky({case})",
                                    lambda: real_render(prof, cam, args["sun_elevation"], args["sun_azimuth"],
                                                        args["observer_altitude"], tiny), names, valid, image_ok)
                    elif name == "exposure_ev":
                        rgb = np.full((4, 8, 3), 0.1)
                        python_case(table, "Python API", f"tonemap({case})", lambda: image_io.tonemap(rgb, value),
                                    {"exposure_ev"}, valid, lambda im: im.dtype == np.uint8)
        # the Python grid's own step bounds (0.1..400 nm; the CLI's are the registry's 1..50)
        for valid, step in ((True, 0.1), (True, 5), (True, 400.0), (False, 0.0), (False, 0.09), (False, 401.0),
                            (False, float("nan")), (False, "5"), (False, True), (False, 1e-46)):
            python_case(table, "Python API", f"default_wavelengths({step!r})", lambda: default_wavelengths(step),
                        {"step_nm"}, valid, lambda wl: bool(np.all(np.diff(wl) > 0)))
        # wavelength lists and a few shapes the registry does not describe
        for valid, wl in ((True, [550.0]), (True, [400.0, 500.0, 700.0]), (False, [700.0, 550.0, 400.0]),
                          (False, [550.0, 550.0]), (False, [[400.0, 500.0]]), (False, ["abc"]), (False, [379.0]),
                          (False, [float("nan")]), (False, [])):
            python_case(table, "Python API", f"as_wavelengths({wl})", lambda: as_wavelengths(wl), {"wavelengths"},
                        valid)
        for valid, radiance in ((True, 0.01), (False, -1e-9), (False, float("nan")), (False, float("inf"))):
            rad = np.full((4, 8, 3), 0.01)
            rad[1, 1, 1] = radiance
            python_case(table, "Python API", f"save_outputs(radiance with {radiance})",
                        lambda: image_io.save_outputs(out=out_path(), radiance=rad, wavelengths=np.array(WL),
                                                      camera=cam), {"radiance"}, valid)
        for valid, t in ((True, "2026-06-21T12:00Z"), (True, "2026-06-21T14:00+02:00"), (False, "2026-13-01T12:00"),
                         (False, "1800-01-01T12:00"), (False, "noon"), (False, "2026-06-21T00:00Z")):
            python_case(table, "Python API", f"place_sun(time {t})", lambda: scene.place_sun(40.0, -3.0, t),
                        {"time_utc"}, valid)
        for valid, argv in ((False, ["compare", "--quality", "foo", "--out", out_path(".png")]),
                            (False, ["profile", "--layers", "0"]), (False, ["profile", "--layers", "100000"]),
                            (True, ["profile", "--layers", "64", "--wavelengths", "550"]),
                            (False, ["radiance", "--view-zenith", ""]), (False, ["radiance", "--view-zenith", "nan"]),
                            (False, ["radiance", "--wavelengths", "550,550"]),
                            (False, ["render", "--max-memory", "0", "--out", out_path()]),
                            # the case: the spectral cube kept (without --spectral the colour
                            # image is marched through the sky-view table and fits)
                            (False, ["render", "--size", "2400x1200", "--wavelength-step", "10", "--out", out_path(),
                                     "--spectral", out_path(".npz")])):
            word = {"compare": "quality", "profile": "layers", "radiance": argv[1].lstrip("-").replace("-", "_"),
                    "render": "max_memory"}[argv[0]]
            cli_case(table, " ".join(argv[:3]), argv, {word}, valid)
        blender(table, folder)
    finally:
        sky_module.render_sky = real_render


def blender(table, folder):
    """The headless Blender entry's option check (parse + check_options), when bpy is installed."""
    try:
        import bpy  # noqa: F401
        from blender_addon import render as headless
    except ImportError:
        table.counts["headless Blender entry (not installed)"]
        return
    from skymodel import scene

    out = os.path.join(folder, "b.png")
    flags = list(headless._REGISTRY_OPTIONS)
    for flag, attr, name in flags:
        p = scene.parameter(name)
        for valid, values in ((False, bad_values(p)), (True, good_values(p))):
            for v in values:
                if name == "quality" and not valid:
                    continue  # argparse choices: exit 2 from argparse, counted below
                argv = ["--out", out, f"{flag}={v}"]

                def check():
                    try:
                        with contextlib.redirect_stderr(io.StringIO()):  # argparse's usage text
                            o = headless.parse_args(argv)
                    except SystemExit as exc:
                        from skymodel.errors import SkymodelInputError

                        raise SkymodelInputError(flag, v, f"argparse exit {exc.code}") from None
                    headless.check_options(o)
                    return o
                python_case(table, "headless Blender entry", f"{flag}={v!r}", check, {flag}, valid)
    for valid, flag, v in ((False, "--volume-bounces", "-1"), (True, "--volume-bounces", "0"),
                           (False, "--samples", "0"), (True, "--samples", "1"), (False, "--time", "1800-01-01T12:00"),
                           (True, "--time", "2026-06-21T12:00")):
        python_case(table, "headless Blender entry", f"{flag}={v!r}",
                    lambda: headless.check_options(headless.parse_args(["--out", out, f"{flag}={v}"])), {flag}, valid)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--write", action="store_true", help="write the table into docs/reliability.md")
    args = ap.parse_args(argv)
    table = Table()
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="skymodel-reliability-") as folder:
        run(table, folder)
    rows = ["| entry point | cases | " + " | ".join(OUTCOMES) + " |", "|---|---:|" + "---:|" * len(OUTCOMES)]
    total = Counter()
    for entry, c in table.counts.items():
        total.update(c)
        rows.append(f"| {entry} | {sum(c.values())} | " + " | ".join(str(c[o]) for o in OUTCOMES) + " |")
    rows.append(f"| all | {sum(total.values())} | " + " | ".join(str(total[o]) for o in OUTCOMES) + " |")
    fails = ["", "Cases that failed:", ""] + [f"- {f}" for f in table.failures] if table.failures else \
        ["", "No case was silently wrong or failed wrongly."]
    body = "\n".join([
        f"Measured in {time.perf_counter() - t0:.0f} s on {machine()}; revision {git_revision()} (with the working "
        f"tree); command: `{command_line()}`.", "", *rows, *fails, ""])
    print("\n".join(rows + fails))
    if args.write:
        update_section(DOC, HEADING, body)
    return 0 if not table.failures else 1


if __name__ == "__main__":
    sys.exit(main())
