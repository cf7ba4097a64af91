"""infer: from a 1D BRDF slice to a full 2D/3D BRDF.

Every method is an estimator: `fit(training: TrainingSet)` then
`predict(flash_slice (90, 3) 1/sr NaN-empty, view="2d"|"3d") -> (table, variance or None)` with table
(90, 90, 3) or (90, 90, 180, 3) in 1/sr, NaN where MERL has no data. Methods: dsgplvm (the paper's
DS-GPLVM, Georgoulis et al. 2015), pca (Nielsen et al. 2015), noll (Nöll et al. 2014), chandraker
(Chandraker & Ramamoorthi 2011), ashikhmin (Ashikhmin & Premože 2007), oracle (evaluation only).
"""

import numpy as np

from flashbrdf.brdf import merl
from flashbrdf.infer.adapter import DSGPLVMMethod
from flashbrdf.infer.baselines import PCA, Ashikhmin, Chandraker, Noll, Oracle
from flashbrdf.infer.estimator import InferenceMethod
from flashbrdf.infer.training_set import TrainingSet
from flashbrdf.infer.model_file import load_method, read_model, save_model
from flashbrdf.infer.relative import RelativeDSGPLVMMethod
from flashbrdf.infer.slice_fit import OUT_OF_TRAINING_NOVELTY


def dsgplvm_method(representation="absolute", **params):
    """The DS-GPLVM estimator for a representation: "absolute" (the default: whole-table features as
    in the paper; infer.adapter) or "relative" (per-channel log-ratio to the observed row,
    infer.relative; measured in benchmarks/generalisation.py, not yet the default)."""
    if representation == "relative":
        return RelativeDSGPLVMMethod(**params)
    if representation == "absolute":
        return DSGPLVMMethod(**params)
    raise ValueError(f"unknown DS-GPLVM representation {representation!r}")


METHODS = {"dsgplvm": dsgplvm_method, "pca": PCA, "noll": Noll, "chandraker": Chandraker,
           "ashikhmin": Ashikhmin, "oracle": Oracle}


MIN_OBSERVED_BINS = 5          # fewer observed θh bins than this: the slice's shape is a guess
MAX_FIRST_THETA_H_DEG = 60.0   # no observed bin below this: the lobe and the diffuse level are unseen


def novelty_warning(method, flash_slice, source="slice"):
    """(novelty score or None, one-line warning or None) for a fitted method and a (90, 3) slice.

    It warns when the slice lies outside the training data (method.novelty > 1), or when it says too
    little to place it at all (fewer than MIN_OBSERVED_BINS bins, or none below
    MAX_FIRST_THETA_H_DEG): the prediction then extrapolates, and its uncertainty is larger than the
    training materials suggest."""
    rho = np.asarray(flash_slice, dtype=float)
    seen = np.isfinite(rho).all(axis=1)
    score = method.novelty(rho)
    reasons = []
    if score is not None and np.isfinite(score) and score > OUT_OF_TRAINING_NOVELTY:
        reasons.append(f"novelty {score:.2f}: farther from every training slice than 99% of them "
                       f"are from their nearest neighbour")
    theta_h = np.degrees(merl.theta_h_centres())
    if seen.sum() < MIN_OBSERVED_BINS or not (seen & (theta_h < MAX_FIRST_THETA_H_DEG)).any():
        first = theta_h[seen].min() if seen.any() else float("nan")
        reasons.append(f"only {int(seen.sum())} theta_h bins observed, the first at {first:.0f} deg")
    if not reasons:
        return score, None
    return score, (f"warning: {source}: the slice lies outside what the model was trained on ("
                   + "; ".join(reasons) + "); the prediction extrapolates")


def make_method(name, **params):
    """A new (unfitted) method by name, with its hyperparameters; ValueError for unknown names."""
    if name not in METHODS:
        raise ValueError(f"unknown method {name!r}; expected one of {sorted(METHODS)}")
    return METHODS[name](**params)


def method_from_model(name, model, training, **params):
    """A fitted method `name` around a DSGPLVM `model` trained before on `training` (TrainingSet),
    e.g. read from MODEL.npz or reused across prediction-time switches: loading, not fitting."""
    return type(make_method(name, **params)).from_model(model, training, **params)


__all__ = ["METHODS", "make_method", "method_from_model", "novelty_warning", "InferenceMethod", "TrainingSet", "DSGPLVMMethod",
           "RelativeDSGPLVMMethod", "PCA",
           "Ashikhmin", "Chandraker", "Noll", "Oracle", "save_model", "read_model", "load_method"]
