"""The jobs of `render` and `compare` (contract, INTERFACES.md "Commands").

render: OUT_DIR/<stem>.exr per reference photo (the photo's pixel units; 0 off the geometry),
OUT_DIR/<stem>.png (tone-mapped preview), and where the reference photo exists
OUT_DIR/<stem>_compare.json (+ <stem>_delta_e.png), compared over the pixels that see the
geometry and that the photo measures (a float photo's 0 is a measurement, a clipped pixel or an
integer code 0 is not: capture.load_reference_entry). OUT_DIR/render.json lists timings and
settings.
compare: OUT_DIR/compare.json {"delta_e_log_mean", "delta_e_log_median", "rel_rmse", "pixels"}
and OUT_DIR/delta_e.png (false colour, with a colour bar).
"""

import json
import time
from pathlib import Path

from flashbrdf import capture
from flashbrdf.brdf.merl import read_merl
from flashbrdf.brdf.models import TabulatedBRDF
from flashbrdf.files.atomic import write_text
from flashbrdf.files.errors import InputError
from flashbrdf.files.outputs import check_outputs, staged_output_dir
from flashbrdf.pipeline.albedo_files import albedo_sidecars, read_albedo
from flashbrdf.pipeline.label_files import faces_path, flash_photo_camera, material_map_inputs
from flashbrdf.pipeline.options import samples_per_pixel
from flashbrdf.pipeline.run_steps import reference_outputs
from flashbrdf.render.albedo_map import DiffuseAlbedoMap
from flashbrdf.render.compare import comparison_mask, write_comparison
from flashbrdf.render.images import read_image, read_mask, write_exr, write_preview
from flashbrdf.render.material_map import MaterialMap
from flashbrdf.render.scene_render import render_scene


def brdf_paths(text):
    """--brdf B1.binary[,B2.binary,...] as [path]; InputError for an empty item (`a,,b`, a
    trailing comma), which would silently shift material k onto another table."""
    paths = [p.strip() for p in str(text).split(",")]
    if not all(paths):
        raise InputError("--brdf", f"item {paths.index('') + 1} of {len(paths)} is empty in "
                                   f"{text!r}; give one table per material, comma-separated")
    return paths


def side_inputs(labels_png=None, albedo_exr=None):
    """The files `--labels LABELS.png` and `--albedo ALBEDO.exr` read beside them (LABELS.png,
    LABELS.faces.npy; ALBEDO.exr, ALBEDO.json, ALBEDO.faces.npy): inputs no output may touch."""
    found = []
    if labels_png:
        found += [labels_png, faces_path(labels_png)]
    if albedo_exr:
        found += [albedo_exr, *albedo_sidecars(albedo_exr)]
    return found


def render(scene_dir, brdf, out, *, labels_png=None, albedo_exr=None, spp=64, seed=0,
           interpolate=False, force=False):
    """`flashbrdf render`: every reference photo's lighting rendered with the table(s) `brdf`
    ("B.binary" or "B1,B2,..." with labels_png: material k with table k)."""
    spp = samples_per_pixel(spp)
    paths = brdf_paths(brdf)
    scene = capture.load_scene(scene_dir)
    # every file read is an input (each table, the labels and the albedo map with their sidecars)
    check_outputs(inputs=[scene_dir, *scene.input_files(), *paths, *side_inputs(
        labels_png, albedo_exr)], outputs=[out], folders=[out])
    references = scene.references(reference_outputs)
    if not references:
        raise InputError(f"{scene.json_path}: photos", "no photo has role 'reference'")
    if len(paths) > 1 and not labels_png:
        raise InputError("--brdf", f"{len(paths)} tables need --labels LABELS.png to say which "
                                   "pixels each one covers")
    if labels_png:  # check the labels before reading any table
        labels, faces, camera = material_map_inputs(scene, labels_png, len(paths))
    tables = [read_merl(p) for p in paths]
    models = [TabulatedBRDF(t, interpolate=interpolate) for t in tables]
    model = MaterialMap(models, labels, camera, faces) if labels_png else models[0]
    if albedo_exr:
        flash_camera = camera if labels_png else flash_photo_camera(scene, "--albedo")
        albedo, floors, albedo_faces = read_albedo(albedo_exr, scene, flash_camera, tables)
        model = DiffuseAlbedoMap(model, albedo, floors, flash_camera, albedo_faces)
    seed = int(seed or 0)
    report = {"brdf": str(Path(paths[0]).resolve()) if len(paths) == 1 else
              [str(Path(p).resolve()) for p in paths], "spp": spp, "seed": seed, "renders": []}
    if labels_png:
        report["labels"] = str(Path(labels_png).resolve())
    if albedo_exr:
        report["albedo"] = str(Path(albedo_exr).resolve())
    # Each photo's files are written into the staged folder as it is rendered, and its arrays
    # let go: bad input found part-way (an unreadable envmap or photo) removes the folder whole,
    # so nothing is left behind, and 12 views of 24 MP no longer sit in memory (0.6 GB each)
    with staged_output_dir(out, force=force, command="render") as staged:
        staged = Path(staged)
        started = time.perf_counter()
        for photo, image, mask in render_scene(scene, model, spp=spp, seed=seed,
                                               photos=references):
            entry = {"photo": photo.stem, "exr": f"{photo.stem}.exr",
                     "seconds": round(time.perf_counter() - started, 3),
                     "pixels": int(mask.sum())}
            write_exr(staged / f"{photo.stem}.exr", image)
            write_preview(staged / f"{photo.stem}.png", image)
            if capture.photo_exists(photo):
                rgb, measured = capture.load_reference_entry(photo)
                entry["compare"] = write_comparison(staged, image, rgb, mask & measured,
                                                    json_name=f"{photo.stem}_compare.json",
                                                    png_name=f"{photo.stem}_delta_e.png")
                del rgb, measured
            report["renders"].append(entry)
            del image, mask
            started = time.perf_counter()
        write_text(staged / "render.json", json.dumps(report, indent=2) + "\n")


def compare(pred, ref, out, mask=None, force=False):
    """`flashbrdf compare PRED REF --out DIR`: compare.json and the false-colour delta_e.png."""
    check_outputs(inputs=[pred, ref, mask], outputs=[out], folders=[out])
    predicted = read_image(pred)
    reference = read_image(ref)
    if predicted.shape != reference.shape:
        raise InputError(ref, f"is {reference.shape[1]}x{reference.shape[0]} but {pred} is "
                              f"{predicted.shape[1]}x{predicted.shape[0]}")
    selected = read_mask(mask, predicted.shape) if mask else None
    # A reference with nothing in it, or a mask selecting nothing, is bad input. A black (or
    # all-NaN) prediction is a valid, bad prediction: its metrics are null over no pixel, as
    # render and run write them.
    if selected is not None and not comparison_mask(predicted, reference, selected).any():
        raise InputError(mask, "selects no pixel where both images are finite: nothing to "
                               "compare")
    if selected is None and not comparison_mask(reference, reference).any():
        raise InputError(ref, "no pixel is finite and nonzero: nothing to compare with")
    with staged_output_dir(out, force=force, command="compare") as staged:
        write_comparison(staged, predicted, reference, selected)
