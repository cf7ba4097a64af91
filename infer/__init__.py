"""infer: from a 1D BRDF slice to a full 2D/3D BRDF.

Every method is an estimator: `fit(training: TrainingSet)` then
`predict(flash_slice (90, 3) 1/sr NaN-empty, view="2d"|"3d") -> (table, variance or None)` with table
(90, 90, 3) or (90, 90, 180, 3) in 1/sr, NaN where MERL has no data. Methods: dsgplvm (the paper's
DS-GPLVM, Georgoulis et al. 2015), pca (Nielsen et al. 2015), noll (Nöll et al. 2014), chandraker
(Chandraker & Ramamoorthi 2011), ashikhmin (Ashikhmin & Premože 2007), oracle (evaluation only).

A slice extracted from photos has thin bins at its ends: `predict_slice(method, rho, n, view)`
(n (90,) sample counts from slice.csv) empties that sparse tail first and returns a Prediction
(table, variance, novelty warning), exactly as `flashbrdf infer` makes it; `predict` takes the
slice as given. predict or novelty before fit raise NotFittedError.
"""

from flashbrdf.infer.adapter import DSGPLVMMethod
from flashbrdf.infer.baselines import PCA, Ashikhmin, Chandraker, Noll, Oracle
from flashbrdf.infer.estimator import InferenceMethod, NotFittedError
from flashbrdf.infer.training_set import TrainingSet
from flashbrdf.infer.model_file import load_method, read_model, save_model
from flashbrdf.infer.relative import RelativeDSGPLVMMethod
from flashbrdf.infer.methods import METHODS, dsgplvm_method, make_method, method_from_model
from flashbrdf.infer.prediction import Prediction, predict_slice
from flashbrdf.infer.warning import novelty_warning, prediction_warning


__all__ = ["METHODS", "dsgplvm_method", "make_method", "method_from_model", "novelty_warning",
           "prediction_warning", "InferenceMethod", "NotFittedError", "Prediction",
           "predict_slice", "TrainingSet", "DSGPLVMMethod", "RelativeDSGPLVMMethod", "PCA",
           "Ashikhmin", "Chandraker", "Noll", "Oracle", "save_model", "read_model", "load_method"]
