"""`flashbrdf run` on an object of several materials (K > 1 after segmentation).

Per material k: its slice (OUT_DIR/materials/material_<k>.csv, coverage.json), one prediction
per method (OUT_DIR/<method>/material_<k>/brdf.binary), and one render per method and
reference photo with every material's table on its own pixels (render.MaterialMap; other
cameras through LABELS.faces.npy). OUT_DIR/labels.png is the label map; OUT_DIR/slice.csv
the whole object's slice, as a single-material run writes it.
A material with no usable sample at all (every pixel rejected) borrows the whole object's
slice, and the report says so; a sparse one is inferred with its missing bins imputed.
"""

import sys

import numpy as np

from flashbrdf.brdf.merl import theta_h_centres
from flashbrdf.pipeline import report_figures as figs
from flashbrdf.pipeline.albedo_files import albedo_for_scene, write_albedo
from flashbrdf.pipeline.cmd_extract import (NARROW_LAST_THETA_H_DEG, material_coverage, write_extraction,
                                  write_material_slices)
from flashbrdf.pipeline.cmd_segment import write_labels
from flashbrdf.pipeline.report import _table_2d, _variance_2d, write_report
from flashbrdf.pipeline.run_export import export_for_report, export_method
from flashbrdf.brdf.models import TabulatedBRDF
from flashbrdf.render import MaterialMap
from flashbrdf.render.albedo_map import DiffuseAlbedoMap
from flashbrdf.render.images import write_preview
from flashbrdf.slice_extract.extract import bin_samples, extract_material_slices


def label_section(labels, fig_dir, criterion):
    """Markdown lines and the figure for the label map."""
    figs.label_map(fig_dir / "labels.png", labels)
    k = int(labels.max())
    why = criterion.get("reason", f"{k} material(s) chosen")
    return ["## Materials", "", f"Segmentation of the flash photo: {k} material(s) "
            f"(`labels.png`; {why}).", "", "![labels](figures/labels.png)", ""]


def material_entries(labels, slice_files, brdf_files):
    """report.json's "materials": [{"label", "pixels", "slice", "brdf": {method: path}}]."""
    return [{"label": k, "pixels": int(np.count_nonzero(labels == k)), "slice": slice_files[k],
             "brdf": {m: files[k] for m, files in brdf_files.items()}}
            for k in range(1, int(labels.max()) + 1)]


def run_materials(ctx, samples, segmentation, faces):
    """The K > 1 branch of cmd_run.run. Returns the report dict.

    ctx: a namespace from cmd_run.run (scene, scene_dir, out, stages, options, methods,
    model_path, spp, notes, title, load_methods(), geometry(), loaded (photos read
    by run's input check), final_out (where `out` will be renamed to)); samples: FlashSamples;
    segmentation: slice_extract.segment.Segmentation; faces: (F,) int32 or None.
    """
    from flashbrdf.pipeline.cmd_run import _infer, _render_and_compare  # cmd_run imports this module

    stages, out, labels = ctx.stages, ctx.out, segmentation.labels
    slices = stages.run("extract materials", extract_material_slices, samples, labels, "labels")
    write_labels(out / "labels.png", segmentation, faces)
    rhos = write_material_slices(out / "materials", ctx.scene_dir, slices, ctx.options, labels)
    cover = material_coverage(slices, labels)
    warnings = list(cover["warnings"])
    # the whole object's slice too, as a single-material run writes it (for comparison)
    whole = stages.run("extract", bin_samples, samples)
    write_extraction(out / "slice.csv", ctx.scene_dir, whole, ctx.options,
                     final_path=ctx.final_out / "slice.csv")
    for k, result in slices.items():
        if result is None:
            rhos[k] = whole.rho
            warnings.append(f"material {k}: inferred from the whole object's slice")
    fitted = stages.run("load model", ctx.load_methods)
    tables, brdf_files = {}, {}
    for name in ctx.methods:
        tables[name], brdf_files[name] = {}, {}
        for k, rho in rhos.items():
            folder = out / name / f"material_{k}"
            counts = (whole if slices[k] is None else slices[k]).n
            tables[name][k] = stages.run(f"infer {name}", _infer, fitted[name], name,
                                         ctx.model_path, rho, counts, folder)
            tail_note = tables[name][k][5]
            tail_warning = tail_note and f"material {k}: {tail_note.removeprefix('note: ')}"
            if tail_warning and tail_warning not in warnings:  # the same for every method
                print(f"note: {tail_warning}", file=sys.stderr)
                warnings.append(tail_warning)
            brdf_files[name][k] = f"{name}/material_{k}/brdf.binary"
    exported = {}  # --export: each material's table of one method, as run exports one table
    if getattr(ctx, "export", False):
        method = export_method(ctx.methods)
        for k in sorted(rhos):
            label, exported[k], note = stages.run("export", export_for_report, out, method,
                                                  ctx.envmap, ctx.final_out, k)
            ctx.notes.append(note)
    rows = []
    references = ctx.scene.photos_with_role("reference")
    if references:
        geometry = stages.run("ray cast", ctx.geometry)
        camera = ctx.scene.photos_with_role("flash")[0].camera
        for name in ctx.methods:
            materials = ctx.with_albedo(MaterialMap(
                [TabulatedBRDF(tables[name][k][0]) for k in sorted(rhos)], labels, camera, faces))
            rows += stages.run(f"render+compare {name}", _render_and_compare, ctx.scene, geometry,
                               name, materials, ctx.spp, out / name, references, ctx.loaded)
        if exported:
            fits = MaterialMap([TabulatedBRDF(exported[k]) for k in sorted(rhos)], labels,
                               camera, faces)
            rows += stages.run(f"render+compare {label}", _render_and_compare, ctx.scene,
                               geometry, label, fits, ctx.spp, out / label, references,
                               ctx.loaded, level=False)
    else:
        ctx.notes.append("The scene has no reference photo: nothing was rendered or compared.")
    fig_dir = out / "figures"
    fig_dir.mkdir(parents=True, exist_ok=True)
    sections = label_section(labels, fig_dir, segmentation.criterion)
    theta_h_deg = np.degrees(theta_h_centres())
    for k in sorted(rhos):
        result = slices[k]
        observed = None if result is None else {"rho": result.rho, "n": result.n,
                                                "spread": result.spread}
        curves = {m: _theta_d0(tables[m][k][0]) for m in ctx.methods}
        figs.slice_plot(fig_dir / f"material_{k}_slice.png", theta_h_deg, observed, curves)
        entry = cover["materials"][k - 1]
        note = (" (sparse: missing bins are imputed by inference)" if entry["sparse"] else
                f" (narrow: no bin past {NARROW_LAST_THETA_H_DEG:g}°, the rest is extrapolated)"
                if entry.get("narrow") else "")
        sections += [f"### Material {k}", "",
                     f"{entry['pixels']} pixels, {entry['bins_filled']} of 90 θh bins filled"
                     + note + f"; slice `materials/material_{k}.csv`.", "",
                     f"![material {k} slice](figures/material_{k}_slice.png)", ""]
        for m in ctx.methods:
            table, variance, label = tables[m][k][0], tables[m][k][1], tables[m][k][3]
            name = f"material_{k}_brdf_{m}.png"
            figs.brdf_images(fig_dir / name, f"{m}, material {k}", _table_2d(table),
                             _variance_2d(variance), label)
            sections += [f"![material {k} {m}](figures/{name})"]
        sections += [""]
    extra = {"materials": material_entries(labels, {k: f"materials/material_{k}.csv"
                                                    for k in rhos}, brdf_files),
             "segmentation": segmentation.criterion}
    return stages.run("report", write_report, out, stages=dict(stages.seconds), references=rows,
                      warnings=warnings, notes=ctx.notes, title=ctx.title, extra=extra,
                      sections=sections)


def run_albedo_map(stages, out, samples, segmentation, faces, scene, notes):
    """`run --albedo-map`: estimate and write OUT_DIR/albedo.exr (+ .json, .faces.npy); returns
    a function that puts the map on a BRDF (a model or a MaterialMap) for rendering."""
    result, albedo_faces = stages.run("albedo map", albedo_for_scene, samples,
                                      segmentation.labels, faces)
    write_albedo(out / "albedo.exr", result, albedo_faces)
    (out / "figures").mkdir(parents=True, exist_ok=True)
    write_preview(out / "figures" / "albedo.png", result.albedo, exposure=1.0)  # albedo 1 = white
    notes.append("Rendered with the per-pixel diffuse albedo map `albedo.exr` (--albedo-map): "
                 "rho = T_k + A/pi - f_k; "
                 f"{100 * result.trusted[segmentation.labels > 0].mean():.0f}% of the object's "
                 "pixels measured it, the rest took their neighbourhood's.\n\n"
                 "![albedo map](figures/albedo.png)")
    camera = scene.photos_with_role("flash")[0].camera
    return lambda brdf: DiffuseAlbedoMap(brdf, result.albedo, result.floors, camera,
                                         albedo_faces)


def _theta_d0(table):
    return _table_2d(table)[:, 0, :]
