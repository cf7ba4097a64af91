"""`flashbrdf extract SCENE_DIR --out SLICE.csv` and `extract SCENE_DIR --labels LABELS.png --out
DIR`."""

from flashbrdf.cli.options import FORCE_HELP, add_force


def add_parsers(sub):
    s = sub.add_parser("extract", help="extract the flash slice from a capture folder")
    s.add_argument("scene_dir", metavar="SCENE_DIR")
    s.add_argument("--out", required=True, metavar="SLICE.csv|DIR")
    s.add_argument("--labels", metavar="LABELS.png",
                   help="one slice per material: DIR/material_<k>.csv and DIR/coverage.json")
    s.add_argument("--max-theta-d", type=float, metavar="DEG",
                   help="reject pixels with theta_d above this (default 5 degrees)")
    s.add_argument("--min-cos", type=float, help="reject cos(theta_i|o) below this (default 0.1)")
    s.add_argument("--silhouette-px", type=int, metavar="PX",
                   help="reject pixels this close to the object's outline (default 1)")
    s.add_argument("--refine-poses", action="store_true",
                   help="first refine each flash view's pose against the pooled "
                        "slice (a pose a pixel off blurs the highlight; up to 3 more passes)")
    add_force(s, "with --labels: " + FORCE_HELP)
    s.set_defaults(handler=extract)


def extract(args):
    from flashbrdf.pipeline import capture_jobs
    options = capture_jobs.extract_options(args.max_theta_d, args.min_cos, args.silhouette_px,
                                           args.refine_poses)
    if args.labels:
        capture_jobs.extract_materials(args.scene_dir, args.labels, args.out, options,
                                       force=args.force)
    else:
        capture_jobs.extract(args.scene_dir, args.out, options)
