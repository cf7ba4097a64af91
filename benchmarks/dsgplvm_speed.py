"""DS-GPLVM speed and held-out quality on the MERL (NBRDF proxy) tables.

For each seeded split of the materials (60 train, 20 test): train 1D + 2D, time it, time one 2D
prediction, record Eq. 12 per ADM cycle, and the LAB-log error (brdf.metrics.brdf_error) of the 2D
prediction of the 20 test materials from their flash slices, beside predicting the training mean and
the pca baseline (infer.baselines.PCA) for context. Settings: the defaults, and the paper as written.

    python -m benchmarks.dsgplvm_speed --merl-dir /work/merl [--splits 3] \
        [--out benchmarks/results/dsgplvm_speed.json]
"""

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np


from flashbrdf.brdf import colour, metrics
from flashbrdf.files.atomic import write_text
from flashbrdf.infer.baselines import PCA
from flashbrdf.infer.training_set import TrainingSet
from flashbrdf.infer.dsgplvm import DSGPLVM

SETTINGS = {
    "default": {},
    "per_dim": {"view_weighting": "per_dim"},
    "paper_as_written": {"view_weighting": "paper", "learn_inverse_width": True,
                         "inverse_width": 2.0, "variance": 0.95},
}


def features(rho, flat_from=1):
    """ρ (N, ..., 3) NaN = no data -> (N, D) brdf features, NaN kept."""
    feats = colour.rho_to_features(np.nan_to_num(rho))
    feats[~np.isfinite(rho).all(axis=-1)] = np.nan
    return feats.reshape(len(rho), -1)


def to_table(mean_features):
    feats = np.asarray(mean_features).reshape(90, 90, 3)
    table = colour.features_to_rho(np.nan_to_num(feats))
    table[~np.isfinite(feats).all(axis=-1)] = np.nan
    return table


def run_split(data, seed, n_train=60, n_test=20):
    order = np.random.default_rng(seed).permutation(len(data))
    train, test = order[:n_train], order[n_train:n_train + n_test]
    f1, f2 = features(data.slices), features(data.tables_2d)
    truth = data.tables_2d
    result = {"seed": seed, "test": [data.names[i] for i in test]}
    mean_table = to_table(np.nanmean(f2[train], axis=0))
    result["mean_predictor"] = [metrics.brdf_error(mean_table, truth[i]) for i in test]
    pca = PCA().fit(data.subset(train))
    result["pca"] = [metrics.brdf_error(pca.predict(data.slices[i], "2d")[0], truth[i])
                     for i in test]
    for name, kw in SETTINGS.items():
        t0 = time.perf_counter()
        model = DSGPLVM(**kw).fit({"1d": f1[train], "2d": f2[train]})
        fit_s = time.perf_counter() - t0
        errors, times = [], []
        for i in test:
            t0 = time.perf_counter()
            mean, _ = model.predict(f1[i], "2d")
            table = to_table(mean)
            times.append(time.perf_counter() - t0)
            errors.append(metrics.brdf_error(table, truth[i]))
        result[name] = {"lab_log": errors, "fit_s": fit_s, "predict_s_median": float(np.median(times)),
                        "q": model.q_, "n_cycles": model.n_cycles_,
                        "objective_history": [float(v) for v in model.objective_history_],
                        "labels_per_class": np.bincount(model.labels_).tolist()}
        print(f"split {seed} {name}: LAB-log mean {np.mean(errors):.3f} median "
              f"{np.median(errors):.3f} (mean predictor {np.mean(result['mean_predictor']):.3f}, pca "
              f"{np.mean(result['pca']):.3f}); fit {fit_s:.1f} s, predict "
              f"{np.median(times) * 1e3:.1f} ms, q {model.q_}, cycles {model.n_cycles_}", flush=True)
    return result


def summary(results, key):
    values = [v for r in results for v in (r[key]["lab_log"] if isinstance(r[key], dict) else r[key])]
    return {"mean": float(np.mean(values)), "median": float(np.median(values))}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--merl-dir", default="/work/merl")
    parser.add_argument("--splits", type=int, default=3)
    parser.add_argument("--out", default=str(Path(__file__).parent / "results" /
                                             "dsgplvm_speed.json"))
    args = parser.parse_args(argv)
    t0 = time.perf_counter()
    data = TrainingSet.from_merl_dir(args.merl_dir)
    load_s = time.perf_counter() - t0
    results = [run_split(data, seed) for seed in range(args.splits)]
    report = {
        "command": "python -m benchmarks.dsgplvm_speed --merl-dir " + args.merl_dir
                   + f" --splits {args.splits}",
        "machine": {"cpus": os.cpu_count()},
        "materials": len(data), "load_all_tables_s": load_s,
        "settings": {k: {**DSGPLVM().get_params(), **v} for k, v in SETTINGS.items()},
        "summary_lab_log": {k: summary(results, k)
                            for k in ["mean_predictor", "pca", *SETTINGS]},
        "fit_s": {k: [r[k]["fit_s"] for r in results] for k in SETTINGS},
        "predict_2d_s": {k: [r[k]["predict_s_median"] for r in results] for k in SETTINGS},
        "splits": results,
    }
    write_text(args.out, json.dumps(report, indent=1))
    print(json.dumps(report["summary_lab_log"], indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
