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

    from skymodel import scene

    out = {
        "locations": {k: {kk: v[kk] for kk in ("latitude", "longitude", "site_altitude_m", "aerosol", "surface",
                                               "description") if kk in v}
                      for k, v in locations().items()},
        "aerosol_model_default": scene.default("aerosol_model"),
        "aerosol_models": {m: aerosols.type_composition(m) for m in aerosols.MODELS},
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
        for model, types in out["aerosol_models"].items():
            default = " (default)" if model == out["aerosol_model_default"] else ""
            print(f"aerosol model {model}{default}:")
            for name, t in types.items():
                fr = ", ".join(f"{k} {v.get('table1_fraction', v.get('number_fraction', 0.0)):.3g}"
                               for k, v in t["components"].items())
                print(f"  {name:24s} {fr}   [{t['source']}]")
        print("aerosol aliases:", ", ".join(f"{k} = {v}" for k, v in out["aerosol_aliases"].items()))
        print("aerosol components:", ", ".join(out["aerosol_components"]))
        print("surfaces:", ", ".join(f"{k} ({v:.2f})" for k, v in out["surfaces"].items()))
        print("qualities:")
        for k, v in out["qualities"].items():
            print(f"  {k:10s} {v}")
    return 0
