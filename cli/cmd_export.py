"""`flashbrdf export BRDF.binary --out DIR [--formats mitsuba,principled,gltf] [--envmap FILE]`.

The folder is built in a temporary sibling and renamed into place, so a failure leaves no
partial output. Bad input (an unreadable table, one with no valid bin, an unknown format, an
output folder that is, holds or lies inside the input) exits 2.
"""

import sys
from pathlib import Path

from flashbrdf.cli.options import add_force


def add_parsers(sub):
    s = sub.add_parser("export", help="a MERL table for Mitsuba 3, Blender and glTF")
    s.add_argument("brdf", metavar="BRDF.binary")
    s.add_argument("--out", required=True, metavar="DIR")
    s.add_argument("--formats", default="mitsuba,principled,gltf",
                   help="comma-separated, some of mitsuba,principled,gltf (default: all three)")
    s.add_argument("--envmap", metavar="FILE",
                   help="a lat-long map: render a sphere with the table and with its Principled "
                        "fit under it, and record their Delta E in principled.json (default: no "
                        "render check)")
    add_force(s)
    s.set_defaults(handler=export)


def export(args):
    from flashbrdf.render.export import MITSUBA_USAGE, export_brdf, parse_formats
    formats = parse_formats(args.formats)
    result = export_brdf(args.brdf, args.out, formats, envmap=args.envmap, force=args.force)
    fit = result["fit"]
    render = fit["render"]
    print(f"fit: {fit['optimiser']}, {fit['seconds']:.1f} s ({fit['cpu_seconds']:.1f} s CPU); "
          f"LAB-log 2D {fit['lab_log_2d']:.3f}"
          + (f"; sphere under {render['envmap']} Delta E log {render['delta_e_log_mean']:.3f}"
             if render else "; no --envmap, render check skipped"), file=sys.stderr)
    for name in result["files"]:
        print(Path(args.out) / name)
    for line in result["warnings"]:
        print(f"warning: {line}", file=sys.stderr)
    if "mitsuba" in formats:
        try:
            import mitsuba  # noqa: F401  (only to say whether the plugin can run here)
        except ImportError:
            print(f"mitsuba is not installed. {MITSUBA_USAGE}", file=sys.stderr)
        else:
            print(MITSUBA_USAGE, file=sys.stderr)
