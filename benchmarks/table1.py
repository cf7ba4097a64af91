"""The paper's Table 1 on the 100 MERL (NBRDF proxy) tables: writes benchmarks/results/table1.md,
table1.json and error_vs_runtime.png (slow: tens of minutes on 2 shared cores).

    nice -n 10 python -m benchmarks.table1 --merl-dir /work/merl --time-budget 4800

--time-budget stops starting new experiments when the remaining ones would not fit (the md says how
many ran). The 3D cache (~4 GB float32) goes to --cache-dir and is deleted at the end.
"""

import argparse
import os
import sys
import tempfile


from flashbrdf.experiments.evaluate import run_evaluation


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--merl-dir", default="/work/merl")
    ap.add_argument("--out", default=os.path.join(os.path.dirname(os.path.abspath(__file__)),
                                                  "results"))
    ap.add_argument("--experiments", type=int, default=25)
    ap.add_argument("--experiments-3d", type=int, default=2)
    ap.add_argument("--time-budget", type=float)
    ap.add_argument("--cache-dir", default=tempfile.gettempdir())
    args = ap.parse_args(argv)
    command = "nice -n 10 python -m benchmarks.table1 " + " ".join(
        a if not a.startswith("/") or "merl" in a else os.path.basename(a)
        for a in (argv if argv is not None else sys.argv[1:]))
    run_evaluation(args.merl_dir, args.out, experiments=args.experiments,
                   experiments_3d=args.experiments_3d, time_budget=args.time_budget,
                   command=command, cache_dir=args.cache_dir)
    return 0


if __name__ == "__main__":
    sys.exit(main())
