"""`flashbrdf run SCENE_DIR --out OUT_DIR [--model MODEL.npz] [--methods dsgplvm,pca,...]`."""

from flashbrdf.cli.options import add_force, add_run_options, run_options


def add_parsers(sub):
    s = sub.add_parser("run", help="extract, infer, render and compare in one go")
    s.add_argument("scene_dir", metavar="SCENE_DIR")
    s.add_argument("--out", required=True, metavar="OUT_DIR")
    add_force(s)
    add_run_options(s)
    s.set_defaults(handler=run)


def run(args):
    from flashbrdf.pipeline.run import run_capture
    run_capture(args.scene_dir, args.out, force=args.force, **run_options(args))
