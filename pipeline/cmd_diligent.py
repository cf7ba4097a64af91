"""`flashbrdf import-diligent OBJ_DIR --flash INDEX --out SCENE_DIR` (contract command)."""

import sys

from tqdm import tqdm

from flashbrdf.pipeline.diligent import import_diligent as write_scene


def import_diligent(args):
    """Write a scene folder from a DiLiGenT object folder; prints where it is. Returns 0."""


    def progress(iterable):
        return tqdm(iterable, desc="import-diligent", unit="photo", file=sys.stderr,
                    disable=not sys.stderr.isatty())

    scene = write_scene(args.obj_dir, args.flash, args.out, progress=progress,
                        force=getattr(args, "force", False), notify=print)
    n_ref = sum(p["role"] == "reference" for p in scene["photos"])
    flash = next(p for p in scene["photos"] if p["role"] == "flash")
    print(f"wrote {args.out}: flash {flash['file']}, {n_ref} reference photos, "
          f"orthographic {scene['camera']['width']}x{scene['camera']['height']} camera")
    return 0
