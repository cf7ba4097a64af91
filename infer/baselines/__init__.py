"""Baselines of the paper's Table 1 behind the common fit/predict interface (see infer.estimator)."""

from flashbrdf.infer.baselines.ashikhmin import Ashikhmin
from flashbrdf.infer.baselines.chandraker import Chandraker
from flashbrdf.infer.baselines.noll import Noll
from flashbrdf.infer.baselines.oracle import Oracle, dual_weights
from flashbrdf.infer.baselines.pca import PCA

__all__ = ["Ashikhmin", "Chandraker", "Noll", "Oracle", "PCA", "dual_weights"]
