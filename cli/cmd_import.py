"""`flashbrdf import-diligent OBJ_DIR --flash INDEX --out SCENE_DIR`: another capture format as a
scene folder (capture.importers)."""

import sys

from flashbrdf.cli.options import add_force


def add_parsers(sub):
    s = sub.add_parser("import-diligent", help="turn a DiLiGenT object folder into a scene folder")
    s.add_argument("obj_dir", metavar="OBJ_DIR")
    s.add_argument("--flash", required=True, type=int, metavar="INDEX")
    s.add_argument("--out", required=True, metavar="SCENE_DIR")
    add_force(s)
    s.set_defaults(handler=import_diligent)


def progress_bar(what):
    """A progress bar over photos on a terminal (none in a log)."""
    from tqdm import tqdm

    def progress(iterable):
        return tqdm(iterable, desc=what, unit="photo", file=sys.stderr,
                    disable=not sys.stderr.isatty())
    return progress


def import_diligent(args):
    from flashbrdf.capture.importers.diligent import import_diligent as write_scene
    scene = write_scene(args.obj_dir, args.flash, args.out, progress=progress_bar("import-diligent"),
                        force=args.force, notify=print)
    n_ref = sum(p["role"] == "reference" for p in scene["photos"])
    flash = next(p for p in scene["photos"] if p["role"] == "flash")
    print(f"wrote {args.out}: flash {flash['file']}, {n_ref} reference photos, "
          f"orthographic {scene['camera']['width']}x{scene['camera']['height']} camera")
