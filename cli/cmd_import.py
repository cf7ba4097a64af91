"""`flashbrdf import-colmap MODEL_DIR --images DIR --mesh MESH --out SCENE_DIR` and `flashbrdf
import-diligent OBJ_DIR --flash INDEX --out SCENE_DIR`: another tool's capture as a scene folder
(capture.importers)."""

import re
import sys

from flashbrdf.cli.options import add_force


def add_parsers(sub):
    _add_import_colmap(sub)
    s = sub.add_parser("import-diligent", help="turn a DiLiGenT object folder into a scene folder")
    s.add_argument("obj_dir", metavar="OBJ_DIR")
    s.add_argument("--flash", required=True, type=int, metavar="INDEX",
                   help="1-based index of the photo to use as the flash (a light near the view: "
                        "52 for the ball); every other photo becomes a reference")
    s.add_argument("--out", required=True, metavar="SCENE_DIR")
    add_force(s)
    s.set_defaults(handler=import_diligent)


def import_diligent(args):
    from flashbrdf.capture.importers.diligent import import_diligent as write_scene
    from flashbrdf.files.progress import photo_progress
    from flashbrdf.slice_extract import ExtractOptions
    scene = write_scene(args.obj_dir, args.flash, args.out,
                        progress=lambda photos: photo_progress(photos, "import-diligent"),
                        force=args.force,
                        notify=lambda line: print(line, file=sys.stderr if line.startswith(
                            "warning") else sys.stdout),
                        max_theta_d_deg=ExtractOptions.max_theta_d_deg)
    n_ref = sum(p["role"] == "reference" for p in scene["photos"])
    flash = next(p for p in scene["photos"] if p["role"] == "flash")
    print(f"wrote {args.out}: flash {flash['file']}, {n_ref} reference photos, "
          f"orthographic {scene['camera']['width']}x{scene['camera']['height']} camera")


def _add_import_colmap(sub):
    s = sub.add_parser(
        "import-colmap", help="turn a COLMAP reconstruction of flash photos into a scene folder",
        description="Each registered image of the COLMAP sparse model MODEL_DIR (text or binary) "
                    "whose file stem matches a photo in --images becomes a flash photo with its "
                    "own camera. scene.json refers to the photos and the mesh; nothing is "
                    "copied.")
    s.add_argument("model_dir", metavar="MODEL_DIR", help="COLMAP sparse model folder (sparse/0)")
    s.add_argument("--images", required=True, metavar="DIR",
                   help="the flash photos (RAW, EXR, ...), named as the model's images")
    s.add_argument("--mesh", required=True, metavar="MESH",
                   help="the object's mesh in the model's frame and units")
    s.add_argument("--out", required=True, metavar="SCENE_DIR")
    s.add_argument("--flash-offset", default="0,0,0", metavar="X,Y,Z",
                   help="flash position in the camera frame (x right, y down, z forward), model "
                        "units (default 0,0,0: at the lens)")
    s.add_argument("--intensity", metavar="R,G,B",
                   help="the flash's intensity_rgb (default 1,1,1: the level is relative)")
    s.add_argument("--target", metavar="MESH",
                   help="a diffuse target of known reflectance (a grey card) seen in some flash "
                        "photos, its own mesh in the model's frame: it fixes the slice's "
                        "absolute level (scene.json \"level\")")
    s.add_argument("--reflectance", metavar="R[,G,B]",
                   help="the target's reflectance, one value or three, in (0, 1] (e.g. 0.18)")
    s.add_argument("--encoding", choices=["linear", "srgb"],
                   help="how the photos' codes map to light (default: 8-bit sRGB, 16-bit and "
                        "float linear); srgb for 16-bit TIFF/PNG a RAW converter wrote with the "
                        "sRGB curve")
    s.add_argument("--calibrated", action="store_true",
                   help="--intensity was measured before (a calibrated flash, scene units): the "
                        "level is absolute")
    add_force(s, "replace SCENE_DIR if an earlier flashbrdf command made it (never any other "
                 "folder)")
    s.set_defaults(handler=import_colmap)
    # `--flash-offset -0.03,0,0`: before Python 3.13 argparse reads a value that starts with "-"
    # and holds commas as an option; 3.13 reads any "-<digit>" as a number, as set here
    if hasattr(s, "_negative_number_matcher"):
        s._negative_number_matcher = re.compile(r"^-\.?\d")


def _numbers(text, flag):
    from flashbrdf.files.errors import InputError
    parts = text.split(",")
    try:
        values = [float(p) for p in parts]
    except ValueError:
        values = []
    if len(values) != 3:
        raise InputError(flag, f"expected three comma-separated numbers, got {text!r}")
    return values


def import_colmap(args):
    """Write the scene folder and print the summary on stdout."""
    from flashbrdf.capture.importers.colmap import import_colmap as write_scene
    done = write_scene(args.model_dir, args.images, args.mesh, args.out,
                       flash_offset=_numbers(args.flash_offset, "--flash-offset"),
                       intensity=(None if args.intensity is None else
                                  _numbers(args.intensity, "--intensity")),
                       force=args.force, target=args.target,
                       reflectance=None if args.reflectance is None else
                       _reflectance(args.reflectance), calibrated=args.calibrated,
                       encoding=args.encoding)
    for line in done.lines():
        print(line)
    if done.frame.warning():
        print(f"warning: {args.mesh}: {done.frame.warning()}", file=sys.stderr)


def _reflectance(text):
    from flashbrdf.files.errors import InputError
    try:
        values = [float(p) for p in text.split(",")]
    except ValueError:
        values = []
    if len(values) not in (1, 3):
        raise InputError("--reflectance", f"expected one number or three, got {text!r}")
    return values * 3 if len(values) == 1 else values
