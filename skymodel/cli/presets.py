"""``skymodel presets``: the named locations, aerosol types, components, surfaces and qualities."""

from __future__ import annotations

import json


def add_command(sub) -> None:
    """Register ``skymodel presets`` on the CLI's subparsers."""
    p = sub.add_parser("presets", help="list locations, aerosol types, components, surfaces and qualities")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_presets)


def cmd_presets(args) -> int:
    from skymodel.optics import aerosols, ground
    from skymodel.optics.atmosphere import locations
    from skymodel.render.quality import QUALITIES

    out = {
        "locations": {k: {kk: v[kk] for kk in ("latitude", "longitude", "aerosol", "surface", "description") if kk in v}
                      for k, v in locations().items()},
        "aerosol_types": list(aerosols.aerosol_types()),
        "aerosol_aliases": aerosols.aliases(),
        "aerosol_components": list(aerosols.components()),
        "surfaces": ground.surfaces(),
        "qualities": {k: q.purpose for k, q in QUALITIES.items()},
    }
    if args.json:
        print(json.dumps(out, indent=1))
    else:
        print("locations:")
        for k, v in out["locations"].items():
            print(f"  {k:18s} {v['latitude']:7.2f} {v['longitude']:8.2f}  {v['aerosol']:18s} {v['surface']:8s} {v.get('description', '')}")
        print("aerosol types:", ", ".join(out["aerosol_types"]))
        print("aerosol aliases:", ", ".join(f"{k} = {v}" for k, v in out["aerosol_aliases"].items()))
        print("aerosol components:", ", ".join(out["aerosol_components"]))
        print("surfaces:", ", ".join(f"{k} ({v:.2f})" for k, v in out["surfaces"].items()))
        print("qualities:")
        for k, v in out["qualities"].items():
            print(f"  {k:10s} {v}")
    return 0
