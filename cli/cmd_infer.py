"""`flashbrdf infer --model MODEL.npz --slice SLICE.csv --out BRDF.binary [--method ...]`."""

from flashbrdf.cli.options import ANCHOR_HELP, MODEL_HELP

METHOD_CHOICES = ["dsgplvm", "pca", "noll", "chandraker", "ashikhmin"]


def add_parsers(sub):
    s = sub.add_parser("infer", help="infer a full BRDF from a slice")
    s.add_argument("--model", metavar="MODEL.npz", help=MODEL_HELP)
    s.add_argument("--slice", required=True, metavar="SLICE.csv")
    s.add_argument("--out", required=True, metavar="BRDF.binary")
    s.add_argument("--method", default="dsgplvm", choices=METHOD_CHOICES,
                   help="default dsgplvm (the shipped default: the anchored DS-GPLVM averaged "
                        "with noll and pca)")
    s.add_argument("--merl-dir", action="append", metavar="DIR",
                   help="the model's training tables, for 3D (repeat it for a model trained on "
                        "several folders)")
    s.add_argument("--no-anchor", action="store_true", help=ANCHOR_HELP)
    s.add_argument("--view", default="auto", choices=["auto", "2d", "3d"],
                   help="predict 2D (copied across phi_d) or 3D; auto: 3D when training tables "
                        "are at hand")
    s.set_defaults(handler=infer)


def infer(args):
    from flashbrdf.pipeline.infer_jobs import infer as job
    job(args.model, args.slice, args.out, method_name=args.method, merl_dirs=args.merl_dir,
        anchor=not args.no_anchor, view=args.view)
