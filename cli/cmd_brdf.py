"""`flashbrdf merl-slice BRDF.binary --out SLICE.csv`."""


def add_parsers(sub):
    s = sub.add_parser("merl-slice", help="write the theta_d = 0 slice of a MERL table")
    s.add_argument("brdf", metavar="BRDF.binary")
    s.add_argument("--out", required=True, metavar="SLICE.csv")
    s.set_defaults(handler=merl_slice)


def merl_slice(args):
    from flashbrdf.pipeline.infer_jobs import merl_slice as job
    job(args.brdf, args.out)
