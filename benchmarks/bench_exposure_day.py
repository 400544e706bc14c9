"""The one exposure rule over a day (:mod:`skymodel.render.exposure`): what the add-on's
environment map, ``skymodel render``'s PNG and ``skymodel timelapse`` get for each instant.

    PYTHONPATH=$PWD nice -n 5 .venv/bin/python benchmarks/bench_exposure_day.py \\
        [--location rural] [--dates 2026-12-21,2026-01-18] [--every 3] [--width 64]

For each date and every ``--every`` hours (UTC): the environment map of the instant
(``render_environment``, quality preview, the night's light on) and its meters: the
horizontal illuminance E_h [lux] (sun and moon lamps and the sky), the sky's log-average L
[cd m^-2], the incident and sky exposures [EV], the exposure (the darker), the sky shown
(L in the colour scale times 2^exposure; 0.18 is middle grey) and how many stops that is
under the brightest frame's. Prints Markdown tables (docs/night.md "The exposure").
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def main() -> int:
    from skymodel import scene
    from skymodel.optics.atmosphere import Atmosphere
    from skymodel.render.environment import render_environment
    from skymodel.render.exposure import CANDELA_PER_UNIT

    ap = argparse.ArgumentParser()
    ap.add_argument("--location", default="rural")
    ap.add_argument("--dates", default="2026-12-21,2026-01-18")
    ap.add_argument("--every", type=float, default=3.0, help="hours between instants")
    ap.add_argument("--width", type=int, default=64)
    args = ap.parse_args()
    cache = tempfile.mkdtemp(prefix="skymodel-exposure-day-")
    for date in args.dates.split(","):
        t0 = time.perf_counter()
        rows = []
        hour = 0.0
        while hour < 24.0 - 1e-9:
            t = f"{date}T{int(hour):02d}:{int(round(hour % 1 * 60)):02d}:00Z"
            atm = Atmosphere(location=args.location, month=scene.month_of(t), day_of_year=scene.day_of_year(t))
            sun = scene.place_sun(atm.latitude, atm.longitude, t, allow_night=True)
            _, env = render_environment(atm, sun.elevation_deg, sun.azimuth_deg,
                                        earth_sun_distance_au=sun.earth_sun_distance_au, quality="preview",
                                        width=args.width, time_iso=t, night="auto", cache_dir=cache)
            i = env.info
            moon = i.get("moon")
            rows.append((t[11:16], sun.elevation_deg, moon, i["horizontal_illuminance_Y"] * CANDELA_PER_UNIT,
                         i["sky_log_average_Y"] * CANDELA_PER_UNIT, i["exposure_incident"], i["exposure_sky"], env.exposure,
                         i["sky_log_average_Y"] * 2.0 ** env.exposure))
            hour += args.every
        top = max(r[8] for r in rows)
        print(f"\n{args.location}, {date} ({args.width} px, preview; {time.perf_counter() - t0:.0f} s)\n")
        print("| UTC | sun | moon | E_h (lux) | sky L (cd/m²) | incident | sky meter | exposure | sky shown "
              "| under the brightest |")
        print("|---|---|---|---|---|---|---|---|---|---|")
        for hm, el, moon, e_h, lum, inc, sky, ev, shown in rows:
            m = "—" if moon is None else f"{moon['elevation_deg']:.0f}°"
            print(f"| {hm} | {el:.1f}° | {m} | {e_h:.3g} | {lum:.3g} | {inc:+.2f} | {sky:+.2f} | {ev:+.2f} EV "
                  f"| {shown:.4f} | {math.log2(top / shown):.1f} stops |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
