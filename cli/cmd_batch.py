"""`flashbrdf batch CAPTURES_DIR --out OUT_DIR [--workers N] [--scheduler ADDRESS] [run options]`."""

from flashbrdf.cli.options import add_engine_options, add_run_options, run_options


def add_parsers(sub):
    s = sub.add_parser("batch", help="run every capture in a folder, as Dask tasks")
    s.add_argument("captures_dir", metavar="CAPTURES_DIR")
    s.add_argument("--out", required=True, metavar="OUT_DIR")
    add_engine_options(s, "the captures", "one worker per core")
    s.add_argument("--force", action="store_true",
                   help="rerun captures whose output is already complete")
    add_run_options(s)
    s.set_defaults(handler=batch)


def batch(args):
    from flashbrdf.pipeline.batch import batch as job
    return job(args.captures_dir, args.out, workers=args.workers, scheduler=args.scheduler,
               force=args.force, **run_options(args))
