"""The jobs of `extract` and `segment`: a capture folder in, the slice(s) or the label files out.

Each takes values, checks its outputs against its inputs before any slow work (files.outputs)
and writes all or nothing; bad input raises InputError (exit 2).
"""

import sys
import time
from pathlib import Path

from flashbrdf import capture
from flashbrdf.files.errors import InputError
from flashbrdf.files.outputs import (check_outputs, check_sidecar_replaceable, sidecar_json,
                                     staged_output_dir)
from flashbrdf.pipeline.albedo_files import albedo_sidecars, check_albedo_out
from flashbrdf.pipeline.label_files import (faces_path, read_face_labels, read_labels,
                                            write_labels)
from flashbrdf.pipeline.options import fewer_materials_warning, materials_option
from flashbrdf.slice_extract import ExtractOptions, extract_slice
from flashbrdf.slice_extract.extract import collect_samples, extract_material_slices
from flashbrdf.slice_extract.segment import coarse_faces_warning, segment_scene
from flashbrdf.slice_extract.slice_files import (material_coverage, write_extraction,
                                                 write_material_slices)


def extract_options(max_theta_d=None, min_cos=None, silhouette_px=None, refine_poses=False):
    """ExtractOptions from `extract`'s options (None: the default); InputError out of range."""
    if max_theta_d is not None and not 0 < max_theta_d <= 90:
        raise InputError("--max-theta-d", f"expected degrees in (0, 90], got {max_theta_d}")
    if min_cos is not None and not 0 <= min_cos < 1:
        raise InputError("--min-cos", f"expected a value in [0, 1), got {min_cos}")
    if silhouette_px is not None and not 0 <= silhouette_px <= 50:
        raise InputError("--silhouette-px", f"expected 0..50 pixels, got {silhouette_px}")
    return ExtractOptions(
        silhouette_px=ExtractOptions.silhouette_px if silhouette_px is None else silhouette_px,
        max_theta_d_deg=ExtractOptions.max_theta_d_deg if max_theta_d is None else max_theta_d,
        min_cos=ExtractOptions.min_cos if min_cos is None else min_cos,
        refine_poses=bool(refine_poses))


def extract(scene_dir, out, options=None):
    """`flashbrdf extract SCENE_DIR --out SLICE.csv`: slice.csv and SLICE.json beside it."""
    options = options or ExtractOptions()
    scene = capture.load_scene(scene_dir)
    check_outputs(inputs=[scene_dir, *scene.input_files()], outputs=[out, sidecar_json(out)])
    check_sidecar_replaceable(sidecar_json(out), "slice_csv", "slice report (SLICE.json)")
    result = extract_slice(scene, options)
    write_extraction(out, scene_dir, result, options)
    for warning in result.report.get("warnings", []):
        print(f"warning: {warning}", file=sys.stderr)


def extract_materials(scene_dir, labels_png, out, options=None, force=False):
    """`extract --labels LABELS.png --out DIR`: DIR/material_<k>.csv and DIR/coverage.json."""
    options = options or ExtractOptions()
    out = Path(out)
    if out.suffix.lower() == ".csv" or (out.exists() and not out.is_dir()):
        raise InputError("--out", "with --labels, --out is a folder (material_<k>.csv go in it)")
    scene = capture.load_scene(scene_dir)
    check_outputs(inputs=[scene_dir, labels_png, faces_path(labels_png), *scene.input_files()],
                  outputs=[out],
                  folders=[out])
    # a folder output, so built aside and renamed: never written into someone's folder, and
    # never half-written
    with staged_output_dir(out, force=force, command="extract") as staged:
        samples = collect_samples(scene, options)
        labels = read_labels(labels_png, samples.shape)
        faces = read_face_labels(labels_png, int(labels.max()), scene, labels,
                                 samples.intersector)
        slices = extract_material_slices(samples, labels, labels_png, faces)
        write_material_slices(staged, scene_dir, slices, options, labels)
    warned = {w for r in slices.values() if r is not None for w in r.report.get("warnings", [])}
    # each material's coverage (no usable pixel, sparse, narrow) first: coverage.json's lines
    for warning in material_coverage(slices, labels)["warnings"] + sorted(warned):
        print(f"warning: {warning}", file=sys.stderr)


def segment(scene_dir, out, materials="auto", albedo_out=None):
    """`flashbrdf segment SCENE_DIR --out LABELS.png [--albedo ALBEDO.exr]`: the label files
    (pipeline.label_files) and, with albedo_out, the albedo map's (pipeline.albedo_files), all
    or none. Returns the number of materials."""
    materials = materials_option(materials)
    if Path(out).suffix.lower() != ".png":
        raise InputError("--out", f"the label image must be a .png, got {out}")
    if albedo_out:
        check_albedo_out(albedo_out)
    scene = capture.load_scene(scene_dir)
    check_outputs(inputs=[scene_dir, *scene.input_files()],
                  outputs=[out, faces_path(out), Path(out).with_suffix(".json"),
                           *([albedo_out, *albedo_sidecars(albedo_out)] if albedo_out else [])])
    started = time.perf_counter()
    samples = collect_samples(scene, ExtractOptions())
    traced = time.perf_counter()
    segmentation, faces = segment_scene(samples, materials)
    done = time.perf_counter()
    for warning in (fewer_materials_warning(segmentation, materials),
                    coarse_faces_warning(segmentation, faces, scene)):
        if warning:
            print(f"warning: {warning}", file=sys.stderr)
    albedo_written = False
    try:
        if albedo_out:  # computed before anything is written: a failure leaves no file
            from flashbrdf.pipeline.albedo_files import albedo_for_scene, write_albedo
            albedo, albedo_faces = albedo_for_scene(samples, segmentation.labels, faces)
            write_albedo(albedo_out, albedo, albedo_faces)
            albedo_written = True
        write_labels(out, segmentation, faces,
                     {"seconds": {"samples": round(traced - started, 3),
                                  "segment": round(done - traced, 3)}})
    except BaseException:  # the labels failed (or Ctrl-C): the albedo map goes too, all or none
        for path in [albedo_out, *albedo_sidecars(albedo_out)] if albedo_written else []:
            Path(path).unlink(missing_ok=True)
        raise
    return segmentation.k
