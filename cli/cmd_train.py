"""`flashbrdf train --merl-dir DIR [--merl-dir DIR2 ...] --out MODEL.npz`."""


def add_parsers(sub):
    s = sub.add_parser("train", help="train a DS-GPLVM model on MERL tables")
    s.add_argument("--merl-dir", required=True, action="append", metavar="DIR",
                   help="a folder of MERL tables; repeat it to train on the tables of several")
    s.add_argument("--out", required=True, metavar="MODEL.npz")
    s.add_argument("--views", default="1d,2d", choices=["1d,2d", "1d,2d,3d"],
                   metavar="1d,2d|1d,2d,3d",
                   help="the views the model shares (default 1d,2d; 1d,2d,3d also stores the "
                        "3D tables, GBs, for 3D predictions without --merl-dir)")
    s.add_argument("--feature-space", default="auto", choices=["auto", "lab", "rgb"],
                   help="dsgplvm features: CIELAB (the paper) or RGB of ln(1 + rho/1e-3); auto "
                        "picks one on a held-out 20%% of the tables, with slice anchoring")
    s.add_argument("--seed", type=int, default=0,
                   help="seed of the held-out split and the fits (0..2^32-1, default 0): the "
                        "same seed, the same model")
    s.set_defaults(handler=train)


def train(args):
    from flashbrdf.pipeline.infer_jobs import train as job
    job(args.merl_dir, args.out, views_text=args.views, feature_space=args.feature_space,
        seed=args.seed)
