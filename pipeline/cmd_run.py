"""`flashbrdf run SCENE_DIR --out OUT_DIR [--model MODEL.npz] [--methods dsgplvm,pca,...]`.

Extract the flash slice, infer a BRDF with each method, render every reference photo's lighting
with each prediction, compare against the photos, and write OUT_DIR/report.md + report.json.

Only the work the scene needs is done: no reference photos -> nothing is rendered; normal-map
geometry -> no rays are cast (render/capture handle that); a 2D model -> no 3D table is loaded
(predictions stay 2D and the renderer looks them up directly); EXR photos never import rawpy.
What was skipped, and why, goes into the report's notes.

OUT_DIR/
  slice.csv, slice.json              the extracted flash slice and its coverage
  <method>/brdf.binary, brdf.json    each method's full MERL table (2D copied across phi_d)
  <method>/<photo>.exr, .png         renders in the photos' pixel units, previews
  <method>/<photo>_compare.json      the contract's compare metrics, + <photo>_delta_e.png
  report.md, report.json, figures/   the report
"""

import json
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
from tqdm import tqdm

from flashbrdf import capture
from flashbrdf.brdf import merl, views
from flashbrdf.brdf.atomic import write_text
from flashbrdf.brdf.errors import InputError
from flashbrdf.infer import METHODS, make_method, prediction_warning
from flashbrdf.infer.model_file import check_model_file, load_methods
from flashbrdf.infer.slices import (sample_counts, sparse_tail_note, sparse_tail_record,
                          without_sparse_tail)
from flashbrdf.pipeline.cmd_extract import write_extraction
from flashbrdf.pipeline.cmd_render import photo_exists, reference_outputs, samples_per_pixel
from flashbrdf.pipeline.cmd_segment import materials_option, segment_scene, write_labels
from flashbrdf.pipeline.report import write_report
from flashbrdf.pipeline.run_export import export_for_report, export_method, scene_envmap
from flashbrdf.pipeline.safety import check_outputs, staged_output_dir
from flashbrdf.render import (MaterialMap, TabulatedBRDF, level_ratio, render_scene, write_comparison,
                    write_exr, write_preview)
from flashbrdf.render.albedo_map import DiffuseAlbedoMap
from flashbrdf.render.envmap import read_envmap_pixels
from flashbrdf.render.scene_render import SceneGeometry
from flashbrdf.slice_extract import ExtractOptions
from flashbrdf.slice_extract.extract import bin_samples, collect_samples

DEFAULT_MODEL = Path(__file__).resolve().parents[1] / "sample_data" / "models" / "merl100_1d2d.npz"
METHODS_NEEDING_NO_MODEL = ("chandraker",)


class _Stages:
    """Wall-clock seconds per stage, in run order, printed as a table at the end.

    On a terminal a progress bar counts the stages (renders add their own per-photo bars);
    otherwise each stage prints one line on stdout, which keeps logs readable.
    """

    def __init__(self, total):
        self.seconds = {}
        self.bar = tqdm(total=total, unit="stage", file=sys.stderr, disable=not sys.stderr.isatty())

    def run(self, name, fn, *args, **kwargs):
        if self.bar.disable:  # on stdout: stderr is kept for the one error line of bad input
            print(f"[{name}] ...", flush=True)
        self.bar.set_description(name)
        start = time.perf_counter()
        result = fn(*args, **kwargs)
        self.seconds[name] = self.seconds.get(name, 0.0) + time.perf_counter() - start
        self.bar.update(1)
        return result

    def table(self):
        width = max(len(k) for k in self.seconds) if self.seconds else 5
        lines = [f"{'stage':<{width}}  seconds", f"{'-' * width}  -------"]
        lines += [f"{k:<{width}}  {v:7.2f}" for k, v in self.seconds.items()]
        lines.append(f"{'total':<{width}}  {sum(self.seconds.values()):7.2f}")
        return "\n".join(lines)


def _methods(text):
    names = [m.strip() for m in text.split(",") if m.strip()]
    usable = [m for m in METHODS if not make_method(m).evaluation_only]
    unknown = [m for m in names if m not in usable]
    if not names or unknown:
        raise InputError("--methods", f"unknown method(s) {', '.join(unknown) or '(none)'}; "
                                      f"expected some of {', '.join(usable)}")
    return list(dict.fromkeys(names))


def _model_path(args, methods):
    if args.model is not None:
        if not Path(args.model).is_file():
            raise InputError(args.model, "no such model file")
        return Path(args.model)
    if all(m in METHODS_NEEDING_NO_MODEL for m in methods):
        return None  # nothing to read: the default model is 9 MB and takes seconds to load
    if DEFAULT_MODEL.is_file():
        return DEFAULT_MODEL
    raise InputError("--model", f"no model given and the default {DEFAULT_MODEL} is missing "
                                "(make it with `flashbrdf train`)")


def _load_methods(names, model_path, anchor):
    """{name: fitted method}, the model file read once for all of them."""
    if model_path is None:
        return {name: make_method(name).fit(None) for name in names}
    return load_methods(model_path, names, overrides={"dsgplvm": {"anchor": anchor}})


def _infer(method, method_name, model_path, rho, n, out_dir):
    """Predict a 2D table (or 3D where the model stores 3D data) from the slice rho with sample
    counts n, its sparse periphery emptied (infer.slices.without_sparse_tail); write brdf.binary
    + brdf.json."""
    start = time.perf_counter()
    view = "3d" if method.training_3d() == "stored" else "2d"
    n = sample_counts(rho, n)  # an empty bin's n does not set the threshold the record tells
    rho, ignored = without_sparse_tail(rho, n)
    table, variance = method.predict(rho, view=view)
    seconds = time.perf_counter() - start
    novelty, warning = prediction_warning(method, rho, f"{method_name}")
    full = views.table_3d_from_2d(table) if view == "2d" else table
    full = np.where(np.isfinite(full), full, -1.0)
    full[~merl.merl_valid_mask()] = -1.0
    out_dir.mkdir(parents=True, exist_ok=True)
    merl.write_merl(out_dir / "brdf.binary", full)
    write_text(out_dir / "brdf.json", json.dumps({
        "method": method_name, "model": None if model_path is None else str(model_path),
        "view": view, "predict_seconds": seconds, "novelty": novelty,
        "sparse_tail_ignored": sparse_tail_record(ignored, n),
        "predicted": "2D table copied across phi_d" if view == "2d" else "3D table"}, indent=2))
    label = "predictive variance (" + getattr(method, "feature_label", "features") + ")"
    note = sparse_tail_note(ignored, n) if ignored else None
    return table, variance, view, label, warning, note


def _check_references(references):
    """Read every reference photo and environment map `run` will need, before any slow work:
    bad input (unreadable, wrong size, not lat-long) fails in seconds, not after inference.

    Returns {photo index: (rgb, measured)} for the photos that exist (render compares with them
    over the object's measured pixels: capture.load_reference_entry).
    """
    loaded = {}
    for photo in references:
        if photo.light is not None and photo.light.type == "envmap":
            read_envmap_pixels(photo.light.file)
        if photo_exists(photo):
            loaded[photo.index] = capture.load_reference_entry(photo)
    return loaded


def _render_and_compare(scene, geometry, method_name, table, spp, out_dir, references, loaded,
                        level=True):
    """Render and compare every reference for one method; `level=False` (an export's fit of a
    method's own table) leaves it out of the report's level check."""
    rows = []
    brdf = table if isinstance(table, (MaterialMap, DiffuseAlbedoMap)) else TabulatedBRDF(table)
    for photo, image, mask in render_scene(scene, brdf, spp=spp, photos=references,
                                           geometry=geometry):
        write_exr(out_dir / f"{photo.stem}.exr", image)
        write_preview(out_dir / f"{photo.stem}.png", image)
        row = {"photo": photo.stem, "method": method_name, "render": image, "mask": mask}
        if photo.index in loaded:
            reference, measured = loaded[photo.index]
            metrics, delta_e = write_comparison(out_dir, image, reference, mask & measured,
                                                json_name=f"{photo.stem}_compare.json",
                                                png_name=f"{photo.stem}_delta_e.png",
                                                return_map=True)
            row.update(metrics, reference=reference, delta_e_map=delta_e)
            if level:
                row["level_ratio_rgb"] = level_ratio(image, reference, mask & measured).tolist()
        else:
            row.update(delta_e_log_mean=None, rel_rmse=None)
        rows.append(row)
    return rows


def run(args, load_methods=None):
    """`flashbrdf run`; load_methods(names, model_path, anchor) -> {name: fitted method} replaces
    the model read (batch passes its per-worker cache)."""

    methods = _methods(args.methods)
    model_path = _model_path(args, methods)
    spp = samples_per_pixel(args)
    materials_option(getattr(args, "materials", None))  # bad --materials: before the model loads
    scene = capture.load_scene(args.scene_dir)
    check_outputs(inputs=[args.scene_dir, *scene.input_files(), model_path], outputs=[args.out],
                  folders=[args.out])
    if model_path is not None:
        check_model_file(model_path)
    references = scene.references(reference_outputs)
    loaded = _check_references(references)
    with staged_output_dir(args.out, force=getattr(args, "force", False), command="run") as staged:
        stages, report = _run_stages(args, scene, methods, model_path, spp, references, loaded,
                                     Path(staged), load_methods)
    return _finish(stages, report, Path(args.out))


def _run_stages(args, scene, methods, model_path, spp, references, loaded, out,
                load_methods=None):
    """The slow part of `run`, into the staged folder `out`: returns (stages, report dict)."""
    # run_materials calls back into this module (_infer, _render_and_compare): an import cycle
    from flashbrdf.pipeline.run_materials import (label_section, material_entries, run_albedo_map,
                                        run_materials)

    materials = materials_option(getattr(args, "materials", None))
    export = getattr(args, "export", False)
    # where `out` ends up: args.out, once run's staged folder is renamed there; a batch runs
    # into a staging folder of its own and names the capture's final folder (final_out)
    final = Path(getattr(args, "final_out", None) or args.out)
    albedo_map = bool(getattr(args, "albedo_map", False))
    stages, notes = _Stages(total=6 + 2 * len(methods) + 2 * export + albedo_map), []
    fitted = stages.run("load model", load_methods or _load_methods, methods, model_path,
                        not args.no_anchor)
    options = ExtractOptions()
    samples = stages.run("extract", collect_samples, scene, options)
    segmentation, faces = stages.run("segment", segment_scene, samples, materials)
    title = f"flashbrdf run {Path(args.scene_dir).name}"
    with_albedo = (run_albedo_map(stages, out, samples, segmentation, faces, scene, notes)
                   if albedo_map else None)
    if segmentation.k > 1:
        ctx = SimpleNamespace(
            scene=scene, scene_dir=args.scene_dir, out=out, stages=stages, options=options,
            methods=methods, model_path=model_path, spp=spp, notes=notes, title=title,
            load_methods=lambda: fitted, geometry=lambda: SceneGeometry(scene), loaded=loaded,
            final_out=final, with_albedo=with_albedo or (lambda brdf: brdf),
            export=export, envmap=scene_envmap(references))
        return stages, run_materials(ctx, samples, segmentation, faces)
    result = stages.run("extract", bin_samples, samples)
    rho = write_extraction(out / "slice.csv", args.scene_dir, result, options,
                           final_path=final / "slice.csv")
    write_labels(out / "labels.png", segmentation, faces)

    predictions, two_d, ood_warnings = {}, [], []
    for name in methods:
        table, variance, view, label, warning, tail_note = stages.run(
            f"infer {name}", _infer, fitted[name], name, model_path, rho, result.n, out / name)
        if tail_note and tail_note.removeprefix("note: ") not in notes:  # the same for every method
            print(tail_note, file=sys.stderr)
            notes.append(tail_note.removeprefix("note: "))
        if warning:
            print(warning, file=sys.stderr)
            ood_warnings.append(warning.removeprefix("warning: "))
        predictions[name] = {"table": table, "variance": variance, "file": f"{name}/brdf.binary",
                             "variance_label": label}
        if view == "2d":
            two_d.append(name)

    exported = None
    if export:
        exported = stages.run("export", export_for_report, out, export_method(methods),
                              scene_envmap(references), final)
        notes.append(exported[2])
    if two_d:
        notes.append(f"{', '.join(two_d)}: 2D predictions rho(theta_h, theta_d) (the model has no "
                     "3D data); no 3D table was loaded, and renders look the 2D tables up directly.")
    rows = []
    if not references:
        notes.append("The scene has no reference photo: nothing was rendered or compared.")
    else:
        geometry = stages.run("ray cast", SceneGeometry, scene)
        if scene.geometry.mesh is None:
            notes.append("Normal-map geometry: no rays were cast.")
        elif geometry.convex:
            notes.append("Convex mesh: no shadow rays were cast.")
        for name in methods:
            brdf = predictions[name]["table"]
            if with_albedo is not None:
                brdf = with_albedo(TabulatedBRDF(brdf))
            rows += stages.run(f"render+compare {name}", _render_and_compare, scene, geometry, name,
                               brdf, spp, out / name, references, loaded)
        if exported is not None:
            label, table = exported[:2]
            rows += stages.run(f"render+compare {label}", _render_and_compare, scene, geometry,
                               label, table, spp, out / label, references, loaded, level=False)
    observed = {"rho": rho, "n": result.n, "spread": result.spread}
    (out / "figures").mkdir(parents=True, exist_ok=True)
    sections = label_section(segmentation.labels, out / "figures", segmentation.criterion)
    extra = {"materials": material_entries(segmentation.labels, {1: "slice.csv"},
                                           {m: {1: p["file"]} for m, p in predictions.items()}),
             "segmentation": segmentation.criterion}
    report = stages.run("report", write_report, out, stages=dict(stages.seconds), references=rows,
                        observed=observed, predictions=predictions, notes=notes, title=title,
                        warnings=ood_warnings, extra=extra, sections=sections)
    return stages, report


def _finish(stages, report, out):
    """Close the progress bar and print the stage table, the summary and the report's path."""
    stages.bar.close()
    print(stages.table(), file=sys.stderr)
    for method, summary in report.get("summary", {}).items():
        mean = summary.get("delta_e_log_mean", {}).get("mean")
        if mean is not None:
            print(f"{method}: mean delta_e_log_mean {mean:.3f} over {summary['references']} "
                  "reference(s)", file=sys.stderr)
    print(f"report: {(out / 'report.md').resolve()}")
    return 0
