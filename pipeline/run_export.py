"""`run --export`: export the default method's BRDF beside the report, and the table of its
Principled fit, so the report can show the fit's renders next to the tabulated BRDF's and the photo.

OUT_DIR/export/            flashbrdf export of <method>/brdf.binary (all formats)
OUT_DIR/<method>-principled/   renders of the reference photos with the fitted Principled
"""

from pathlib import Path

from brdf.principled import tabulate_principled
from pipeline.cmd_export import export_brdf


def export_method(methods):
    """The method whose BRDF is exported: dsgplvm (the default) when run, else the first."""
    return "dsgplvm" if "dsgplvm" in methods else methods[0]


def export_for_report(out, method):
    """Export OUT/<method>/brdf.binary into OUT/export; returns (label, fitted table
    (90, 90, 180, 3), a note for the report)."""
    out = Path(out)
    result = export_brdf(out / method / "brdf.binary", out / "export")
    fit = result["fit"]
    note = (f"--export: {method}'s BRDF exported to export/ (Mitsuba 3, principled.json, glTF). "
            f"Its Principled fit has 2D LAB-log error {fit['lab_log_2d']:.2f} against the table"
            + (f" and sphere Delta E log {fit['render_delta_e_log']:.2f} under pisa"
               if fit["render_delta_e_log"] is not None else "")
            + f"; its renders are the method `{method}-principled`.")
    return f"{method}-principled", tabulate_principled(result["params"]), note
