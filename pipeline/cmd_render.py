"""`flashbrdf render` and `flashbrdf compare` (contract, INTERFACES.md "Commands").

render SCENE_DIR --brdf BRDF.binary --out OUT_DIR [--spp N] [--seed N] [--interpolate]
    OUT_DIR/<stem>.exr per reference photo (the photo's pixel units; 0 off the geometry),
    OUT_DIR/<stem>.png (tone-mapped preview), and where the reference photo exists
    OUT_DIR/<stem>_compare.json (+ <stem>_delta_e.png), compared over the pixels that see the
    geometry and are usable in the photo. OUT_DIR/render.json lists timings and settings.
compare PRED.exr REF.exr [--mask MASK.png] --out OUT_DIR
    OUT_DIR/compare.json {"delta_e_log_mean", "delta_e_log_median", "rel_rmse", "pixels"} and
    OUT_DIR/delta_e.png (false colour, with a colour bar).
"""

import json
import os
import time
from pathlib import Path

from brdf.atomic import write_text
from brdf.errors import InputError


def _photo_exists(photo):
    if photo.file is not None:
        return Path(photo.file).is_file()
    return bool(photo.brackets) and all(Path(p).is_file() for p, _ in photo.brackets)


def render(args):
    import capture
    from brdf.merl import read_merl
    from render.brdf_models import TabulatedBRDF
    from render.compare import write_comparison
    from render.images import write_exr, write_preview
    from render.scene_render import render_scene

    spp = int(getattr(args, "spp", 64) or 64)
    if spp < 1:
        raise InputError("--spp", f"must be >= 1, got {spp}")
    scene = capture.load_scene(args.scene_dir)
    references = scene.photos_with_role("reference")
    if not references:
        raise InputError(f"{scene.json_path}: photos", "no photo has role 'reference'")
    brdf = TabulatedBRDF(read_merl(args.brdf), interpolate=bool(getattr(args, "interpolate", False)))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    seed = int(getattr(args, "seed", 0) or 0)
    report = {"brdf": str(Path(args.brdf).resolve()), "spp": spp, "seed": seed, "renders": []}
    started = time.perf_counter()
    for photo, image, mask in render_scene(scene, brdf, spp=spp, seed=seed, photos=references):
        elapsed = time.perf_counter() - started
        write_exr(out / f"{photo.stem}.exr", image)
        write_preview(out / f"{photo.stem}.png", image)
        entry = {"photo": photo.stem, "exr": f"{photo.stem}.exr", "seconds": round(elapsed, 3),
                 "pixels": int(mask.sum())}
        if _photo_exists(photo):
            reference, usable = capture.load_photo_entry(photo)
            metrics = write_comparison(out, image, reference, mask & usable,
                                       json_name=f"{photo.stem}_compare.json",
                                       png_name=f"{photo.stem}_delta_e.png")
            entry["compare"] = metrics
        report["renders"].append(entry)
        started = time.perf_counter()
    write_text(out / "render.json", json.dumps(report, indent=2) + "\n")
    return 0


def compare(args):
    from render.compare import write_comparison
    from render.images import read_image, read_mask

    pred = read_image(args.pred)
    ref = read_image(args.ref)
    if pred.shape != ref.shape:
        raise InputError(args.ref, f"is {ref.shape[1]}x{ref.shape[0]} but {args.pred} is "
                                   f"{pred.shape[1]}x{pred.shape[0]}")
    mask = read_mask(args.mask, pred.shape) if getattr(args, "mask", None) else None
    os.makedirs(args.out, exist_ok=True)
    write_comparison(args.out, pred, ref, mask)
    return 0
