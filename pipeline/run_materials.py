"""`flashbrdf run` on an object of several materials (K > 1 after segmentation).

Per material k: its slice (OUT_DIR/materials/material_<k>.csv, coverage.json), one prediction
per method (OUT_DIR/<method>/material_<k>/brdf.binary), and a render per method and
reference photo (each photo rendered once for all methods) with every material's table on its
own pixels (render.MaterialMap; other cameras through LABELS.faces.npy). OUT_DIR/labels.png is
the label map; OUT_DIR/slice.csv the whole object's slice, as a single-material run writes it.
A material with no usable sample at all (every pixel rejected) borrows the whole object's
slice, and the report says so; a sparse one is inferred with its missing bins imputed.
"""

import sys

import numpy as np

from flashbrdf.brdf.merl import theta_h_centres
from flashbrdf.brdf.models import TabulatedBRDF
from flashbrdf.brdf.views import table_2d_view, variance_2d_view
from flashbrdf.pipeline import report_figures as figs
from flashbrdf.pipeline.albedo_files import albedo_for_scene, write_albedo
from flashbrdf.pipeline.label_files import write_labels
from flashbrdf.pipeline.previews import previews_under_envmap
from flashbrdf.pipeline.report import coverage, write_report
from flashbrdf.pipeline.report_data import variance_description
from flashbrdf.pipeline.run_export import export_for_report, export_method, scene_envmap
from flashbrdf.pipeline.run_steps import drop_scratch, infer_method, render_and_compare
from flashbrdf.render import DiffuseAlbedoMap, MaterialMap
from flashbrdf.render.images import write_preview
from flashbrdf.render.scene_render import SceneGeometry
from flashbrdf.slice_extract import ExtractOptions
from flashbrdf.slice_extract.extract import bin_samples, extract_material_slices
from flashbrdf.slice_extract.segment import coarse_faces_warning
from flashbrdf.slice_extract.slice_files import (NARROW_LAST_THETA_H_DEG, material_coverage,
                                                 write_extraction, write_material_slices)


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


def run_materials(settings, scene, out, stages, fitted, samples, segmentation, faces,
                  references, loaded, notes, with_albedo=None):
    """The K > 1 branch of pipeline.run: the report dict.

    settings: pipeline.run.RunSettings; out: the staged output folder; stages: the StageTimer;
    fitted: {method: fitted method}; samples: FlashSamples; segmentation:
    slice_extract.segment.Segmentation; faces: (F,) int32 or None; references and loaded: the
    reference photos and those read by run's input check (pipeline.run_steps.check_references);
    notes: the report's notes so far (appended to); with_albedo: None, or a function putting
    the albedo map on a BRDF (run --albedo-map).
    """
    labels = segmentation.labels
    slices = stages.run("extract materials", extract_material_slices, samples, labels, "labels",
                        faces)
    write_labels(out / "labels.png", segmentation, faces)
    rhos = write_material_slices(out / "materials", settings.scene_dir, slices, ExtractOptions(),
                                 labels)
    cover = material_coverage(slices, labels)
    warnings = list(cover["warnings"])
    flagged = {e["label"] for e in cover["materials"] if e.get("sparse") or e.get("narrow")}
    for k, result in slices.items():  # what a single-material run warns of its slice, per material
        if result is not None:
            _, auto = coverage(np.degrees(theta_h_centres()), {"rho": result.rho, "n": result.n})
            # a sparse or narrow slice's extent is warned of above, once
            warnings += [f"material {k}: {w}" for w in auto
                         if not (k in flagged and w.startswith("θh above"))]
    # the whole object's slice too, as a single-material run writes it (for comparison)
    whole = stages.run("extract", bin_samples, samples, photo_levels=False)
    write_extraction(out / "slice.csv", settings.scene_dir, whole, ExtractOptions(),
                     final_path=settings.final_out / "slice.csv")
    # warnings of every material: the flash too far from the lens, a mesh too coarse for them
    coarse = coarse_faces_warning(segmentation, faces, scene)
    for w in whole.report.get("warnings", []) + ([coarse] if coarse else []):
        print(f"warning: {w}", file=sys.stderr)
        warnings.insert(0, w)
    for k, result in slices.items():
        if result is None:
            rhos[k] = whole.rho
            warnings.append(f"material {k}: inferred from the whole object's slice")
    tables, brdf_files = {}, {}
    for name in settings.methods:
        tables[name], brdf_files[name] = {}, {}
        for k, rho in rhos.items():
            folder = out / name / f"material_{k}"
            counts = (whole if slices[k] is None else slices[k]).n
            tables[name][k] = stages.run(f"infer {name}", infer_method, fitted[name], name,
                                         settings.model_path, rho, counts, folder,
                                         samples.level)
            tail_note = tables[name][k].tail_note
            tail_warning = tail_note and f"material {k}: {tail_note.removeprefix('note: ')}"
            if tail_warning and tail_warning not in warnings:  # the same for every method
                print(f"note: {tail_warning}", file=sys.stderr)
                warnings.append(tail_warning)
            brdf_files[name][k] = f"{name}/material_{k}/brdf.binary"
    exported = {}  # --export: each material's table of one method, as run exports one table
    if settings.export:
        method = export_method(settings.methods)
        for k in sorted(rhos):
            label, exported[k], note = stages.run("export", export_for_report, out, method,
                                                  scene_envmap(references),
                                                  settings.final_out, k)
            notes.append(note)
    notes.append("Level: " + samples.level["note"] + ".")
    rows = []
    if references:
        geometry = stages.run("ray cast", SceneGeometry, scene, samples.intersector)
        camera = scene.photos_with_role("flash")[0].camera
        renders = []  # every method's materials, and the export's fits: rendered together
        for name in settings.methods:
            materials = MaterialMap([TabulatedBRDF(tables[name][k].table) for k in sorted(rhos)],
                                    labels, camera, faces)
            if with_albedo is not None:
                materials = with_albedo(materials)
            renders.append((name, materials, True))
        if exported:
            fits = MaterialMap([TabulatedBRDF(exported[k]) for k in sorted(rhos)], labels,
                               camera, faces)
            renders.append((label, fits, False))
        rows = render_and_compare(scene, geometry, renders, settings.spp, out, references,
                                  loaded, stages)
    else:
        notes.append("The scene has no reference photo: nothing was compared.")
    fig_dir = out / "figures"
    fig_dir.mkdir(parents=True, exist_ok=True)
    sections = label_section(labels, fig_dir, segmentation.criterion)
    theta_h_deg = np.degrees(theta_h_centres())
    page = {"labels": labels, "each": {}}  # what report.html shows of each material
    for k in sorted(rhos):
        result = slices[k]
        observed = None if result is None else {"rho": result.rho, "n": result.n,
                                                "spread": result.spread}
        curves = {m: table_2d_view(tables[m][k].table)[:, 0, :] for m in settings.methods}
        figs.slice_plot(fig_dir / f"material_{k}_slice.png", theta_h_deg, observed, curves)
        entry = cover["materials"][k - 1]
        note = (" (sparse: missing bins are imputed by inference)" if entry["sparse"] else
                f" (narrow: no bin past {NARROW_LAST_THETA_H_DEG:g}°, the rest is extrapolated)"
                if entry.get("narrow") else "")
        sections += [f"### Material {k}", "",
                     f"{entry['pixels']} pixels, {entry['bins_filled']} of 90 θh bins filled"
                     + note + f"; slice `materials/material_{k}.csv`.", "",
                     f"![material {k} slice](figures/material_{k}_slice.png)", ""]
        page["each"][k] = {"observed": observed, "predictions": {}}
        for m in settings.methods:
            prediction = tables[m][k]
            described = variance_description(fitted[m])
            label = described["variance_label"]
            page["each"][k]["predictions"][m] = {"table": prediction.table,
                                                 "variance": prediction.variance, **described}
            name = f"material_{k}_brdf_{m}.png"
            figs.brdf_images(fig_dir / name, f"{m}, material {k}", table_2d_view(prediction.table),
                             variance_2d_view(prediction.variance), label)
            sections += [f"![material {k} {m}](figures/{name})"]
        sections += [""]
    extra = {"materials": material_entries(labels, {k: f"materials/material_{k}.csv"
                                                    for k in rhos}, brdf_files),
             "segmentation": segmentation.criterion, "level": samples.level}
    if not references or settings.envmap is not None:
        camera = scene.photos_with_role("flash")[0].camera
        brdfs = {m: MaterialMap([TabulatedBRDF(tables[m][k].table) for k in sorted(rhos)],
                                labels, camera, faces) for m in settings.methods}
        if with_albedo is not None:
            brdfs = {m: with_albedo(brdf) for m, brdf in brdfs.items()}
        extra["previews"], lines = stages.run(
            "previews", previews_under_envmap, settings, scene, None, brdfs,
            {m: {k: tables[m][k].table for k in sorted(rhos)} for m in settings.methods}, out)
        sections += lines
    loaded.clear()  # the references are files by now (spill_references)
    report = stages.run("report", write_report, out, stages=dict(stages.seconds),
                        references=rows, warnings=warnings, notes=notes, title=settings.title,
                        extra=extra, sections=sections, materials=page)
    drop_scratch(out)
    return report


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
