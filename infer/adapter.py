"""DS-GPLVM behind the common interface: ρ in and out, features in between.

The model (infer.dsgplvm.DSGPLVM) works on feature matrices: brdf.colour.rho_to_features of the flash
slice (270 = 90 θh × 3), of the 2D table (24,300) and optionally of the valid 3D bins, NaN where a bin
has no data. This adapter builds those views from a TrainingSet, inverts the predicted features with
brdf.colour.features_to_rho and marks invalid bins NaN. 3D predictions combine the training 3D tables
in feature space with the model's GP weights, streamed one table at a time; a model trained without
a 3D view uses its 2D view's weights (the GP posterior mean is linear in the training outputs).
"""

from contextlib import nullcontext

import numpy as np

from flashbrdf.brdf import colour
from flashbrdf.brdf.bins import scatter_valid, valid_flat_3d, valid_mask_2d
from flashbrdf.brdf.merl import N_THETA_D, N_THETA_H
from flashbrdf.infer.consensus import (ConsensusMembers, consensus_log_correction,
                                       consensus_table, member_spread)
from flashbrdf.infer.anchoring import AnchoredSpace, anchor_log_correction, anchor_to_slice
from flashbrdf.infer.blas import one_blas_thread
from flashbrdf.infer.dsgplvm import DSGPLVM
from flashbrdf.infer.estimator import (
    InferenceMethod,
    LinearSpace,
    clip_to_range,
    stream_combination,
)
from flashbrdf.infer.gp import loo_bin_variance
from flashbrdf.infer.row_blend import ROW_BLEND_DEG, RowBlendSpace, blend_toward_row
from flashbrdf.infer.slice_fit import (
    SLICE_FIT_WEIGHT,
    convex_slice_weights,
    mixed_weights,
    slice_fit_share,
)
from flashbrdf.infer.slices import check_slice
from flashbrdf.infer.uncertainty import mixture_spread, weights_disagreement


class FeatureSpace(LinearSpace):
    """brdf feature map (log, then Lab unless space="rgb") as the combination space; GP means are
    clipped to the training range (LinearSpace.clip_to_training)."""
    clip_to_training = True

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
    # NaN passes through the feature map; inf, or a bin with a channel missing, is masked below
    feats = colour.rho_to_features(tables, space=space)
    feats[~np.isfinite(tables).all(axis=-1)] = np.nan
    return feats.reshape(len(tables), -1)


class DSGPLVMMethod(InferenceMethod):
    """fit(training) / predict(flash_slice, view) for the DS-GPLVM.

    q, beta, seed and **model_kw go to DSGPLVM; feature_space "lab" (paper) or "rgb" (ablation);
    views ("1d", "2d") or ("1d", "2d", "3d") (3D features are float32 rows of the valid bins).
    latent "backprojection" (the paper, Eq. 9) or "optimise" (ablation without back-constraints at
    test time: x* maximises the 1D GP's predictive density of the observed slice bins).
    anchor: False (the paper) or True, our addition: the prediction is corrected along theta_h so
    its theta_d = 0 row passes through the observed slice (infer.anchoring.anchor_to_slice), then
    blended toward the observed row's flat extension near theta_d = 0 over row_blend_deg degrees
    (infer.row_blend; 0 switches the blend off). The 3D prediction takes the correction computed on
    the 2D prediction, so both views agree.
    slice_fit: our addition, applied with anchor=True: the share λ of the prediction's weights over
    the training tables that comes from a direct convex fit of the training slices to the observed
    one rather than from the GP (infer.slice_fit; 0: the GP's weights alone, as in the paper);
    all of them for a slice past the out-of-training threshold (infer.slice_fit.slice_fit_share).
    consensus: our addition, applied with anchor=True: the 2D prediction is averaged with Nöll's
    and PCA's (fitted on the same training set; PCA with `pca_params`) per θd in the LAB-log
    metric's space (infer.consensus); the variance gains the members' spread. 3D predictions take
    the consensus' (θh, θd) level and keep the DS-GPLVM's φd structure.
    A DSGPLVM trained before (read from a model file) is used through `from_model`, not `fit`.
    """
    name = "dsgplvm"
    has_uncertainty = True

    def __init__(self, q=None, beta=50.0, feature_space="lab", views=("1d", "2d"), seed=0,
                 latent="backprojection", anchor=False, representation="absolute",
                 calibration=1.0, row_blend_deg=ROW_BLEND_DEG, slice_fit=SLICE_FIT_WEIGHT,
                 consensus=True, pca_params=None, **model_kw):
        if representation != "absolute":
            raise ValueError("DSGPLVMMethod is the absolute representation; see infer.dsgplvm_method")
        if latent not in ("backprojection", "optimise"):
            raise ValueError(f"latent must be 'backprojection' or 'optimise', not {latent!r}")
        self.q, self.beta, self.feature_space = q, beta, feature_space
        self.views, self.seed, self.latent = views, seed, latent
        self.anchor, self.representation, self.calibration = anchor, representation, calibration
        self.row_blend_deg, self.slice_fit = row_blend_deg, slice_fit
        self.consensus, self.pca_params = consensus, pca_params
        self.model_kw = model_kw

    @property
    def feature_label(self):
        """What the predictive variance is measured in, for reports."""
        return ("CIELAB" if self.feature_space == "lab" else "RGB") + " of ln(1 + rho/1e-3)"

    def get_params(self, deep=True):
        """InferenceMethod's, plus the keyword arguments that go to DSGPLVM."""
        return {**super().get_params(deep), **self.model_kw}

    def view_features(self, training, features_2d=None):
        """{view: (N, D_v) features}; features_2d: table_features of the 2D tables if at hand."""
        if features_2d is None:
            features_2d = table_features(training.tables_2d, self.feature_space)
        views = {"1d": np.array([slice_features(s, self.feature_space) for s in training.slices]),
                 "2d": features_2d}
        if "3d" in self.views:
            rows = np.empty((len(training), 3 * len(valid_flat_3d())), np.float32)
            for i in range(len(training)):
                rows[i] = colour.rho_to_features(training.table_3d_valid(i, np.float32),
                                                 space=self.feature_space).ravel()
            views["3d"] = rows
        return views

    def fit(self, training, labels=None):
        feats = table_features(training.tables_2d, self.feature_space)
        model = DSGPLVM(q=self.q, beta=self.beta, seed=self.seed, views=tuple(self.views),
                               **self.model_kw)
        model = model.fit(self.view_features(training, feats), labels=labels)
        return self._use_model(model, training, feats)

    @classmethod
    def from_model(cls, model, training, features_2d=None, **params):
        """A fitted estimator around a DSGPLVM trained before (e.g. read from MODEL.npz) on
        `training` (TrainingSet): loading, not fitting. params: the constructor's arguments;
        features_2d: table_features of the training tables, if at hand."""
        return cls(**params)._use_model(model, training, features_2d)

    def _use_model(self, model, training, feats=None):
        """Set the fitted state from a trained DSGPLVM and its training set; returns self."""
        self.training_ = training
        if feats is None:
            feats = table_features(training.tables_2d, self.feature_space)
        # bins below the horizon are NaN in every table: left NaN without numpy's all-NaN
        # warning (catch_warnings is not thread-safe, and Dask workers fit in threads)
        seen = ~np.isnan(feats).all(axis=0)
        low, high = np.full(feats.shape[1], np.nan), np.full(feats.shape[1], np.nan)
        low[seen], high[seen] = np.nanmin(feats[:, seen], axis=0), np.nanmax(feats[:, seen], axis=0)
        self.range_2d_ = (low, high)
        self.model_ = model
        rows = self.model_.view_data_["2d"].data
        self.bin_variance_ = None if rows is None else \
            loo_bin_variance(self.model_.posteriors_["2d"], rows)
        # the 2D rows and their squares, finite, for the combination's per-bin spread; float32:
        # a variance needs no more, and predict reads them whole (2 × 11 MB for 121 tables)
        self.rows_2d_ = None if rows is None else np.nan_to_num(rows).astype(np.float32)
        self.rows_2d_squared_ = None if rows is None else self.rows_2d_ ** 2
        self.members_ = ConsensusMembers(training, self.pca_params) \
            if self.anchor and self.consensus else None
        self._members_cache = None
        return self

    def novelty(self, flash_slice):
        """How far a slice lies from the training slices (infer.dsgplvm.DSGPLVM.novelty): > 1 means
        outside what the model was trained on."""
        self.check_fitted()
        return self.model_.novelty(slice_features(check_slice(flash_slice), self.feature_space))

    def bin_variance(self, gp_variance, combination_variance=None):
        """Per-bin predictive variance (90, 90, 3) in feature units² from the GP's per-dimension
        variance (feature units²): κ · (v · the 2D view's leave-one-out residual shape
        (infer.gp.loo_bin_variance) + combination_variance), so bins the training data predict
        badly get wide intervals. combination_variance: (D_kept,) in feature units², the spread and
        disagreement of the combined tables (infer.uncertainty), or None."""
        keep = self.model_.view_data_["2d"].keep
        kept = float(gp_variance) * (1.0 if self.bin_variance_ is None else self.bin_variance_)
        if combination_variance is not None:
            kept = kept + combination_variance
        out = np.full(len(keep), np.nan)
        out[keep] = kept
        return (self.calibration * out).reshape(N_THETA_H, N_THETA_D, 3)

    def _weight_parts(self, feats, view):
        """(the GP's weights (N,) over the training rows, summing to 1; its per-dimension predictive
        variance in feature units²; the slice fit's weights (N,), or None when not used; the
        slice's novelty, DSGPLVM.novelty)."""
        if self.latent == "backprojection":
            w, var = self.model_.predict_weights(feats, view=view)
        else:
            post = self.model_.posteriors_[view]
            w, var = post.weights(optimise_latent(self.model_, feats))
            w = w[0] + (1.0 - w[0].sum()) / w.shape[1]
            var = float(var[0]) * self.model_.view_data_[view].scale ** 2
        fit = None
        if self.anchor and self.slice_fit:   # our addition; anchor=False is the paper's
            src = self.model_.view_data_[self.model_.source_view]
            y = (np.asarray(feats, float)[src.keep] - src.mean[src.keep]) / src.scale
            fit = convex_slice_weights(src.data, y)
        return w, var, fit, self.model_.novelty(feats)

    def _weights(self, feats, view):
        """(weights (N,) over the training rows, summing to 1; the GP's per-dimension predictive
        variance in feature units²): the GP's weights, mixed with the slice fit's (slice_fit; all
        the slice fit's past the out-of-training threshold, infer.slice_fit.slice_fit_share)."""
        return self._mix(self._weight_parts(feats, view))

    def _mix(self, parts):
        w, var, fit, novelty = parts
        if fit is None:
            return w, var
        return mixed_weights(w, fit, slice_fit_share(novelty, self.slice_fit)), var

    def _combination_variance(self, parts):
        """(D_kept,) in feature units², for the anchored method: the spread of the 2D tables the
        λ = slice_fit combination combines plus the GP and slice-fit weights' disagreement
        (infer.uncertainty); None for the paper's method, whose variance is the GP's alone.
        At slice_fit's λ even past the out-of-training threshold, where the mean is the slice fit's
        alone: the switch moves the mean, not what is known about the slice, and the fit's sparse
        weights alone would narrow the intervals just where they are already too narrow (RGL (NBRDF
        proxy) from a MERL-only model: central-90% coverage 78.0% against 83.7%)."""
        if not self.anchor or self.rows_2d_ is None:
            return None
        w_gp, _, fit, _ = parts
        w = w_gp if fit is None else mixed_weights(w_gp, fit, self.slice_fit)
        out = mixture_spread(w, self.rows_2d_, self.rows_2d_squared_)
        if fit is not None:
            out = out + weights_disagreement(w_gp, fit, self.rows_2d_, self.slice_fit)
        return out * self.model_.view_data_["2d"].scale ** 2

    def predict(self, flash_slice, view="2d"):
        # the 2D view's products are small (infer.blas); the 3D stream keeps its threads
        with one_blas_thread() if view == "2d" else nullcontext():
            table, variance = super().predict(flash_slice, view)
        if self.anchor and view == "2d":  # 3D: anchored in combination()
            table, variance, _ = self._finished_2d(table, variance, check_slice(flash_slice))
        if view == "3d":
            # the 3D table's (θh, θd) level is the 2D prediction's (anchored, consensus): so is
            # its per-bin variance, the same across φd (the GP's own 3D variance is one number);
            # the anchored combination computed it already
            variance_2d = variance if np.ndim(variance) == 3 else \
                self.predict(flash_slice, "2d")[1]
            variance = np.where(np.isnan(table), np.nan, variance_2d[:, :, None, :])
        return table, variance

    def _finished_2d(self, table_2d, variance, rho):
        """The DS-GPLVM's own 2D table and variance → the default's: anchored to the slice,
        blended toward its row and, with consensus members, their consensus, the variance
        widened by κ × their spread. Returns (table, variance, members or None)."""
        table = self._anchored(table_2d, rho)
        if self.members_ is None:
            return table, variance, None
        members = self.member_tables(rho, table)
        stack = np.stack(list(members.values()))
        spread = member_spread(colour.rho_to_features(np.nan_to_num(stack),
                                                      space=self.feature_space))
        variance = variance + self.calibration * np.where(np.isnan(variance), np.nan, spread)
        return consensus_table(stack), variance, members

    def member_tables(self, flash_slice, own_table=None):
        """{"dsgplvm": the anchored DS-GPLVM's own 2D table, "noll", "pca"}: the consensus'
        members (infer.consensus) for a slice, each (90, 90, 3) in 1/sr; None without consensus.
        The last slice's are kept: the warning (infer.consensus_warning) asks again."""
        if self.members_ is None:
            return None
        rho = check_slice(flash_slice)
        key = rho.tobytes()
        cached = self._members_cache     # one read: another thread may replace it meanwhile
        if cached is not None and cached[0] == key:
            return cached[1]
        if own_table is None:
            with one_blas_thread():
                own_table = self._anchored(InferenceMethod.predict(self, rho, "2d")[0], rho)
        members = {"dsgplvm": own_table} | self.members_.tables(rho)
        self._members_cache = (key, members)
        return members

    def _anchored(self, table_2d, rho):
        """The DS-GPLVM's own 2D table anchored to the slice and blended toward its row."""
        return blend_toward_row(anchor_to_slice(table_2d, rho), rho, self.row_blend_deg)

    def _predict_2d(self, rho, parts=None):
        """parts: _weight_parts for the 2D view, when already at hand."""
        feats = slice_features(rho, self.feature_space)
        parts = self._weight_parts(feats, "2d") if parts is None else parts
        w, var = self._mix(parts)
        data = self.model_.view_data_["2d"]
        mean = np.full(len(data.keep), np.nan)
        # the weights sum to 1 and the stored rows are centred: mean + w @ rows is the combination
        mean[data.keep] = data.mean[data.keep] + data.scale * (w @ data.data)
        mean = clip_to_range(np.asarray(mean, float), *self.range_2d_)
        mean = mean.reshape(N_THETA_H, N_THETA_D, 3)
        table = colour.features_to_rho(np.nan_to_num(mean), space=self.feature_space)
        invalid = ~valid_mask_2d() | ~np.isfinite(mean).all(axis=-1)
        table[invalid] = np.nan
        # the GP's variance is one number per view (isotropic), broadcast over its dimensions
        var = self.bin_variance(var if np.isfinite(var) else np.nan,
                                self._combination_variance(parts))
        # Off the training data the GP's variance saturates at its prior while the error keeps
        # growing: widen the intervals by the squared novelty (distance over the training
        # slices' own 99th-percentile spacing) beyond 1. On RGL (NBRDF proxy), with the shipped
        # MERL-only model, this took 90% coverage from 70.6% to 80.0% (benchmarks/generalisation.py).
        novelty = parts[3]
        var *= max(1.0, novelty) ** 2
        var[invalid] = np.nan
        return table, var

    def _weights_view(self):
        return "3d" if "3d" in self.model_.view_names_ else "2d"

    def _predict_3d(self, rho):
        """Streamed 3D mean, and its variance: anchored, the 2D prediction's per-bin variance
        (90, 90, 3); otherwise the GP's per-dimension predictive variance (a scalar: one
        isotropic GP per view, in feature units², which predict replaces by the 2D view's)."""
        weights, space, var = self._combination(rho)
        return scatter_valid(stream_combination(self.training_, weights, space)), var

    def combination(self, rho):
        return self._combination(rho)[:2]

    def _combination(self, rho):
        """(weights (N,), 3D combination space, variance as _predict_3d returns it). Anchored:
        the space's inverse applies the correction computed on the 2D prediction."""
        view = self._weights_view()
        with one_blas_thread():   # small products only (infer.blas); the 3D stream is not here
            parts = self._weight_parts(slice_features(rho, self.feature_space), view)
            weights, var = self._mix(parts)
            if self.anchor:
                table_2d, var_2d = self._predict_2d(rho, parts if view == "2d" else None)
                final_2d, var, members = self._finished_2d(table_2d, var_2d, rho)
        space = FeatureSpace(self.feature_space)
        if self.anchor:
            # a model without a 3D view combines its 3D tables with the 2D weights: reuse them
            log_c = anchor_log_correction(table_2d[:, 0], rho)
            space = space if log_c is None else AnchoredSpace(space, log_c)
            space = RowBlendSpace(space, rho, self.row_blend_deg)
            if members is not None:  # its own member is the 2D table just predicted
                space = AnchoredSpace(space, consensus_log_correction(members["dsgplvm"],
                                                                      final_2d))
        return np.asarray(weights, float), space, var


def optimise_latent(model, feats, n_starts=5):
    """x* (1, q) minimising the 1D GP's negative log predictive density of the observed slice bins,
    started from the back-projection and the latents of the nearest training slices."""
    src = model.view_data_[model.source_view]
    y = (np.asarray(feats, float)[src.keep] - src.mean[src.keep]) / src.scale
    ok = np.isfinite(y)
    post = model.posteriors_[model.source_view]
    data = src.data[:, ok]

    def nll(x):
        w, var = post.weights(x[None])
        r = y[ok] - w[0] @ data
        return 0.5 * (r @ r) / var[0] + 0.5 * ok.sum() * np.log(var[0])

    d2 = ((np.nan_to_num(data) - y[ok]) ** 2).sum(1)
    starts = [model.project(feats)[0]] + [model.latent_[i] for i in np.argsort(d2)[:n_starts - 1]]
    from scipy.optimize import minimize  # here: the default latent="backprojection" never calls it
    best = min((minimize(nll, x0, method="L-BFGS-B") for x0 in starts), key=lambda r: r.fun)
    return best.x[None]
