"""`flashbrdf render SCENE_DIR --brdf B[,B2,...] --out OUT_DIR` and `flashbrdf compare PRED REF
--out OUT_DIR`."""

from flashbrdf.cli.options import add_force


def add_parsers(sub):
    s = sub.add_parser("render", help="render every reference photo's lighting")
    s.add_argument("scene_dir", metavar="SCENE_DIR")
    s.add_argument("--brdf", required=True, metavar="BRDF.binary[,BRDF2.binary,...]")
    s.add_argument("--labels", metavar="LABELS.png",
                   help="material k of the label image is rendered with the k-th table")
    s.add_argument("--albedo", metavar="ALBEDO.exr",
                   help="a per-pixel diffuse albedo map (segment --albedo) replaces each "
                        "material's diffuse floor")
    s.add_argument("--out", required=True, metavar="OUT_DIR")
    add_force(s)
    s.add_argument("--spp", type=int, default=64,
                   help="samples per pixel for environment maps (default 64)")
    s.add_argument("--seed", type=int, default=0, help="the samples' seed (default 0)")
    s.add_argument("--interpolate", action="store_true",
                   help="interpolate the BRDF table between bin centres (default: nearest bin)")
    s.set_defaults(handler=render)

    s = sub.add_parser("compare", help="log-CIELAB Delta E between two images",
                       description="Writes OUT_DIR/compare.json (delta_e_log_mean, "
                                   "delta_e_log_median, rel_rmse, pixels) and a false-colour "
                                   "Delta E PNG, over the mask, or where both images are finite "
                                   "and nonzero.")
    s.add_argument("pred", metavar="PRED.exr")
    s.add_argument("ref", metavar="REF.exr")
    s.add_argument("--mask", metavar="MASK.png")
    s.add_argument("--out", required=True, metavar="OUT_DIR")
    add_force(s)
    s.set_defaults(handler=compare)


def render(args):
    from flashbrdf.pipeline.render_jobs import render as job
    job(args.scene_dir, args.brdf, args.out, labels_png=args.labels, albedo_exr=args.albedo,
        spp=args.spp, seed=args.seed, interpolate=args.interpolate, force=args.force)


def compare(args):
    from flashbrdf.pipeline.render_jobs import compare as job
    job(args.pred, args.ref, args.out, mask=args.mask, force=args.force)
