"""3D inference time of the DS-GPLVM as `flashbrdf infer --view 3d` does it: the training tables are
read from their MERL (NBRDF proxy) files (valid bins only, memory-mapped, float32) and combined in
feature space on worker threads.

For 60 training materials (Table 1's size) and for a model of 99: fit (60) or load (99),
then time predict(slice, "3d") for a held-out slice, cold (first call) and warm (median of the
next --repeats), with 1 and 2 worker threads. Writes benchmarks/results/infer3d_speed.json.

    python -m benchmarks.infer3d_speed --merl-dir /work/merl [--repeats 3]
"""

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

from flashbrdf.brdf import merl, views
from flashbrdf.files.atomic import write_text
from flashbrdf.infer import TrainingSet, load_method, make_method

HELD_OUT = "red-specular-plastic"


def _time_predict(method, flash_slice, workers, repeats):
    os.environ["FLASHBRDF_THREADS"] = str(workers)
    times = []
    for _ in range(repeats + 1):
        t0 = time.perf_counter()
        method.predict(flash_slice, "3d")
        times.append(time.perf_counter() - t0)
    return {"first_s": times[0], "median_s": float(np.median(times[1:])), "all_s": times}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--merl-dir", default="/work/merl")
    ap.add_argument("--model", default=str(ROOT / "sample_data" / "models" / "merl100_1d2d.npz"))
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "infer3d_speed.json"))
    args = ap.parse_args(argv)
    names = [n for n, _ in merl.list_merl(args.merl_dir) if n != HELD_OUT]
    flash_slice = views.flash_slice(merl.read_merl(dict(merl.list_merl(args.merl_dir))[HELD_OUT]))[0]
    rng = np.random.default_rng(0)
    train60 = sorted(rng.choice(names, 60, replace=False))
    t0 = time.perf_counter()
    m60 = make_method("dsgplvm", anchor=True, feature_space="rgb").fit(
        TrainingSet.from_merl_dir(args.merl_dir, train60))
    fit60 = time.perf_counter() - t0
    m99 = load_method(args.model, "dsgplvm", args.merl_dir, anchor=True)
    result = {"command": "python -m benchmarks.infer3d_speed --merl-dir DIR",
              "machine": {"cpus": os.cpu_count(), "load_average_start": os.getloadavg()},
              "held_out": HELD_OUT, "fit_60_s (read + fit)": fit60, "runs": {}}
    for label, method in (("60 training tables", m60), ("99 training tables", m99)):
        for workers in (1, 2):
            result["runs"][f"{label}, {workers} thread(s)"] = _time_predict(
                method, flash_slice, workers, args.repeats)
            print(label, workers, result["runs"][f"{label}, {workers} thread(s)"], flush=True)
    result["machine"]["load_average_end"] = os.getloadavg()
    write_text(args.out, json.dumps(result, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
