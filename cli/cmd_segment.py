"""`flashbrdf segment SCENE_DIR --out LABELS.png [--materials auto|K] [--albedo ALBEDO.exr]`."""

from pathlib import Path


def add_parsers(sub):
    s = sub.add_parser("segment", help="label the flash photo's pixels by material")
    s.add_argument("scene_dir", metavar="SCENE_DIR")
    s.add_argument("--out", required=True, metavar="LABELS.png")
    s.add_argument("--materials", default="auto", metavar="auto|K",
                   help="the number of materials, or auto (default): chosen, 1 for one material")
    s.add_argument("--albedo", metavar="ALBEDO.exr",
                   help="also write a per-pixel diffuse albedo map (textured materials)")
    s.set_defaults(handler=segment)


def segment(args):
    from flashbrdf.pipeline.capture_jobs import segment as job
    k = job(args.scene_dir, args.out, args.materials, args.albedo)
    print(f"{k} material(s): {Path(args.out).resolve()}")
