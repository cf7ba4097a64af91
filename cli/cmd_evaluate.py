"""`flashbrdf evaluate --merl-dir DIR --out OUT_DIR [--test-dir DIR] [--render] ...`."""

from flashbrdf.cli.options import add_engine_options, add_force


def add_parsers(sub):
    s = sub.add_parser("evaluate", help="the paper's Table 1 (and Table 2 with --render)")
    s.add_argument("--merl-dir", required=True, action="append", metavar="DIR",
                   help="training tables (repeatable with --test-dir)")
    s.add_argument("--out", required=True, metavar="OUT_DIR")
    add_force(s)
    s.add_argument("--test-dir", metavar="DIR",
                   help="train on every --merl-dir table, score every method on these tables")
    s.add_argument("--render", action="store_true",
                   help="also Table 2: render each test prediction on a sphere under the maps")
    s.add_argument("--envmap", action="append", metavar="FILE",
                   help="with --render: a lat-long map for Table 2 (repeat it for several; "
                        "default two maps made in code, render.envmap.default_envmaps: a sky "
                        "with a sun and a studio)")
    s.add_argument("--quick", action="store_true",
                   help="one experiment (the first split) instead of 25: a few minutes")
    s.add_argument("--experiments", type=int, help="number of experiments (default 25)")
    s.add_argument("--time-budget", type=float, metavar="SECONDS",
                   help="stop starting experiments when this wall time would be exceeded")
    add_engine_options(s, "the experiments", "one after the other in this process")
    s.set_defaults(handler=evaluate)


def evaluate(args):
    from flashbrdf.pipeline.evaluate_job import evaluate as job
    job(args.merl_dir, args.out, test_dir=args.test_dir, render=args.render,
        envmaps=args.envmap, quick=args.quick, experiments=args.experiments,
        time_budget=args.time_budget, workers=args.workers, scheduler=args.scheduler,
        force=args.force)
