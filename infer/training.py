"""What `flashbrdf train` does to a training set, in one place: tune, fit, write MODEL.npz.

`pipeline.infer_jobs.train` (the command) and `experiments.test_set` (the external test-set
protocol of `flashbrdf evaluate --test-dir`) both call train_model, so an evaluated model is
exactly the one `train` would have written.
"""

import time

import numpy as np

from flashbrdf.files.errors import InputError
from flashbrdf.infer.adapter import DSGPLVMMethod
from flashbrdf.infer.baselines.pca import PCA
from flashbrdf.infer.model_file import save_model
from flashbrdf.infer.model_selection import tune_baselines


def train_model(training, path, views=("1d", "2d"), seed=0, feature_space="auto", merl_dirs=()):
    """Tune every method's hyperparameters on `training` (infer.model_selection.tune_baselines), fit the
    DS-GPLVM and write MODEL.npz to `path` (atomically). training: TrainingSet; views: the
    DS-GPLVM's views; merl_dirs: the training folders, recorded in the file. Returns the params
    dict stored in the file, with `train_seconds` (all of it) and `fit_seconds` {"tuning",
    "dsgplvm"} (the validation fits that pick hyperparameters, and the final DS-GPLVM fit).
    """
    wanted = list(views)
    start = time.perf_counter()
    # fitted on the tables as the file holds them (float32): a load rebuilds these very rows
    # and checks them against the fit, which near-duplicate tables fail by float32's rounding
    training = training.as_stored()
    params = tune_baselines(training, seed=seed, feature_space=feature_space)
    tuned = time.perf_counter()
    space = params["dsgplvm"]["feature_space"]
    model = DSGPLVMMethod(views=wanted, seed=seed, feature_space=space).fit(training)
    params["dsgplvm"] = {"feature_space": space, "views": wanted, "seed": seed,
                         "calibration": params["dsgplvm"]["calibration"],
                         "pca_params": params["dsgplvm"]["pca_params"]}
    done = time.perf_counter()
    params["train_seconds"] = done - start
    params["fit_seconds"] = {"tuning": tuned - start, "dsgplvm": done - tuned}
    # the consensus' PCA (infer.consensus), fitted here once and stored: not refitted at each load
    pca = PCA(**(params["dsgplvm"]["pca_params"] or {})).fit(training)
    if not 0 < len(pca.var_) < len(training) or np.any(pca.var_ <= 0):
        # what a load would refuse as a damaged model: say so now, naming the tables
        raise InputError("--merl-dir", f"the {len(training)} training tables are one table once "
                                       "mapped as pca maps them (ln of rho over a reference): "
                                       "nothing varies to learn from; train on distinct materials")
    save_model(path, training, params, dsgplvm=model.model_, merl_dir=list(merl_dirs),
               pca_state=pca.state())
    return params
