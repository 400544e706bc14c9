"""``skymodel compare``: sky models side by side and their luminance errors.

The comparison itself (rendering the models, the errors, the composed PNG) is
:mod:`skymodel.models.comparison`; this module is its command line.
"""

from __future__ import annotations

import json
import sys

from skymodel import scene
from skymodel.cli.options import add_atmosphere_arguments, add_option, add_sun_arguments, atmosphere_from_args, \
    sun_from_args


def add_command(sub) -> None:
    """Register ``skymodel compare`` on the CLI's subparsers."""
    from skymodel.models.comparison import DEFAULT_MODELS

    p = sub.add_parser("compare", help="render sky models side by side and print their luminance errors")
    add_atmosphere_arguments(p)
    add_sun_arguments(p, observer=False)
    p.add_argument("--models", default=",".join(DEFAULT_MODELS),
                   help="comma-separated model names (default: %(default)s); see skymodel.models.model_names()")
    add_option(p, "compare_size")
    add_option(p, "quality")
    add_option(p, "compare_wavelength_step")
    p.add_argument("--out", default="compare.png", help="PNG with the panels side by side (default compare.png)")
    p.add_argument("--json", action="store_true", help="print the metrics as JSON")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=cmd_compare)


def cmd_compare(args) -> int:
    from skymodel.models.comparison import compare, format_table
    from skymodel.render import image_io

    # every option checked before any work: a bad one fails the command (exit 2), never a skipped panel
    quality = scene.check("quality", args.quality)
    size = scene.check("compare_size", args.compare_size)
    step = scene.check("compare_wavelength_step", args.compare_wavelength_step)
    image_io.check_output_path("out", args.out, (".png",))
    atm = atmosphere_from_args(args)
    sun = sun_from_args(args, atm)
    say = None if args.quiet else (lambda text: print(text, file=sys.stderr, flush=True))
    cmp = compare(atm, sun.elevation_deg, sun.azimuth_deg, args.models, size, quality, step, progress=say)
    if cmp.image is not None:
        image_io.write_png(args.out, cmp.image, text={"Software": "skymodel compare",
                                                       "Models": ",".join(cmp.models)})
    if args.json:
        print(json.dumps(dict(cmp.as_dict(), png=args.out if cmp.image is not None else None), indent=1))
    else:
        print(format_table(cmp))
        if cmp.image is not None:
            print(f"wrote {args.out} ({', '.join(cmp.models)})")
    return 0
