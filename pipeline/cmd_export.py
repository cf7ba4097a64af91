"""`flashbrdf export BRDF.binary --out DIR [--formats mitsuba,principled,gltf]`.

The folder is built in a temporary sibling and renamed into place (files.outputs's
staged_output_dir), so a failure leaves no partial output. Bad input (an unreadable table, one with no
valid bin, an unknown format, an output folder that is, holds or lies inside the input) exits 2.
"""

import sys
from pathlib import Path

from flashbrdf.brdf.merl import read_merl
from flashbrdf.files.outputs import check_outputs, staged_output_dir
from flashbrdf.render.export import FORMATS, MITSUBA_USAGE, export_table, parse_formats


def export_brdf(brdf_path, out_dir, formats=FORMATS, envmap=None, force=False, final_path=None):
    """Export a MERL table into out_dir (an earlier export there is replaced only with force); the
    result dict of render.export.export_table. envmap: a lat-long map (`export --envmap`) for the
    sphere render check of the fit, or None to skip it (nothing outside the project is read
    unless a flag names it). final_path: where brdf_path will be once its staged folder is
    renamed into place, recorded in the files instead of brdf_path (`run --export`)."""
    check_outputs(inputs=[brdf_path, envmap], outputs=[out_dir], folders=[out_dir])
    table = read_merl(brdf_path)
    if envmap is not None:
        from flashbrdf.render.envmap import read_envmap_pixels
        read_envmap_pixels(envmap)  # bad input before any work: missing, unreadable or not 2:1
    with staged_output_dir(out_dir, force=force, command="export") as tmp:
        result = export_table(table, brdf_path, tmp, formats, envmap=envmap,
                              final_path=final_path)
    return result


def export(args):
    formats = parse_formats(args.formats)
    result = export_brdf(args.brdf, args.out, formats, envmap=getattr(args, "envmap", None),
                         force=getattr(args, "force", False))
    fit = result["fit"]
    render = fit["render"]
    print(f"fit: {fit['optimiser']}, {fit['seconds']:.1f} s ({fit['cpu_seconds']:.1f} s CPU); "
          f"LAB-log 2D {fit['lab_log_2d']:.3f}"
          + (f"; sphere under {render['envmap']} Delta E log {render['delta_e_log_mean']:.3f}"
             if render else "; no --envmap, render check skipped"), file=sys.stderr)
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
