"""`flashbrdf render` and `flashbrdf compare` (contract, INTERFACES.md "Commands").

render SCENE_DIR --brdf BRDF.binary --out OUT_DIR [--spp N] [--seed N] [--interpolate]
    OUT_DIR/<stem>.exr per reference photo (the photo's pixel units; 0 off the geometry),
    OUT_DIR/<stem>.png (tone-mapped preview), and where the reference photo exists
    OUT_DIR/<stem>_compare.json (+ <stem>_delta_e.png), compared over the pixels that see the
    geometry and that the photo measures (a float photo's 0 is a measurement, a clipped pixel or
    an integer code 0 is not: capture.load_reference_entry). OUT_DIR/render.json lists timings
    and settings.
compare PRED.exr REF.exr [--mask MASK.png] --out OUT_DIR
    OUT_DIR/compare.json {"delta_e_log_mean", "delta_e_log_median", "rel_rmse", "pixels"} and
    OUT_DIR/delta_e.png (false colour, with a colour bar).
"""

import json
import time
from pathlib import Path

from flashbrdf import capture
from flashbrdf.files.atomic import write_text
from flashbrdf.files.errors import InputError
from flashbrdf.brdf.merl import read_merl
from flashbrdf.pipeline.albedo_files import albedo_sidecars, read_albedo
from flashbrdf.pipeline.cmd_segment import faces_path, flash_photo_camera
from flashbrdf.files.outputs import check_outputs, staged_output_dir
from flashbrdf.render.albedo_map import DiffuseAlbedoMap
from flashbrdf.brdf.models import TabulatedBRDF
from flashbrdf.render.compare import comparison_mask, write_comparison
from flashbrdf.render.images import read_image, read_mask, write_exr, write_preview
from flashbrdf.render.material_map import MaterialMap
from flashbrdf.render.scene_render import render_scene

MAX_SPP = 1 << 20  # samples per pixel; 16,384 times the default


def photo_exists(photo):
    """Whether a photo entry's file (or every bracket) is on disk; a reference may be absent."""
    if photo.file is not None:
        return Path(photo.file).is_file()
    return bool(photo.brackets) and all(Path(p).is_file() for p, _ in photo.brackets)


def samples_per_pixel(args):
    """--spp of `render` and `run`: 64 when absent; InputError below 1 (never silently 64) or
    above MAX_SPP (the sample pattern alone would not fit in memory)."""
    spp = getattr(args, "spp", None)
    spp = 64 if spp is None else int(spp)
    if not 1 <= spp <= MAX_SPP:
        raise InputError("--spp", f"must be in 1..{MAX_SPP}, got {spp}")
    return spp


def brdf_paths(text):
    """--brdf B1.binary[,B2.binary,...] as [path]; InputError for an empty item (`a,,b`, a
    trailing comma), which would silently shift material k onto another table."""
    paths = [p.strip() for p in str(text).split(",")]
    if not all(paths):
        raise InputError("--brdf", f"item {paths.index('') + 1} of {len(paths)} is empty in "
                                   f"{text!r}; give one table per material, comma-separated")
    return paths


def reference_outputs(stem):
    """The files render and run write for one reference photo (in OUT_DIR, or OUT_DIR/<method>)."""
    return [f"{stem}.exr", f"{stem}.png", f"{stem}_compare.json", f"{stem}_delta_e.png"]


def side_inputs(labels_png=None, albedo_exr=None):
    """The files `--labels LABELS.png` and `--albedo ALBEDO.exr` read beside them (LABELS.png,
    LABELS.faces.npy; ALBEDO.exr, ALBEDO.json, ALBEDO.faces.npy): inputs no output may touch."""
    found = []
    if labels_png:
        found += [labels_png, faces_path(labels_png)]
    if albedo_exr:
        found += [albedo_exr, *albedo_sidecars(albedo_exr)]
    return found


def render(args):
    spp = samples_per_pixel(args)
    paths = brdf_paths(args.brdf)
    labels_png = getattr(args, "labels", None)
    albedo_exr = getattr(args, "albedo", None)
    scene = capture.load_scene(args.scene_dir)
    # every file read is an input (each table, the labels and the albedo map with their sidecars)
    check_outputs(inputs=[args.scene_dir, *scene.input_files(), *paths, *side_inputs(
        labels_png, albedo_exr)], outputs=[args.out], folders=[args.out])
    references = scene.references(reference_outputs)
    if not references:
        raise InputError(f"{scene.json_path}: photos", "no photo has role 'reference'")
    if len(paths) > 1 and not labels_png:
        raise InputError("--brdf", f"{len(paths)} tables need --labels LABELS.png to say which "
                                   "pixels each one covers")
    interpolate = bool(getattr(args, "interpolate", False))
    if labels_png:  # check the labels before reading any table
        from flashbrdf.pipeline.cmd_segment import material_map_inputs  # it imports this module: a cycle
        labels, faces, camera = material_map_inputs(scene, labels_png, len(paths))
    tables = [read_merl(p) for p in paths]
    models = [TabulatedBRDF(t, interpolate=interpolate) for t in tables]
    brdf = MaterialMap(models, labels, camera, faces) if labels_png else models[0]
    if albedo_exr:
        flash_camera = camera if labels_png else flash_photo_camera(scene, "--albedo")
        albedo, floors, albedo_faces = read_albedo(albedo_exr, scene, flash_camera, tables)
        brdf = DiffuseAlbedoMap(brdf, albedo, floors, flash_camera, albedo_faces)
    seed = int(getattr(args, "seed", None) or 0)
    report = {"brdf": str(Path(paths[0]).resolve()) if len(paths) == 1 else
              [str(Path(p).resolve()) for p in paths], "spp": spp, "seed": seed, "renders": []}
    if labels_png:
        report["labels"] = str(Path(labels_png).resolve())
    if albedo_exr:
        report["albedo"] = str(Path(albedo_exr).resolve())
    # Render and load every reference first, write afterwards: bad input found part-way (an
    # unreadable envmap or photo) then leaves no output file behind.
    results = []
    started = time.perf_counter()
    for photo, image, mask in render_scene(scene, brdf, spp=spp, seed=seed, photos=references):
        entry = {"photo": photo.stem, "exr": f"{photo.stem}.exr",
                 "seconds": round(time.perf_counter() - started, 3), "pixels": int(mask.sum())}
        reference = capture.load_reference_entry(photo) if photo_exists(photo) else None
        results.append((photo, image, mask, reference, entry))
        started = time.perf_counter()
    with staged_output_dir(args.out, force=getattr(args, "force", False),
                           command="render") as staged:
        out = Path(staged)
        for photo, image, mask, reference, entry in results:
            write_exr(out / f"{photo.stem}.exr", image)
            write_preview(out / f"{photo.stem}.png", image)
            if reference is not None:
                rgb, measured = reference
                entry["compare"] = write_comparison(out, image, rgb, mask & measured,
                                                    json_name=f"{photo.stem}_compare.json",
                                                    png_name=f"{photo.stem}_delta_e.png")
            report["renders"].append(entry)
        write_text(out / "render.json", json.dumps(report, indent=2) + "\n")
    return 0


def compare(args):
    check_outputs(inputs=[args.pred, args.ref, getattr(args, "mask", None)], outputs=[args.out],
                  folders=[args.out])
    pred = read_image(args.pred)
    ref = read_image(args.ref)
    if pred.shape != ref.shape:
        raise InputError(args.ref, f"is {ref.shape[1]}x{ref.shape[0]} but {args.pred} is "
                                   f"{pred.shape[1]}x{pred.shape[0]}")
    mask = read_mask(args.mask, pred.shape) if getattr(args, "mask", None) else None
    # A reference with nothing in it, or a mask selecting nothing, is bad input. A black (or
    # all-NaN) prediction is a valid, bad prediction: its metrics are null over no pixel, as
    # render and run write them.
    if mask is not None and not comparison_mask(pred, ref, mask).any():
        raise InputError(args.mask, "selects no pixel where both images are finite: nothing "
                                    "to compare")
    if mask is None and not comparison_mask(ref, ref).any():
        raise InputError(args.ref, "no pixel is finite and nonzero: nothing to compare with")
    with staged_output_dir(args.out, force=getattr(args, "force", False),
                           command="compare") as out:
        write_comparison(out, pred, ref, mask)
    return 0
