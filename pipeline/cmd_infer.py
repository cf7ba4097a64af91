"""`flashbrdf train`, `infer` and `evaluate`: the infer stage's commands."""

import json
import time
from pathlib import Path

import numpy as np

from brdf import merl, views
from brdf.atomic import write_text
from brdf.errors import InputError


def train(args):
    """Train the DS-GPLVM on every MERL table in --merl-dir; store what the baselines need too."""
    from infer import DSGPLVMMethod, TrainingSet
    from infer.evaluate import tune_baselines
    wanted = args.views.split(",")
    start = time.perf_counter()
    training = TrainingSet.from_merl_dir(args.merl_dir, keep_3d="3d" in wanted)
    if len(training) < 3:
        raise InputError(args.merl_dir, f"needs at least 3 MERL tables, found {len(training)}")
    params = tune_baselines(training, seed=args.seed,
                            feature_space=getattr(args, "feature_space", "auto"))
    space = params["dsgplvm"]["feature_space"]
    model = DSGPLVMMethod(views=wanted, seed=args.seed, feature_space=space).fit(training)
    params["dsgplvm"] = {"feature_space": space, "views": wanted, "seed": args.seed}
    params["train_seconds"] = time.perf_counter() - start
    from infer import save_model
    save_model(args.out, training, params, dsgplvm=model.model, merl_dir=args.merl_dir)
    print(f"trained on {len(training)} materials in {params['train_seconds']:.1f} s -> {args.out}")
    return 0


def _uncertainty_summary(variance, feature_label):
    if variance is None:
        return None
    v = np.ravel(np.asarray(variance, float))
    v = v[np.isfinite(v)]
    if not v.size:
        return None
    return {"space": f"brdf.colour features ({feature_label}), predictive variance",
            "mean": float(v.mean()), "median": float(np.median(v)), "max": float(v.max()),
            "mean_std": float(np.sqrt(v).mean())}


def infer(args):
    """Predict a full MERL table from a slice; write it and BRDF.json beside it."""
    from infer import load_method, make_method
    t0 = time.perf_counter()
    rho, n = views.read_slice_csv(args.slice)
    view = getattr(args, "view", "auto") or "auto"
    if args.model is None:
        if args.method != "chandraker":
            raise InputError("--model", f"method {args.method} needs a trained model")
        method, has_3d = make_method("chandraker").fit(None), True
    else:
        if not Path(args.model).is_file():
            raise InputError(args.model, "no such model file")
        overrides = {"anchor": not getattr(args, "no_anchor", False)} \
            if args.method == "dsgplvm" else {}
        method = load_method(args.model, args.method, args.merl_dir, **overrides)
        has_3d = args.method in ("chandraker", "ashikhmin") or method.training_.has_3d()
    if view == "auto":
        view = "3d" if has_3d else "2d"
    elif view == "3d" and not has_3d:
        raise InputError("--merl-dir", "a 3D prediction from a model without stored 3D data needs "
                         "--merl-dir")
    t1 = time.perf_counter()
    table, variance = method.predict(rho, view=view)
    t2 = time.perf_counter()
    if view == "2d":
        table = views.table_3d_from_2d(table)
    table = np.where(np.isfinite(table), table, -1.0)
    table[~merl.merl_valid_mask()] = -1.0
    merl.write_merl(args.out, table)
    t3 = time.perf_counter()
    report = {"method": args.method, "model": None if args.model is None else str(args.model),
              "slice": str(args.slice), "view": view,
              "predicted": "3D table" if view == "3d" else "2D table copied across phi_d",
              "observed_theta_h_bins": int(np.isfinite(rho).all(axis=1).sum()),
              "params": method.get_params(),
              "timings": {"load_s": t1 - t0, "predict_s": t2 - t1, "write_s": t3 - t2,
                          "total_s": t3 - t0},
              "uncertainty": _uncertainty_summary(variance, getattr(method, "feature_label", ""))}
    write_text(Path(args.out).with_suffix(".json"), json.dumps(report, indent=2, default=str) + "\n")
    return 0


def evaluate(args):
    """The paper's Table 1 protocol on --merl-dir (see infer.evaluate); with --render also its
    Table 2 (render.table2) on the mean-performing experiment's test materials, 2D predictions."""
    from infer.evaluate import experiment_predictor, run_evaluation
    from pipeline.dask_engine import check_engine_options, dask_client
    check_engine_options(args)
    options = dict(quick=args.quick, experiments=getattr(args, "experiments", None),
                   time_budget=getattr(args, "time_budget", None))
    if getattr(args, "workers", None) or getattr(args, "scheduler", None):
        with dask_client(args.workers, args.scheduler) as client:  # experiments as Dask tasks
            result = run_evaluation(args.merl_dir, args.out, client=client, **options)
    else:
        result = run_evaluation(args.merl_dir, args.out, **options)
    if getattr(args, "render", False):
        from render import table2
        names, predict = experiment_predictor(args.merl_dir, result)
        table2(args.merl_dir, args.out, predict, names=names)
    return 0
