"""`flashbrdf run`: extract the flash slice, infer a BRDF with each method, render every reference
photo's lighting with each prediction, compare with the photos, and write the report.

Only the work the scene needs is done: no reference photos -> nothing is rendered; normal-map
geometry -> no rays are cast (render/capture handle that); a 2D model -> no 3D table is loaded
(predictions stay 2D and the renderer looks them up directly); EXR photos never import rawpy.
What was skipped, and why, goes into the report's notes. Several materials: pipeline.run_materials.

OUT_DIR/
  slice.csv, slice.json              the extracted flash slice and its coverage
  <method>/brdf.binary, brdf.json    each method's full MERL table (2D copied across phi_d)
  <method>/<photo>.exr, .png         renders in the photos' pixel units, previews
  <method>/<photo>_compare.json      the contract's compare metrics, + <photo>_delta_e.png
  report.md, report.json, figures/   the report
"""

import sys
from dataclasses import dataclass
from pathlib import Path

from flashbrdf import capture
from flashbrdf.brdf.models import TabulatedBRDF
from flashbrdf.files.outputs import check_outputs, staged_output_dir
from flashbrdf.infer.model_file import check_model_file
from flashbrdf.pipeline.label_files import write_labels
from flashbrdf.pipeline.options import (fewer_materials_warning, materials_option, method_names,
                                        model_path, samples_per_pixel)
from flashbrdf.pipeline.previews import previews_under_envmap
from flashbrdf.pipeline.report import write_report
from flashbrdf.pipeline.report_data import variance_description
from flashbrdf.pipeline.run_export import export_for_report, export_method, scene_envmap
from flashbrdf.pipeline.run_materials import (label_section, material_entries, run_albedo_map,
                                              run_materials)
from flashbrdf.pipeline.run_steps import (StageTimer, check_references, infer_method,
                                          load_methods, reference_outputs, render_and_compare,
                                          drop_scratch, spill_references)
from flashbrdf.render.envmap import read_envmap_pixels
from flashbrdf.render.scene_render import SceneGeometry
from flashbrdf.slice_extract import ExtractOptions
from flashbrdf.slice_extract.extract import bin_samples, collect_samples
from flashbrdf.slice_extract.segment import segment_scene
from flashbrdf.slice_extract.slice_files import write_extraction


@dataclass(frozen=True)
class RunSettings:
    """What a run was asked: the capture, the methods (checked names), the model file (or None),
    samples per pixel, materials ("auto" or K), the albedo map, slice anchoring, --export, and
    where the output folder ends up (final_out: it is built aside and renamed)."""
    scene_dir: str
    methods: tuple
    model_path: object
    spp: int
    materials: object
    albedo_map: bool
    anchor: bool
    export: bool
    final_out: Path
    envmap: object = None  # a lat-long map to render the previews under (pipeline.previews)
    refine_poses: bool = False  # extract --refine-poses (slice_extract.pose_refine)

    @property
    def title(self):
        return f"flashbrdf run {Path(self.scene_dir).name}"


def run_capture(scene_dir, out, *, model=None, methods="dsgplvm", spp=64, materials="auto",
                albedo_map=False, anchor=True, export=False, force=False, final_out=None,
                read_methods=None, envmap=None, refine_poses=False):
    """`flashbrdf run` into the folder `out` (built aside, renamed on success). methods: "a,b" or
    a list; model: a model file or None (the default model, when a method needs one). final_out:
    where `out` ends up when the caller renames it again (batch). read_methods(names,
    model_path, anchor) -> {name: fitted method} replaces the model read (batch passes its
    per-worker cache). envmap: a lat-long map to render the object and a sphere of each
    material under (pipeline.previews); without reference photos they are rendered anyway, under
    the project's own studio map. refine_poses: refine the flash cameras first (extract
    --refine-poses). Returns the report dict."""
    names = method_names(methods)
    settings = RunSettings(str(scene_dir), tuple(names), model_path(model, names),
                           samples_per_pixel(spp), materials_option(materials), bool(albedo_map),
                           bool(anchor), bool(export), Path(final_out or out),
                           None if envmap is None else str(envmap), bool(refine_poses))
    scene = capture.load_scene(scene_dir)
    check_outputs(inputs=[scene_dir, *scene.input_files(), settings.model_path, envmap],
                  outputs=[out], folders=[out])
    if envmap is not None:
        read_envmap_pixels(envmap)  # a missing or malformed map is bad input before any work
    if settings.model_path is not None:
        check_model_file(settings.model_path)
    references = scene.references(reference_outputs)
    loaded = check_references(references)
    with staged_output_dir(out, force=force, command="run") as staged:
        stages, report = _run_stages(settings, scene, references, loaded, Path(staged),
                                     read_methods or load_methods)
    _print_summary(stages, report, settings.final_out)  # batch: where the folder is published
    return report


def _run_stages(settings, scene, references, loaded, out, read_methods):
    """The slow part of `run`, into the staged folder `out`: returns (stages, report dict)."""
    stages = StageTimer(total=8 + 2 * len(settings.methods) + 2 * settings.export
                        + settings.albedo_map)
    notes = []
    spill_references(loaded, out)
    fitted = stages.run("load model", read_methods, list(settings.methods), settings.model_path,
                        settings.anchor)
    options = ExtractOptions(refine_poses=settings.refine_poses)
    samples = stages.run("extract", collect_samples, scene, options)
    # one material needs no labels, unless the albedo map reads them: a first flash view that
    # misses the object is then no reason to stop
    segmentation, faces = stages.run("segment", segment_scene, samples, settings.materials,
                                     empty_ok=not settings.albedo_map)
    fewer = fewer_materials_warning(segmentation, settings.materials)
    if fewer:
        print(f"warning: {fewer}", file=sys.stderr)
        notes.append(fewer)
    with_albedo = (run_albedo_map(stages, out, samples, segmentation, faces, scene, notes)
                   if settings.albedo_map else None)
    if segmentation.k > 1:
        return stages, run_materials(settings, scene, out, stages, fitted, samples, segmentation,
                                     faces, references, loaded, notes, with_albedo)
    result = stages.run("extract", bin_samples, samples)
    level, intersector = samples.level, samples.intersector
    del samples  # the pooled samples and the first photo: 1 GB at 24 MP, not needed past here
    rho = write_extraction(out / "slice.csv", settings.scene_dir, result, options,
                           final_path=settings.final_out / "slice.csv")
    write_labels(out / "labels.png", segmentation, faces)

    predictions, two_d = {}, []
    ood_warnings = list(result.report.get("warnings", []))  # the flash too far from the lens
    for w in ood_warnings:
        print(f"warning: {w}", file=sys.stderr)
    for name in settings.methods:
        prediction = stages.run(f"infer {name}", infer_method, fitted[name], name,
                                settings.model_path, rho, result.n, out / name, level)
        note = prediction.tail_note
        if note and note.removeprefix("note: ") not in notes:  # the same for every method
            print(note, file=sys.stderr)
            notes.append(note.removeprefix("note: "))
        if prediction.warning:
            print(prediction.warning, file=sys.stderr)
            ood_warnings.append(prediction.warning.removeprefix("warning: "))
        predictions[name] = {"table": prediction.table, "variance": prediction.variance,
                             "file": f"{name}/brdf.binary",
                             **variance_description(fitted[name])}
        if prediction.view == "2d":
            two_d.append(name)

    exported = None
    if settings.export:
        exported = stages.run("export", export_for_report, out, export_method(settings.methods),
                              scene_envmap(references), settings.final_out)
        notes.append(exported[2])
    if two_d:
        notes.append(f"{', '.join(two_d)}: 2D predictions rho(theta_h, theta_d) (the model has no "
                     "3D data); no 3D table was loaded, and renders look the 2D tables up directly.")
    notes.append("Level: " + level["note"] + ".")
    rows, geometry = [], None
    if not references:
        notes.append("The scene has no reference photo: nothing was compared.")
    else:
        geometry = stages.run("ray cast", SceneGeometry, scene, intersector)
        if scene.geometry.mesh is None:
            notes.append("Normal-map geometry: no rays were cast.")
        elif geometry.convex:
            notes.append("Convex mesh: no shadow rays were cast.")
        renders = []  # every method's table, and the export's fit: rendered together
        for name in settings.methods:
            brdf = predictions[name]["table"]
            if with_albedo is not None:
                brdf = with_albedo(TabulatedBRDF(brdf))
            renders.append((name, brdf, True))
        if exported is not None:
            renders.append((exported[0], exported[1], False))
        rows = render_and_compare(scene, geometry, renders, settings.spp, out, references,
                                  loaded, stages)
    observed = {"rho": rho, "n": result.n, "spread": result.spread}
    (out / "figures").mkdir(parents=True, exist_ok=True)
    sections = label_section(segmentation.labels, out / "figures", segmentation.criterion)
    extra = {"materials": material_entries(segmentation.labels, {1: "slice.csv"},
                                           {m: {1: p["file"]} for m, p in predictions.items()}),
             "segmentation": segmentation.criterion, "level": level}
    if not references or settings.envmap is not None:
        brdfs = {name: TabulatedBRDF(p["table"]) for name, p in predictions.items()}
        if with_albedo is not None:
            brdfs = {name: with_albedo(brdf) for name, brdf in brdfs.items()}
        extra["previews"], lines = stages.run(
            "previews", previews_under_envmap, settings, scene, geometry, brdfs,
            {name: {1: p["table"]} for name, p in predictions.items()}, out)
        sections += lines
    geometry = None  # its cached primary hits (96 bytes a pixel): the report needs none
    loaded.clear()  # the references are files by now (spill_references)
    report = stages.run("report", write_report, out, stages=dict(stages.seconds), references=rows,
                        observed=observed, predictions=predictions, notes=notes,
                        title=settings.title, warnings=ood_warnings, extra=extra,
                        sections=sections)
    drop_scratch(out)
    return stages, report


def _print_summary(stages, report, out):
    """Close the progress bar and print the stage table, the summary and the report's path."""
    stages.bar.close()
    print(stages.table(), file=sys.stderr)
    for method, summary in report.get("summary", {}).items():
        mean = summary.get("delta_e_log_mean", {}).get("mean")
        if mean is not None:
            matched = summary.get("level_matched")
            print(f"{method}: mean delta_e_log_mean {mean:.3f} over {summary['references']} "
                  "reference(s)" + ("" if matched is None else
                                    f"; level-matched {matched['delta_e_log_mean']['mean']:.3f} "
                                    f"(renders x{matched['scale']:.3f})"), file=sys.stderr)
    # the page a user opens first, then the Markdown beside it (same numbers)
    print(f"report: {(out / 'report.html').resolve()} (and report.md, report.json beside it)")
