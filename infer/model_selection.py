"""The validation grid search that picks hyperparameters, for `flashbrdf train` (tune_baselines)
and for every experiment of the Table 1 protocol (experiments.evaluate).

Methods are scored by the mean LAB-log error (brdf.metrics) of their 2D predictions on held-out
materials; grids are scikit-learn ParameterGrids over the methods' constructor arguments.
"""

import time

import numpy as np
from joblib import Parallel, delayed
from sklearn.model_selection import ParameterGrid

from flashbrdf.brdf import metrics
from flashbrdf.files.errors import InputError
from flashbrdf.files.threads import thread_budget
from flashbrdf.infer import make_method
from flashbrdf.infer.training_set import MIN_TRAINING_TABLES
from flashbrdf.infer.uncertainty import calibration_factor

DS_GRID = {"q": [None], "beta": [50.0, 100.0], "feature_space": ["lab", "rgb"]}
DS_FIXED = {"anchor": True}                      # "dsgplvm" is the anchored DS-GPLVM of infer/run
# tune_baselines holds max(1, n // 5) tables out to validate, and a DS-GPLVM needs 3 to fit
PCA_GRID = {"n_components": [3, 6, 12, 24, None], "ridge": [1e-3, 1e-2, 1e-1, 1.0, 10.0]}


def errors_2d(method, data, index):
    """[brdf_errors dict] of a fitted method's 2D predictions for materials `index` of `data`,
    over the bins that hold data (TrainingSet.scored_table)."""
    return [metrics.brdf_errors(_predict_2d(method, data.slices[i], truth), truth)
            for i, truth in ((i, data.scored_table(i)) for i in index)]


def _predict_2d(method, rho, table):
    """A fitted method's 2D prediction from slice rho; evaluation-only methods see the table."""
    return method.predict_truth(table) if method.evaluation_only else method.predict(rho, "2d")[0]


def lab_log(errs):
    return float(np.mean([e["lab_log"] for e in errs]))


def valid_lab_log(method, data, index):
    """lab_log(errors_2d(method, data, index)), computing that one error only (the grid's score)."""
    return float(np.mean([metrics.brdf_error(_predict_2d(method, data.slices[i], truth), truth,
                                             "log", "lab")
                          for i, truth in ((i, data.scored_table(i)) for i in index)]))


def _trial(name, params, train, valid, data):
    """Fit one grid point and score it on the validation materials: -> trial dict."""
    t0 = time.perf_counter()
    m = make_method(name, **params).fit(train)
    fit_s = time.perf_counter() - t0
    return {"params": params, "valid_lab_log": valid_lab_log(m, data, valid), "fit_s": fit_s,
            "method": m}


def _grid(grid, fixed=None):
    """The grid's parameter dicts, in the grid's key order (ParameterGrid sorts them), as the
    reports print them, each with `fixed` added."""
    return [{k: combo[k] for k in grid} | (fixed or {}) for combo in ParameterGrid(grid)]


def _run(tasks, workers):
    """Results of joblib `delayed` tasks, in their order: in `workers` processes, or here for 1.
    Each task is the same deterministic computation in any process (DSGPLVM.fit runs its BLAS
    on one thread), so the results do not depend on `workers`."""
    workers = max(1, min(workers, len(tasks)))
    if workers == 1:
        return [fn(*args, **kwargs) for fn, args, kwargs in tasks]
    return Parallel(n_jobs=workers)(tasks)


def _best(trials):
    """(best fitted method, best params, trials) of select; ties go to the first grid point."""
    best = min(trials, key=lambda t: t["valid_lab_log"])     # min keeps the first of equals
    return best["method"], best["params"], trials


def select(name, grid, train, valid, data, fixed=None, workers=1):
    """Grid search on validation LAB-log: -> (best fitted method, best params, [(params, err, s)]).
    workers > 1 fits the grid points in that many processes (joblib), with the same result."""
    tasks = [delayed(_trial)(name, params, train, valid, data) for params in _grid(grid, fixed)]
    return _best(_run(tasks, workers))


def _tune_closed_form(training, train, valid):
    """pca's grid on the split and ashikhmin's r0 on all: -> (pca params, ashikhmin params)."""
    grid = {k: [v for v in vals if v is None or v < len(train)] for k, vals in PCA_GRID.items()}
    _, pca_params, _ = select("pca", grid, training.subset(train), valid, training)
    return pca_params, make_method("ashikhmin").fit(training).fitted_params()


def training_workers():
    """Processes for the validation fits of `train`: $FLASHBRDF_THREADS (a worker's share of the
    cores, as in infer.estimator), else one per core, at most 2."""
    return thread_budget(2)


# The fewest tables any measured model was trained on (Table 1's 60-material splits): below it the
# warning's threshold and the intervals' scale, measured on models of 60-122 tables, are untested,
# and the baselines' mixtures extrapolate (a 4-table model gave white-fabric a grazing peak of
# 564 1/sr in noll's member against the truth's 0.76, unwarned)
MEASURED_MIN_TRAINING_TABLES = 60


def small_training_note(n_tables):
    """One line for `train` when n_tables is under MEASURED_MIN_TRAINING_TABLES, else None."""
    if n_tables >= MEASURED_MIN_TRAINING_TABLES:
        return None
    return (f"note: {n_tables} materials are fewer than any model we measured "
            f"({MEASURED_MIN_TRAINING_TABLES} or more): the out-of-distribution warning and the "
            "90% intervals are untested at this size, and predictions far from every training "
            "material can be wrong without a warning; add tables (the shipped model has 121)")


def check_training_size(n_tables, where):
    """InputError naming `where` (a folder or "--merl-dir") when n_tables is too few to train."""
    if n_tables < MIN_TRAINING_TABLES:
        raise InputError(where, f"needs at least {MIN_TRAINING_TABLES} different MERL tables "
                                f"(a fifth of them is held out to choose the hyperparameters), "
                                f"found {n_tables}")


def tune_baselines(training, seed=0, feature_space="auto", workers=None):
    """Hyperparameters for `flashbrdf train`: ashikhmin r0 on all; pca and (feature_space "auto")
    the DS-GPLVM's feature space on a seeded 80/20 split, scored like Table 1's validation.
    workers: processes for the DS-GPLVM validation fits and the baselines' tuning (default
    training_workers(); the result is the same for any number)."""
    workers = training_workers() if workers is None else workers
    # the validation fits are 2D: each worker was handed the 3D rows too (3.2 GB for 100
    # tables in /dev/shm, over 8 GB with two workers)
    training = training.without_stored_3d()
    n = len(training)
    order = np.random.default_rng(seed).permutation(n)
    cut = max(1, n // 5)
    valid, train = np.sort(order[:cut]), np.sort(order[cut:])
    spaces = DS_GRID["feature_space"] if feature_space == "auto" else [feature_space]
    # the DS-GPLVM's validation fits and the baselines' tuning side by side, longest first
    tasks = [delayed(_trial)("dsgplvm", params, training.subset(train), valid, training)
             for params in _grid({"feature_space": spaces}, DS_FIXED)]
    *trials, (pca_params, ashikhmin_params) = _run(
        tasks + [delayed(_tune_closed_form)(training, train, valid)], workers)
    best, ds, _ = _best(trials)
    # the consensus (infer.consensus) averages with the PCA baseline as tuned here
    best = type(best).from_model(best.model_, best.training_,
                                 **(best.get_params() | {"pca_params": pca_params}))
    # the per-bin variance is calibrated on the same held-out 20%: central 90% intervals there
    # cover 90% of the bins
    kappa = calibration_factor(best, training.slices[valid], training.tables_2d[valid])
    return {"pca": pca_params, "ashikhmin": ashikhmin_params,
            "noll": {}, "chandraker": {},
            "dsgplvm": {"feature_space": ds["feature_space"], "calibration": kappa,
                        "pca_params": pca_params}}
