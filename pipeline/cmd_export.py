"""`flashbrdf export BRDF.binary --out DIR [--formats mitsuba,principled,gltf]`.

The folder is built in a temporary sibling and renamed into place (pipeline.safety's
staged_output_dir), so a failure leaves no partial output. Bad input (an unreadable table, one with no
valid bin, an unknown format, an output folder that is, holds or lies inside the input) exits 2.
"""

import sys
from pathlib import Path

from brdf.errors import InputError
from brdf.merl import read_merl
from pipeline.safety import check_outputs, staged_output_dir
from render.envmap import default_envmaps
from render.export import FORMATS, MITSUBA_USAGE, export_table, parse_formats


def pisa_envmap():
    """Path of ../shared's pisa map, or None when it is not there (the render check is skipped)."""
    try:
        return default_envmaps()[0]
    except InputError:
        return None


def export_brdf(brdf_path, out_dir, formats=FORMATS, envmap="pisa", force=False):
    """Export a MERL table into out_dir (an earlier export there is replaced only with force); the
    result dict of render.export.export_table. envmap="pisa" uses ../shared's pisa when present."""
    check_outputs(inputs=[brdf_path], outputs=[out_dir], folders=[out_dir])
    table = read_merl(brdf_path)
    if envmap == "pisa":
        envmap = pisa_envmap()
    with staged_output_dir(out_dir, force=force, command="export") as tmp:
        result = export_table(table, brdf_path, tmp, formats, envmap=envmap)
    return result


def export(args):
    formats = parse_formats(args.formats)
    result = export_brdf(args.brdf, args.out, formats, force=getattr(args, "force", False))
    fit = result["fit"]
    render = fit["render"]
    print(f"fit: {fit['optimiser']}, {fit['seconds']:.1f} s ({fit['cpu_seconds']:.1f} s CPU); "
          f"LAB-log 2D {fit['lab_log_2d']:.3f}"
          + (f"; sphere under {render['envmap']} Delta E log {render['delta_e_log_mean']:.3f}"
             if render else "; no pisa map found, render check skipped"), file=sys.stderr)
    for name in result["files"]:
        print(Path(args.out) / name)
    if "mitsuba" in formats:
        try:
            import mitsuba  # noqa: F401  (only to say whether the plugin can run here)
        except ImportError:
            print(f"mitsuba is not installed. {MITSUBA_USAGE}", file=sys.stderr)
        else:
            print(MITSUBA_USAGE, file=sys.stderr)
    return 0
