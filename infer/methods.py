"""The methods by name: the registry `make_method` reads, and fitted methods around a stored model."""

from flashbrdf.infer.adapter import DSGPLVMMethod
from flashbrdf.infer.baselines import PCA, Ashikhmin, Chandraker, Noll, Oracle
from flashbrdf.infer.relative import RelativeDSGPLVMMethod


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


def make_method(name, **params):
    """A new (unfitted) method by name, with its hyperparameters; ValueError for unknown names."""
    if name not in METHODS:
        raise ValueError(f"unknown method {name!r}; expected one of {sorted(METHODS)}")
    return METHODS[name](**params)


def method_from_model(name, model, training, features_2d=None, **params):
    """A fitted method `name` around a DSGPLVM `model` trained before on `training` (TrainingSet),
    e.g. read from MODEL.npz or reused across prediction-time switches: loading, not fitting.
    features_2d: the training tables' 2D features when the caller has them (absolute dsgplvm)."""
    cls = type(make_method(name, **params))
    if features_2d is not None:
        return cls.from_model(model, training, features_2d=features_2d, **params)
    return cls.from_model(model, training, **params)
