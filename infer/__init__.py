"""infer: from a 1D BRDF slice to a full 2D/3D BRDF.

Every method is an estimator: `fit(training: TrainingSet)` then
`predict(flash_slice (90, 3) 1/sr NaN-empty, view="2d"|"3d") -> (table, variance or None)` with table
(90, 90, 3) or (90, 90, 180, 3) in 1/sr, NaN where MERL has no data. Methods: dsgplvm (the paper's
DS-GPLVM, Georgoulis et al. 2015), pca (Nielsen et al. 2015), noll (Nöll et al. 2014), chandraker
(Chandraker & Ramamoorthi 2011), ashikhmin (Ashikhmin & Premože 2007), oracle (evaluation only).
"""

from flashbrdf.infer.adapter import DSGPLVMMethod
from flashbrdf.infer.baselines import PCA, Ashikhmin, Chandraker, Noll, Oracle
from flashbrdf.infer.estimator import InferenceMethod
from flashbrdf.infer.training_set import TrainingSet
from flashbrdf.infer.model_file import load_method, read_model, save_model
from flashbrdf.infer.relative import RelativeDSGPLVMMethod
from flashbrdf.infer.warning import prediction_warning


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


def novelty_warning(method, flash_slice, source="slice"):
    """(novelty score or None, one-line warning or None) for a fitted method and a (90, 3) slice:
    infer.warning.prediction_warning's score and line (its record has every field: BRDF.json's
    "novelty" takes it whole, and its "out_of_distribution" is True exactly when the line is
    given)."""
    record, line = prediction_warning(method, flash_slice, source)
    return record["score"], line


def make_method(name, **params):
    """A new (unfitted) method by name, with its hyperparameters; ValueError for unknown names."""
    if name not in METHODS:
        raise ValueError(f"unknown method {name!r}; expected one of {sorted(METHODS)}")
    return METHODS[name](**params)


def method_from_model(name, model, training, **params):
    """A fitted method `name` around a DSGPLVM `model` trained before on `training` (TrainingSet),
    e.g. read from MODEL.npz or reused across prediction-time switches: loading, not fitting."""
    return type(make_method(name, **params)).from_model(model, training, **params)


__all__ = ["METHODS", "make_method", "method_from_model", "novelty_warning", "prediction_warning", "InferenceMethod", "TrainingSet", "DSGPLVMMethod",
           "RelativeDSGPLVMMethod", "PCA",
           "Ashikhmin", "Chandraker", "Noll", "Oracle", "save_model", "read_model", "load_method"]
