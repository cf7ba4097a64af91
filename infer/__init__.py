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
from flashbrdf.infer.methods import METHODS, dsgplvm_method, make_method, method_from_model
from flashbrdf.infer.warning import novelty_warning, prediction_warning


__all__ = ["METHODS", "dsgplvm_method", "make_method", "method_from_model", "novelty_warning",
           "prediction_warning", "InferenceMethod", "TrainingSet", "DSGPLVMMethod",
           "RelativeDSGPLVMMethod", "PCA",
           "Ashikhmin", "Chandraker", "Noll", "Oracle", "save_model", "read_model", "load_method"]
