"""Baselines of the paper's Table 1 behind the common fit/predict interface (see infer.estimator)."""

from infer.baselines.ashikhmin import Ashikhmin
from infer.baselines.chandraker import Chandraker
from infer.baselines.noll import Noll
from infer.baselines.oracle import Oracle, dual_weights
from infer.baselines.pca import PCA

__all__ = ["Ashikhmin", "Chandraker", "Noll", "Oracle", "PCA", "dual_weights"]
