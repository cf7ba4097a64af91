"""DS-GPLVM behind the common interface: ρ in and out, features in between.

The model (infer.dsgplvm.DSGPLVM) works on feature matrices: brdf.colour.rho_to_features of the flash
slice (270 = 90 θh × 3), of the 2D table (24,300) and optionally of the valid 3D bins, NaN where a bin
has no data. This adapter builds those views from a TrainingSet, inverts the predicted features with
brdf.colour.features_to_rho and marks invalid bins NaN. 3D predictions combine the training 3D tables
in feature space with the model's GP weights, streamed one table at a time; a model trained without
a 3D view uses its 2D view's weights (the GP posterior mean is linear in the training outputs).
"""

import numpy as np

from brdf import colour
from infer.common import InferenceMethod, LinearSpace, valid_mask_2d


def _model_class():
    from infer.dsgplvm import DSGPLVM
    return DSGPLVM


class FeatureSpace(LinearSpace):
    """brdf feature map (log, then Lab unless space="rgb") as the combination space."""

    def __init__(self, space="lab"):
        self.space = space

    def forward(self, rho, sel=slice(None)):
        return colour.rho_to_features(rho, space=self.space)

    def inverse(self, mapped, sel=slice(None)):
        return colour.features_to_rho(mapped, space=self.space)


def slice_features(rho, space="lab"):
    """(90, 3) ρ, NaN empty -> (270,) features, NaN where empty (missing data for the model)."""
    feats = colour.rho_to_features(np.nan_to_num(rho), space=space)
    feats[~np.isfinite(rho).all(axis=1)] = np.nan
    return feats.ravel()


def table_features(tables_2d, space="lab"):
    """(N, 90, 90, 3) ρ -> (N, 24300) features, NaN where the table has no data."""
    tables = np.asarray(tables_2d, float)
    feats = colour.rho_to_features(np.nan_to_num(tables), space=space)
    feats[~np.isfinite(tables).all(axis=-1)] = np.nan
    return feats.reshape(len(tables), -1)


class DSGPLVMMethod(InferenceMethod):
    """fit(training) / predict(flash_slice, view) for the DS-GPLVM.

    q, beta, seed and **model_kw go to DSGPLVM; feature_space "lab" (paper) or "rgb" (ablation);
    views ("1d", "2d") or ("1d", "2d", "3d") (3D features are float32 rows of the valid bins).
    """
    name = "dsgplvm"

    def __init__(self, q=None, beta=50.0, feature_space="lab", views=("1d", "2d"), seed=0,
                 model=None, **model_kw):
        self.q, self.beta, self.feature_space = q, beta, feature_space
        self.views, self.seed, self.model_kw = tuple(views), seed, model_kw
        self.model = model  # an already fitted DSGPLVM (e.g. loaded from a file)

    def get_params(self):
        return {"q": self.q, "beta": self.beta, "feature_space": self.feature_space,
                "views": list(self.views), "seed": self.seed, **self.model_kw}

    def view_features(self, training):
        views = {"1d": np.array([slice_features(s, self.feature_space) for s in training.slices]),
                 "2d": table_features(training.tables_2d, self.feature_space)}
        if "3d" in self.views:
            rows = np.empty((len(training), training.table_3d_valid(0).size), np.float32)
            for i in range(len(training)):
                rows[i] = colour.rho_to_features(training.table_3d_valid(i),
                                                 space=self.feature_space).ravel()
            views["3d"] = rows
        return views

    def fit(self, training, labels=None):
        self.training_ = training
        if self.model is None:
            model = _model_class()(q=self.q, beta=self.beta, seed=self.seed, **self.model_kw)
            self.model = model.fit(self.view_features(training), labels=labels)
        return self

    def _predict_2d(self, rho):
        mean, var = self.model.predict(slice_features(rho, self.feature_space), view="2d")
        mean = np.asarray(mean, float).reshape(90, 90, 3)
        table = colour.features_to_rho(np.nan_to_num(mean), space=self.feature_space)
        invalid = ~valid_mask_2d() | ~np.isfinite(mean).all(axis=-1)
        table[invalid] = np.nan
        var = np.broadcast_to(np.asarray(var, float), (90 * 90 * 3,) if np.size(var) > 1 else ())
        if var.ndim:
            var = var.reshape(90, 90, 3).copy()
            var[invalid] = np.nan
        return table, var

    def _weights_view(self):
        trained = getattr(self.model, "views_", None) or getattr(self.model, "view_names_", None)
        return "3d" if trained is not None and "3d" in trained else "2d"

    def combination(self, rho):
        weights, _ = self.model.predict_weights(slice_features(rho, self.feature_space),
                                                view=self._weights_view())
        return np.asarray(weights, float), FeatureSpace(self.feature_space)
