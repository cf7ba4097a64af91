"""The paper's Table 1 protocol (`flashbrdf evaluate`).

Experiments: R repetitions of 5-fold splits of a seeded permutation (R = 5 gives the paper's 25
experiments); in each, one fold (20 %) is the test set, the next fold the validation set and the rest
(60 %) the training set. Validation picks the DS-GPLVM's β and feature space and the pca/oracle
hyperparameters (LAB-log 2D error). Two DS-GPLVMs are scored from the same fits: "dsgplvm" is what
`flashbrdf infer` does (slice anchoring on, log-LAB or log-RGB features as validation picks) and
"dsgplvm-paper" is the paper's method (log-LAB features, no anchoring; docs/methods.md lists
its departures). Errors: brdf.metrics for every test prediction (2D; 3D on the experiments that fit
the time budget, the paper's mean-performing one first), pooled mean and median, plus the
"mean-performing experiment" (dsgplvm 2D LAB-log mean closest to the mean over experiments).
"""

import json
import os
import resource
import sys
import time
import tracemalloc

import numpy as np

from flashbrdf.brdf import merl
from flashbrdf.brdf.bins import valid_mask_2d
from flashbrdf.brdf.shadowing import inverse_denominator
from flashbrdf.experiments.eval3d import RowsView, build_cache, evaluate_3d, holes_file
from flashbrdf.experiments.table1_files import mean_performing, write_table1
from flashbrdf.files.errors import InputError
from flashbrdf.infer import TrainingSet, make_method, method_from_model
from flashbrdf.infer.baselines.pca import cosine_weights
from flashbrdf.infer.model_selection import DS_FIXED, DS_GRID, PCA_GRID, errors_2d, lab_log, select
from flashbrdf.infer.training_set import check_distinct

PAPER = "dsgplvm-paper"                          # the paper's DS-GPLVM, scored from the same fits
PAPER_FIXED = {"feature_space": "lab", "anchor": False}
METHOD_ORDER = ("chandraker", "ashikhmin", "noll", "pca", "oracle", "dsgplvm", PAPER)
PREDICTION_ONLY = ("anchor", "latent", "row_blend_deg", "consensus", "pca_params")  # no refit
ORACLE_GRID = {"ridge": [1e-6, 1e-2, 1.0]}
QUICK_DS_GRID = {"q": [None], "beta": [50.0], "feature_space": ["lab", "rgb"],
                 "max_cycles": [10]}  # smoke run: short ADM


def build_method(name, **params):
    """make_method for the evaluated names: PAPER is the DS-GPLVM with PAPER_FIXED."""
    if name == PAPER:
        return make_method("dsgplvm", **(params | PAPER_FIXED))
    return make_method(name, **params)


def splits(n, repetitions, seed=0, folds=5):
    """[(train, valid, test)] index arrays; each repetition is a seeded permutation cut in `folds`."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(repetitions):
        parts = np.array_split(rng.permutation(n), folds)
        for f in range(folds):
            test, valid = parts[f], parts[(f + 1) % folds]
            train = np.concatenate([parts[g] for g in range(folds) if g not in (f, (f + 1) % folds)])
            out.append((np.sort(train), np.sort(valid), np.sort(test)))
    return out


def _measure(fn):
    """Run fn() under tracemalloc: -> (result, seconds, peak MB)."""
    tracemalloc.start()
    t0 = time.perf_counter()
    result = fn()
    seconds = time.perf_counter() - t0
    peak = tracemalloc.get_traced_memory()[1] / 2**20
    tracemalloc.stop()
    return result, seconds, peak


def _fit_key(params):
    """The hyperparameters that change a DS-GPLVM fit (defaults filled in, prediction-time
    switches dropped), as a hashable key."""
    full = make_method("dsgplvm", **params).get_params()
    return json.dumps({k: v for k, v in full.items() if k not in PREDICTION_ONLY},
                      sort_keys=True, default=str)


def _select_paper(trials, train, valid_idx, data):
    """The paper's DS-GPLVM from the log-LAB fits of the dsgplvm grid, scored unanchored on
    validation: -> (method, params, trials) like select()."""
    out, best = [], None
    for t in trials:
        if t["params"].get("feature_space") != "lab":
            continue
        params = t["params"] | PAPER_FIXED
        m = method_from_model("dsgplvm", t["method"].model_, train, **params)
        err = lab_log(errors_2d(m, data, valid_idx))
        out.append({"params": params, "valid_lab_log": err, "fit_s": t["fit_s"], "method": m})
        if best is None or err < best["valid_lab_log"]:
            best = out[-1]
    return best["method"], best["params"], out


def run_experiment(k, split, data, cache, quick, costs, points, ablations, measure=None):
    """Fit every method on one split; 2D test errors; returns (record, fitted methods).
    measure: tracemalloc peaks (default: when `costs` is still empty, i.e. the first experiment)."""
    train_idx, valid_idx, test_idx = split
    train = data.subset(train_idx)
    train.valid_3d = RowsView(cache.rows, train_idx) if cache is not None else None
    n_train = len(train_idx)
    fitted, chosen, record = {}, {}, {"experiment": k, "test": [data.names[i] for i in test_idx],
                                      "errors_2d": {}}
    all_trials = {}
    if measure is None:  # tracemalloc on the first experiment only (it slows numpy a little)
        measure = not costs
    grids = {"dsgplvm": QUICK_DS_GRID if quick else DS_GRID,
             "pca": {kk: [v for v in vals if v is None or v < n_train] for kk, vals in PCA_GRID.items()},
             "oracle": ORACLE_GRID}
    for name in METHOD_ORDER:
        t0, peak = time.perf_counter(), None
        if name == PAPER:
            m, params, trials = _select_paper(all_trials["dsgplvm"], train, valid_idx, data)
            train_s = time.perf_counter() - t0
            peak = costs.get("dsgplvm", {}).get("peak_mb") if measure else None
        elif name in grids:
            fixed = DS_FIXED | {"pca_params": chosen["pca"]} if name == "dsgplvm" else None
            fit = lambda: select(name, grids[name], train, valid_idx, data, fixed)  # noqa: E731
            if measure:  # peak over the grid's fits (each fit alone peaks no higher)
                (m, params, trials), _, peak = _measure(fit)
            else:
                m, params, trials = fit()
            train_s = time.perf_counter() - t0
        else:
            m, trials = make_method(name).fit(train), []
            params = m.fitted_params()
            train_s = time.perf_counter() - t0
            if measure:  # peak of one fit plus one 2D prediction
                _, _, peak = _measure(lambda: errors_2d(make_method(name, **params).fit(train),
                                                        data, test_idx[:1]))
        all_trials[name] = trials
        t0 = time.perf_counter()
        errs = errors_2d(m, data, test_idx)
        infer_s = (time.perf_counter() - t0) / len(test_idx)
        fitted[name], chosen[name], record["errors_2d"][name] = m, params, errs
        c = costs.setdefault(name, {"train_s": [], "infer_2d_s": [], "infer_3d_s": None,
                                    "peak_mb": None})
        single_fit = [t["fit_s"] for t in trials if t["params"] == params] if trials else [train_s]
        c["train_s"].append(single_fit[0] if single_fit else train_s)
        c["infer_2d_s"].append(infer_s)
        if peak is not None:
            c["peak_mb"] = peak
        for t in trials if k == 0 else []:
            if name in ("dsgplvm", "pca", PAPER):
                t0 = time.perf_counter()
                e = lab_log(errors_2d(t["method"], data, test_idx))
                s = (time.perf_counter() - t0) / len(test_idx)
                label = ",".join(f"{a}={b}" for a, b in t["params"].items()
                                 if a not in ("seed", "q", "anchor") or b is not None and a == "q")
                points.append({"method": name, "label": f"{name} {label}", "seconds": s, "error": e})
        if k == 0 and name not in ("dsgplvm", "pca", PAPER):
            points.append({"method": name, "label": name, "seconds": infer_s, "error": lab_log(errs)})
    record["chosen"] = chosen
    if ablations is not None:
        for label, name in (("ours: dsgplvm (anchored, feature space chosen on validation)",
                             "dsgplvm"), ("the paper's DS-GPLVM (log-LAB, unanchored)", PAPER)):
            entry = ablations.setdefault(label, {"errors": []})
            entry["errors"] = entry["errors"] + record["errors_2d"][name]
        models = {_fit_key(t["params"]): t["method"].model_ for t in all_trials["dsgplvm"]}
        run_ablations(fitted[PAPER], train, data, test_idx, ablations, k, points, quick, models)
    return record, fitted


def run_ablations(base, train, data, test_idx, ablations, k, points, quick=False, models=None):
    """The issue's ablations of the paper's DS-GPLVM `base` (fitted): no prior (β = 0), log-RGB
    features, no back-constraints (latent by optimisation at test time); then our slice anchoring,
    alone and with log-RGB features; ADM cycles on the first experiment. models: {_fit_key: fitted
    DSGPLVM} already trained on `train` (the grid's fits), reused instead of refitting."""
    params = base.get_params()
    models = dict(models or {})
    variants = {"no prior (beta=0)": {"beta": 0.0},
                "log-RGB features": {"feature_space": "rgb"},
                "no back-constraints (latent optimised at test time)": {"latent": "optimise"},
                "with slice anchoring": {"anchor": True},
                "log-RGB features + slice anchoring": {"feature_space": "rgb", "anchor": True}}
    if k == 0 and not quick:
        variants |= {f"ADM cycles <= {c}": {"max_cycles": c} for c in (1, 5)}
    for label, change in variants.items():
        p = params | change
        try:
            model = models.get(_fit_key(p))
            m = make_method("dsgplvm", **p).fit(train) if model is None else \
                method_from_model("dsgplvm", model, train, **p)
        except TypeError as err:  # the model does not offer this switch
            ablations.setdefault(label, {"skipped": str(err)})
            continue
        models[_fit_key(p)] = m.model_
        t0 = time.perf_counter()
        errs = errors_2d(m, data, test_idx)
        entry = ablations.setdefault(label, {})
        entry["errors"] = entry.get("errors", []) + errs
        if k == 0 and change and "max_cycles" in change:
            points.append({"method": PAPER, "label": f"{PAPER} {label}",
                           "seconds": (time.perf_counter() - t0) / len(test_idx),
                           "error": lab_log(errs)})


def experiment_predictor(merl_dir, result, view="2d", seed=0):
    """(names, predict) for the paper's Table 2 (experiments.table2): the test materials of Table 1's
    mean-performing experiment, each method refitted on that experiment's training set with its
    chosen hyperparameters. predict(name, method) -> table ((90, 90, 3) for view "2d", 3D streamed
    from merl_dir for "3d"), the oracle from the true 2D table, or None for unknown methods."""
    k = result["mean_performing"]["experiment"]
    data = TrainingSet.from_merl_dir(merl_dir)
    train_idx, _, test_idx = splits(len(data), k // 5 + 1, seed)[k]
    train = data.subset(train_idx)
    chosen = result["hyperparameters"][k]["chosen"]
    fitted = {}

    def predict(name, method):
        if method not in chosen or name not in data.names:
            return None
        if method not in fitted:
            fitted[method] = build_method(method, **chosen[method]).fit(train)
        i = data.names.index(name)
        if fitted[method].evaluation_only:
            return fitted[method].predict_truth(data.tables_2d[i]) if view == "2d" else None
        return fitted[method].predict(data.slices[i], view)[0]

    return [data.names[i] for i in test_idx], predict


def warm_up():
    """Fill the geometry caches so that timings measure methods, not one-off set-up."""
    valid_mask_2d(), cosine_weights(), inverse_denominator()


# ----------------------------------------------------------------------------- as Dask tasks
def experiment_task(k, split, data, cache_file, quick, with_ablations):
    """Experiment k as an independent, picklable task: run_experiment on its own accumulators.
    -> {"record", "costs", "points", "ablations", "seconds"} of this experiment alone, which
    merge_experiment adds in experiment order, giving the sequential loop's numbers."""
    t0 = time.perf_counter()
    warm_up()
    # opens the shared file
    cache = build_cache(data.paths, cache_file, data.tables_2d) if cache_file else None
    costs, points, ablations = {}, [], {} if with_ablations else None
    record, _ = run_experiment(k, split, data, cache, quick, costs, points, ablations,
                               measure=(k == 0))
    return {"record": record, "costs": costs, "points": points, "ablations": ablations,
            "seconds": time.perf_counter() - t0}


def merge_experiment(part, records, costs, points, ablations):
    """Add one experiment_task result to the run's accumulators, as run_experiment would have."""
    records.append(part["record"])
    for name, c in part["costs"].items():
        total = costs.setdefault(name, {"train_s": [], "infer_2d_s": [], "infer_3d_s": None,
                                        "peak_mb": None})
        total["train_s"] += c["train_s"]
        total["infer_2d_s"] += c["infer_2d_s"]
        if c["peak_mb"] is not None:
            total["peak_mb"] = c["peak_mb"]
    points += part["points"]
    for label, entry in (part["ablations"] or {}).items():
        total = ablations.setdefault(label, {})
        if "skipped" in entry:
            total.setdefault("skipped", entry["skipped"])
        if "errors" in entry:
            total["errors"] = total.get("errors", []) + entry["errors"]


def experiment_3d_task(chosen, split, data, cache_file, first, stride):
    """run_3d of one experiment as a task: -> (errors_3d, {method: 3D inference s or None})."""
    record, costs = {"chosen": chosen}, {name: {} for name in chosen}
    run_3d(record, split, data, build_cache(data.paths, cache_file, data.tables_2d), costs, first,
           stride)
    return record["errors_3d"], {name: c.get("infer_3d_s") for name, c in costs.items()}


def _experiments_on_dask(client, data, all_splits, cache_file, quick, time_budget, start,
                         reserve_3d, accumulators, write, notes):
    """The 2D experiments as Dask tasks, at most one per worker in flight (so the time budget
    can stop new ones as the sequential loop does), merged in experiment order as they finish
    into accumulators = (records, costs, points, ablations); write() after each merge."""
    from distributed import as_completed  # only with --workers/--scheduler: dask is slow to import
    records = accumulators[0]
    # hash=False: a key of its own. Scattered by content, the 3D stage's copy took the 2D stage's
    # key, and the 2D stage's release then dropped it under the 3D tasks ("lost dependencies")
    shared = client.scatter(data, broadcast=True, hash=False)
    slots = max(1, len(client.scheduler_info().get("workers", {})))
    per_exp_s, finished = [], {}
    running, submitted = as_completed(loop=client.loop), 0

    def submit():
        nonlocal submitted
        k = submitted
        running.add(client.submit(experiment_task, k, all_splits[k], shared, cache_file, quick,
                                  k < 1 or not time_budget, pure=False, retries=1,
                                  key=f"table1-experiment-{k}-{os.getpid()}"))
        submitted += 1

    def over_budget():
        return (time_budget and per_exp_s and time.perf_counter() - start + np.mean(per_exp_s)
                + reserve_3d > time_budget)

    while submitted < min(slots, len(all_splits)):
        submit()
    for future in running:
        part = future.result()
        future.release()
        finished[part["record"]["experiment"]] = part
        per_exp_s.append(part["seconds"])
        while len(records) in finished:  # merge the finished prefix, in experiment order
            done = finished.pop(len(records))
            merge_experiment(done, *accumulators)
            print(f"experiment {len(records) - 1}: {done['seconds']:.1f} s, dsgplvm LAB-log "
                  f"{lab_log(done['record']['errors_2d']['dsgplvm']):.3f}", flush=True)
            write()
        if submitted < len(all_splits):
            if over_budget():
                if not any(n.startswith("time budget") for n in notes):
                    notes.append(f"time budget {time_budget:.0f} s: stopped after {submitted} of "
                                 f"{len(all_splits)} experiments (2D).")
            else:
                submit()


def _3d_on_dask(client, data, order, records, all_splits, cache_file, costs, stride, write):
    """3D metrics of the experiments in `order` as Dask tasks, all at once, added to their
    records as they finish (the first in `order` also times 3D inference). -> number done."""
    from distributed import as_completed  # only with --workers/--scheduler: dask is slow to import
    shared = client.scatter(data, broadcast=True, hash=False)   # a key of its own (see above)
    futures = {client.submit(experiment_3d_task, records[k]["chosen"], all_splits[k], shared,
                             cache_file, i == 0, stride, pure=False, retries=1,
                             key=f"table1-3d-{k}-{os.getpid()}"): (k, i == 0)
               for i, k in enumerate(order)}
    for future in as_completed(futures, loop=client.loop):
        k, first = futures.pop(future)
        records[k]["errors_3d"], infer_3d_s = future.result()
        future.release()
        if first:
            for name, seconds in infer_3d_s.items():
                costs[name]["infer_3d_s"] = seconds
        print(f"3D metrics, experiment {k}: done", flush=True)
        write()
    return len(order)


def check_protocol_tables(merl_dir):
    """InputError naming merl_dir when it holds too few tables for the protocol (5: each fold's
    train / validation / test split needs some), counted before any is read."""
    if len(merl.list_merl(merl_dir)) < 5:
        raise InputError(merl_dir, "evaluate needs at least 5 MERL tables")


def run_evaluation(merl_dir, out_dir, quick=False, experiments=None, experiments_3d=None,
                   time_budget=None, seed=0, command=None, keep_cache=False, cache_dir=None,
                   client=None):
    """Run the protocol on every MERL table in merl_dir; write table1.md/json and the plot.
    The float32 3D cache (N × 40 MB) goes to cache_dir (default out_dir) and is removed after.
    client: a dask.distributed Client to run the experiments on as tasks (same numbers); the
    cache file must then be on a filesystem the workers share. experiments: how many (default
    25, or 1 with quick)."""
    start = time.perf_counter()
    warm_up()
    check_protocol_tables(merl_dir)
    data = TrainingSet.from_merl_dir(merl_dir)
    check_distinct(data.paths, data.tables_2d)
    n = len(data)
    n_exp = experiments or (1 if quick else 25)
    all_splits = splits(n, -(-n_exp // 5), seed)[:n_exp]
    n_3d = (1 if quick else 2) if experiments_3d is None else experiments_3d
    os.makedirs(out_dir, exist_ok=True)
    cache_file = os.path.join(cache_dir or out_dir, f".cache_valid_3d_{os.getpid()}.f32")
    cache = build_cache(data.paths, cache_file, data.tables_2d) if n_3d else None
    command = command or "flashbrdf " + " ".join(sys.argv[1:])
    notes = [f"{n} materials; {len(all_splits)} experiment(s) planned of "
             f"{len(all_splits[0][0])} train / {len(all_splits[0][1])} validation / "
             f"{len(all_splits[0][2])} test, seed {seed}."]
    try:
        records, costs, points, ablations, per_exp_s = [], {}, [], {}, []
        result = {"dataset": "MERL (NBRDF proxy)", "command": command, "notes": notes}
        per_3d_s = 900.0  # first guess of one experiment's 3D metrics on 2 shared cores
        reserve_3d = per_3d_s * n_3d

        def write():
            write_table1(out_dir, result, records, costs, points, ablations, len(all_splits))

        if client is not None:
            _experiments_on_dask(client, data, all_splits, cache_file if n_3d else None, quick,
                                 time_budget, start, reserve_3d, (records, costs, points,
                                                                  ablations), write, notes)
        for k, split in enumerate(all_splits if client is None else []):
            elapsed = time.perf_counter() - start
            if (time_budget and records and
                    elapsed + np.mean(per_exp_s) + reserve_3d > time_budget):
                notes.append(f"time budget {time_budget:.0f} s: stopped after {len(records)} of "
                             f"{len(all_splits)} experiments (2D).")
                break
            t0 = time.perf_counter()
            record, _ = run_experiment(k, split, data, cache, quick, costs, points,
                                       ablations if (k < 1 or not time_budget) else None)
            records.append(record)
            per_exp_s.append(time.perf_counter() - t0)
            print(f"experiment {k}: {per_exp_s[-1]:.1f} s, dsgplvm LAB-log "
                  f"{lab_log(record['errors_2d']['dsgplvm']):.3f}", flush=True)
            write()
        best = mean_performing(records)
        order = [best] + [i for i in range(len(records)) if i != best]
        done_3d = 0
        if client is not None and n_3d:
            done_3d = _3d_on_dask(client, data, order[:n_3d], records, all_splits, cache_file,
                                  costs, stride=5 if quick else 1, write=write)
        for k in order if client is None else []:
            if done_3d >= n_3d:
                break
            if time_budget and done_3d and time.perf_counter() - start + per_3d_s > time_budget:
                notes.append(f"time budget: 3D metrics on {done_3d} experiment(s) only.")
                break
            t0 = time.perf_counter()
            run_3d(records[k], all_splits[k], data, cache, costs, first=(done_3d == 0),
                   stride=5 if quick else 1)
            done_3d += 1
            per_3d_s = time.perf_counter() - t0
            print(f"3D metrics, experiment {k}: {per_3d_s:.1f} s", flush=True)
            write()
        notes.append(f"3D metrics computed on {done_3d} experiment(s) (the mean-performing one first): "
                     + ("every 5th phi_d bin only (--quick smoke run)." if quick else
                        "every valid bin of every test table."))
        notes.append(f"wall time {time.perf_counter() - start:.0f} s; peak RSS "
                     f"{resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB.")
        write_table1(out_dir, result, records, costs, points, ablations, len(all_splits))
    finally:
        for path in (cache_file, holes_file(cache_file)) if not keep_cache else ():
            if os.path.exists(path):
                os.remove(path)
    return result


def run_3d(record, split, data, cache, costs, first, stride=1):
    """Refit the chosen methods of one experiment and add its 3D errors to the record."""
    train_idx, _, test_idx = split
    train = data.subset(train_idx)
    train.valid_3d = RowsView(cache.rows, train_idx)
    methods = {name: build_method(name, **params).fit(train)
               for name, params in record["chosen"].items()}
    slices = data.slices[test_idx]
    if first:  # the CLI's streamed 3D inference time, one material
        for name, m in methods.items():
            if not m.evaluation_only:
                t0 = time.perf_counter()
                m.predict(slices[0], "3d")
                costs[name]["infer_3d_s"] = time.perf_counter() - t0
    record["errors_3d"] = evaluate_3d(cache.rows, train_idx, test_idx, methods, slices,
                                      stride=stride, holes=cache.holes)
