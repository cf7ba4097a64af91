"""`run --export`: export the default method's BRDF beside the report, and the table of its
Principled fit, so the report can show the fit's renders next to the tabulated BRDF's and the photo.

OUT_DIR/export/            flashbrdf export of <method>/brdf.binary (all formats); with several
                           materials, export/material_<k>/ of <method>/material_<k>/brdf.binary
OUT_DIR/<method>-principled/   renders of the reference photos with the fitted Principled
"""

from pathlib import Path

from flashbrdf.brdf.models.principled import tabulate_principled
from flashbrdf.render.export import export_brdf


def export_method(methods):
    """The method whose BRDF is exported: dsgplvm (the default) when run, else the first."""
    return "dsgplvm" if "dsgplvm" in methods else methods[0]


def scene_envmap(references):
    """The map of the first envmap-lit reference photo (a file the scene names), or None: the
    export's sphere render check uses it (nothing outside the capture is read)."""
    return next((p.light.file for p in references
                 if p.light is not None and p.light.type == "envmap"), None)


def export_for_report(out, method, envmap=None, final_out=None, material=None):
    """Export OUT/<method>/brdf.binary into OUT/export, with the sphere render check under
    `envmap` when given; the files name the table at FINAL_OUT/<method>/brdf.binary, where the
    staged OUT is renamed to (default: OUT). material k (`run --materials`): the table
    OUT/<method>/material_<k>/brdf.binary into OUT/export/material_<k>/. Returns (label, fitted
    table (90, 90, 180, 3), a note for the report)."""
    out = Path(out)
    part = Path(method) if material is None else Path(method) / f"material_{material}"
    where = Path("export") if material is None else Path("export") / f"material_{material}"
    final = None if final_out is None else Path(final_out).absolute() / part / "brdf.binary"
    # every run's table is brdf.binary: name the glTF material by run, method and material, so
    # that several imported at once do not share one name
    name = "_".join([Path(final_out or out).name, method]
                    + ([f"material_{material}"] if material else []))
    result = export_brdf(out / part / "brdf.binary", out / where, envmap=envmap,
                         final_path=final, name=name)
    fit = result["fit"]
    whose = f"{method}'s BRDF" if material is None else f"material {material}'s {method} BRDF"
    note = (f"--export: {whose} exported to {where.as_posix()}/ (Mitsuba 3, principled.json, "
            f"glTF). Its Principled fit has 2D LAB-log error {fit['lab_log_2d']:.2f} against the "
            "table"
            + (f" and sphere Delta E log {fit['render_delta_e_log']:.2f} under "
               f"{Path(envmap).name} (the map file as stored: not the scene's rotation or scale)"
               if fit["render_delta_e_log"] is not None else "")
            + f"; its renders are the method `{method}-principled`."
            + "".join(f" Warning: {line}." for line in result["warnings"]))
    return f"{method}-principled", tabulate_principled(result["params"]), note
