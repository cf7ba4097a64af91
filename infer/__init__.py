"""infer: from a 1D BRDF slice to a full 2D/3D BRDF.

Every method is an estimator: `fit(training: TrainingSet)` then
`predict(flash_slice (90, 3) 1/sr NaN-empty, view="2d"|"3d") -> (table, variance or None)` with table
(90, 90, 3) or (90, 90, 180, 3) in 1/sr, NaN where MERL has no data. Methods: dsgplvm (the paper's
DS-GPLVM, Georgoulis et al. 2015), pca (Nielsen et al. 2015), noll (Nöll et al. 2014), chandraker
(Chandraker & Ramamoorthi 2011), ashikhmin (Ashikhmin & Premože 2007), oracle (evaluation only).
"""

from infer.adapter import DSGPLVMMethod
from infer.baselines import PCA, Ashikhmin, Chandraker, Noll, Oracle
from infer.common import InferenceMethod, TrainingSet
from infer.model_file import load_method, read_model, save_model
from infer.relative import RelativeDSGPLVMMethod


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


__all__ = ["METHODS", "make_method", "InferenceMethod", "TrainingSet", "DSGPLVMMethod",
           "RelativeDSGPLVMMethod", "PCA",
           "Ashikhmin", "Chandraker", "Noll", "Oracle", "save_model", "read_model", "load_method"]
