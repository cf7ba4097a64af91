"""`flashbrdf train`, `infer` and `evaluate`: the infer stage's commands."""

import json
import sys
import time
from pathlib import Path

import numpy as np

from flashbrdf.brdf import merl, views
from flashbrdf.brdf.atomic import write_text
from flashbrdf.brdf.errors import InputError
from flashbrdf.experiments.evaluate import check_protocol_tables, experiment_predictor, run_evaluation
from flashbrdf.experiments.test_set import run_test_set
from flashbrdf.infer import TrainingSet, load_method, make_method, prediction_warning
from flashbrdf.infer.model_selection import check_training_size
from flashbrdf.infer.slices import (sample_counts, sparse_tail_note, sparse_tail_record,
                          without_sparse_tail)
from flashbrdf.infer.training import train_model
from flashbrdf.pipeline.dask_engine import check_engine_options, dask_client
from flashbrdf.pipeline.safety import check_outputs, sidecar_json, staged_output_dir


def _merl_inputs(merl_dirs):
    """MERL folders (one, a list, or None) and their tables (InputError when one is not a folder
    of tables)."""
    return [item for folder in _merl_dirs(merl_dirs)
            for item in (folder, *(path for _, path in merl.list_merl(folder)))]


def train(args):
    """Train the DS-GPLVM on every MERL table of every --merl-dir folder (infer.training); store
    what the baselines need too."""
    folders = _merl_dirs(args.merl_dir)
    if args.seed < 0:  # numpy's generators take none: a traceback after the tables were read
        raise InputError("--seed", f"must be a non-negative integer, got {args.seed}")
    check_outputs(inputs=_merl_inputs(folders), outputs=[args.out])
    training = TrainingSet.from_merl_dirs(folders, keep_3d="3d" in args.views.split(","))
    check_training_size(len(training), folders[0] if len(folders) == 1 else "--merl-dir")
    params = train_model(training, args.out, views=args.views.split(","), seed=args.seed,
                         feature_space=getattr(args, "feature_space", "auto"), merl_dirs=folders)
    print(f"trained on {len(training)} materials from {len(folders)} folder(s) in "
          f"{params['train_seconds']:.1f} s -> {args.out}")
    return 0


def _merl_dirs(value):
    """--merl-dir as a list of folders (the option may be repeated; a str is one folder)."""
    return [value] if isinstance(value, str) else list(value or [])


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
    t0 = time.perf_counter()
    json_path = sidecar_json(args.out)
    check_outputs(inputs=[args.model, args.slice, *_merl_inputs(args.merl_dir)],
                  outputs=[args.out, json_path])
    rho, n = views.read_slice_csv(args.slice)
    n = sample_counts(rho, n)  # an empty bin's n does not set the threshold the note tells
    rho, ignored = without_sparse_tail(rho, n)
    if ignored:
        print(sparse_tail_note(ignored, n), file=sys.stderr)
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
        has_3d = method.can_predict_3d()
    if view == "auto":
        view = "3d" if has_3d else "2d"
    elif view == "3d" and not has_3d:
        raise InputError("--merl-dir", "a 3D prediction from a model without stored 3D data needs "
                         "--merl-dir")
    training = getattr(method, "training_", None)
    missing = training.missing_3d if view == "3d" and training is not None else []
    if missing:
        print(f"warning: {len(missing)} of the model's training tables are not in --merl-dir "
              f"(e.g. {', '.join(missing[:3])}); their share of the 3D prediction is their 2D "
              f"table copied across phi_d", file=sys.stderr)
    t1 = time.perf_counter()
    table, variance = method.predict(rho, view=view)
    t2 = time.perf_counter()
    novelty, warning = prediction_warning(method, rho, args.slice)
    if warning:
        print(warning, file=sys.stderr)
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
              "sparse_tail_ignored": sparse_tail_record(ignored, n),
              "training_tables_2d_only": missing,
              "params": method.fitted_params(),
              "timings": {"load_s": t1 - t0, "predict_s": t2 - t1, "write_s": t3 - t2,
                          "total_s": t3 - t0},
              "uncertainty": _uncertainty_summary(variance, getattr(method, "feature_label", "")),
              "novelty": novelty}
    try:
        write_text(json_path, json.dumps(report, indent=2, default=str) + "\n")
    except BaseException:
        Path(args.out).unlink(missing_ok=True)  # both files or neither
        raise
    return 0


MAX_EXPERIMENTS = 10000


def _check_protocol_options(args):
    """InputError for --experiments below 1 (0 would silently mean all 25) or a --time-budget
    that is not a positive number of seconds."""
    experiments = getattr(args, "experiments", None)
    if experiments is not None and experiments < 1:
        raise InputError("--experiments", f"must be at least 1, got {experiments}")
    if experiments is not None and experiments > MAX_EXPERIMENTS:
        # each trains the models (seconds to minutes); 10**9 hung drawing its splits
        raise InputError("--experiments", f"must be at most {MAX_EXPERIMENTS}, got {experiments}")
    budget = getattr(args, "time_budget", None)
    if budget is not None and not (np.isfinite(budget) and budget > 0):
        raise InputError("--time-budget", f"must be a positive number of seconds, got {budget}")


def _render_envmaps(args):
    """Table 2's lat-long maps: every --envmap FILE, or None for the project's own maps
    (render.envmap.default_envmaps, made in code: never a file outside the project that no flag
    names). Each file is read once here, before the long run, so a missing or malformed map is
    bad input at once (InputError)."""
    from flashbrdf.render.envmap import read_envmap_pixels
    given = getattr(args, "envmap", None)
    if given and not getattr(args, "render", False):
        raise InputError("--envmap", "names Table 2's maps: give it with --render")
    if not getattr(args, "render", False) or not given:
        return None
    paths = [Path(p) for p in given]
    names = [path.stem.split("_latlong")[0] for path in paths]  # Table 2's column names
    if len(set(names)) < len(names):
        raise InputError("--envmap", f"two maps share the name {max(names, key=names.count)!r}: "
                                     "Table 2 names a map by its file name")
    for path in paths:
        read_envmap_pixels(path)
    return paths


def evaluate(args):
    """The paper's Table 1 protocol on --merl-dir (see experiments.evaluate); with --render also its
    Table 2 (experiments.table2) on the mean-performing experiment's test materials, 2D predictions.
    With --test-dir: trained on every --merl-dir table, scored on the --test-dir tables
    (experiments.test_set), written all or nothing."""
    folders = _merl_dirs(args.merl_dir)
    check_engine_options(args)
    _check_protocol_options(args)
    if getattr(args, "test_dir", None):
        if getattr(args, "envmap", None) and not getattr(args, "render", False):
            raise InputError("--envmap", "names Table 2's maps: give it with --render")
        if getattr(args, "render", False):
            raise InputError("--render", "renders the cross-validation protocol's materials; "
                                         "not with --test-dir")
        check_outputs(inputs=_merl_inputs(folders + [args.test_dir]), outputs=[args.out],
                      folders=[args.out])
        with staged_output_dir(args.out, force=getattr(args, "force", False),
                               command="evaluate") as out:
            run_test_set(folders, args.test_dir, out, seed=getattr(args, "seed", 0))
        print(f"test set scores -> {Path(args.out) / 'test_set.md'}")
        return 0
    if len(folders) != 1:
        raise InputError("--merl-dir", "the cross-validation protocol takes one folder; give "
                                       "--test-dir to train on several")
    merl_dir = folders[0]
    envmaps = _render_envmaps(args)
    check_outputs(inputs=_merl_inputs(folders) + (envmaps or []), outputs=[args.out],
                  folders=[args.out])
    options = dict(quick=args.quick, experiments=getattr(args, "experiments", None),
                   time_budget=getattr(args, "time_budget", None))
    # never more local workers than experiments: a spare one costs its start and sits idle
    workers = args.workers and min(args.workers, options["experiments"] or
                                   (1 if args.quick else 25))
    with staged_output_dir(args.out, force=getattr(args, "force", False),
                           command="evaluate") as out:
        check_protocol_tables(merl_dir)  # before a cluster starts, not in run_evaluation
        if getattr(args, "workers", None) or getattr(args, "scheduler", None):
            with dask_client(workers, args.scheduler) as client:  # experiments as Dask tasks
                result = run_evaluation(merl_dir, out, client=client, **options)
        else:
            result = run_evaluation(merl_dir, out, **options)
        if getattr(args, "render", False):
            # experiments.table2 (renderer, figures) adds 1.7-2.2 s to import (python -X importtime)
            from flashbrdf.experiments.table2 import table2
            names, predict = experiment_predictor(merl_dir, result)
            table2(merl_dir, out, predict, names=names, envmaps=envmaps)
    return 0


