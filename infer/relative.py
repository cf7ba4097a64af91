"""The relative representation of the default DS-GPLVM: how reflectance changes with θd, per channel,
relative to the observed θd = 0 row and to the channel's own level.

Why: the paper's features (CIELAB of ln ρ for the whole table) put a material's absolute colour and
level into every distance, although how ρ changes with θd barely depends on them. A model trained on
MERL's plastics and metals then collapses towards MERL's mean for a felt or a paper. Here each colour
channel of each training material is one training row, scaled by its own level, and the 2D view is the
log-ratio field of the table to its θd = 0 row. The θd = 0 row of a prediction is therefore the
observation itself (anchoring is exact, by construction), and a red felt and a white felt share one
neighbourhood.

For one channel c with level L (median of the observed slice over θh < LEVEL_MAX_THETA_H_DEG):
- slice features  f(θh) = ln(ρ(θh, 0)/L + ε), NaN where the bin is missing or θh ≥ FEATURE_MAX_THETA_H_DEG;
- ratio field     r(θh, θd[, φd]) = ln(ρ(θh, θd[, φd])/L + ε) − f̄(θh),
  with f̄ the slice filled over its missing bins (infer.slices.fill_slice);
- inverse         ρ = L·(exp(f̄(θh) + r) − ε), clamped ≥ 0.
ε = RATIO_EPSILON (relative to L) keeps the logs finite for black bins. Values are ρ in 1/sr; arrays
are (90,) over θh, (90, 90) over (θh, θd) or (n, ) over valid 3D bins with their θh index.
"""

import warnings

import numpy as np

from flashbrdf.brdf import merl
from flashbrdf.brdf.bins import scatter_valid, valid_bins_3d, valid_mask_2d
from flashbrdf.brdf.merl import N_THETA_D, N_THETA_H
from flashbrdf.infer.estimator import InferenceMethod, clip_to_range
from flashbrdf.infer.slices import check_slice, fill_slice
from flashbrdf.infer.dsgplvm import DSGPLVM
from flashbrdf.infer.gp import loo_bin_variance
from flashbrdf.infer.viewdata import restore_rows

RATIO_EPSILON = 1e-2               # relative to the channel level: below 1% of it, ρ counts as black
LEVEL_MAX_THETA_H_DEG = 75.0       # the level ignores the grazing end of the slice, which captures miss
FEATURE_MAX_THETA_H_DEG = 75.0     # slice bins past this are anchored on, not compared: a real flash
                                   # capture rarely has them, and measured data is least trustworthy there
LEVEL_FLOOR = 1e-8                 # 1/sr: a black channel keeps a finite scale


def _theta_h_deg():
    return np.degrees(merl.theta_h_centres())


def channel_levels(flash_slice):
    """Per-channel level L (3,) in 1/sr of a (90, 3) slice (NaN = missing): the median over the
    observed bins below LEVEL_MAX_THETA_H_DEG (over all observed bins when none is), floored."""
    rho = np.asarray(flash_slice, dtype=float)
    seen = np.isfinite(rho).all(axis=1)
    low = seen & (_theta_h_deg() < LEVEL_MAX_THETA_H_DEG)
    rows = rho[low] if low.any() else rho[seen]
    return np.maximum(np.median(rows, axis=0), LEVEL_FLOOR)


def log_relative(rho, levels):
    """ln(ρ/L + ε) for ρ (..., 3) in 1/sr and levels (3,); negative or NaN ρ stays NaN."""
    rho = np.asarray(rho, dtype=float)
    with np.errstate(invalid="ignore"):
        return np.log(np.where(rho >= 0, rho, np.nan) / levels + RATIO_EPSILON)


def slice_features(flash_slice, levels):
    """(3, 90) per-channel slice features, NaN where missing or past FEATURE_MAX_THETA_H_DEG."""
    f = log_relative(flash_slice, levels).T.copy()
    f[:, _theta_h_deg() >= FEATURE_MAX_THETA_H_DEG] = np.nan
    return f


def ratio_field(table_2d, filled_slice, levels):
    """(3, 8100) per-channel log-ratio rows of a (90, 90, 3) table (NaN kept) to its filled slice."""
    r = log_relative(table_2d, levels) - log_relative(filled_slice, levels)[:, None, :]
    return np.moveaxis(r, -1, 0).reshape(3, -1)


def from_ratio(ratio, filled_slice, levels, theta_h_index=None):
    """ρ from per-channel log-ratios. ratio: (90, 90, 3) over (θh, θd), or (n, 3) on bins whose θh
    bin is theta_h_index (n,). Returns ρ of the same shape, ≥ 0, NaN where ratio is NaN."""
    anchor = log_relative(filled_slice, levels)                       # (90, 3)
    anchor = anchor[:, None, :] if theta_h_index is None else anchor[theta_h_index]
    out = (np.exp(anchor + ratio) - RATIO_EPSILON) * levels
    return np.where(np.isnan(out), np.nan, np.maximum(out, 0.0))


# ----------------------------------------------------------------------------- the estimator
Z90 = 1.6448536269514722          # half-width of the central 90% interval of a unit normal


def training_rows(training):
    """Per-channel training rows of a TrainingSet: -> (levels (N, 3), filled slices (N, 90, 3),
    1D features (3N, 90), 2D ratio rows (3N, 8100)); row 3i + c is channel c of material i."""
    filled = np.array([fill_slice(check_slice(s)) for s in training.slices])
    levels = np.array([channel_levels(s) for s in training.slices])
    feats = np.concatenate([slice_features(s, lv) for s, lv in zip(training.slices, levels)])
    ratios = np.concatenate([ratio_field(t, f, lv)
                             for t, f, lv in zip(training.tables_2d, filled, levels)])
    ratios[:, ~valid_mask_2d().ravel()] = np.nan
    return levels, filled, feats, ratios


class RelativeDSGPLVMMethod(InferenceMethod):
    """The default `dsgplvm`: the paper's DS-GPLVM (infer.dsgplvm.DSGPLVM, unchanged) trained on the
    relative representation of this module instead of whole-table CIELAB features.

    Each training material gives three rows (its channels). A flash slice is split the same way;
    each channel is projected by the 1D back-mapping and mapped to its ratio field by the 2D GP,
    then multiplied back onto the observed row. q, beta, seed, **model_kw go to DSGPLVM.
    calibration: κ, the factor on the per-bin predictive variance that makes central 90% intervals
    cover 90% of held-out bins (set by `flashbrdf train` on a held-out split; 1.0 = uncalibrated).
    A DSGPLVM trained before (from a model file) is used through `from_model`, not `fit`.
    """
    name = "dsgplvm"
    has_uncertainty = True
    feature_label = f"ln(rho/L + {RATIO_EPSILON:g}) per channel, L the channel's slice level"

    def __init__(self, q=None, beta=50.0, variance=0.95, max_cycles=10, seed=0, calibration=1.0,
                 anchor=True, representation="relative", **model_kw):
        # anchor: accepted for the command line's --no-anchor; a relative prediction passes through
        # the observed row by construction, so there is nothing to switch off
        if representation != "relative":
            raise ValueError("RelativeDSGPLVMMethod is the relative representation")
        self.anchor, self.representation = anchor, representation
        self.q, self.beta, self.variance, self.max_cycles = q, beta, variance, max_cycles
        self.seed, self.calibration, self.model_kw = seed, calibration, model_kw

    def get_params(self, deep=True):
        """InferenceMethod's, plus the keyword arguments that go to DSGPLVM."""
        return {**super().get_params(deep), **self.model_kw}

    def fit(self, training, labels=None):
        levels, filled, feats, ratios = training_rows(training)
        model = DSGPLVM(q=self.q, beta=self.beta, variance=self.variance,
                        max_cycles=self.max_cycles, seed=self.seed,
                        views=("1d", "2d"), **self.model_kw).fit(
            {"1d": feats, "2d": ratios}, labels=None if labels is None else np.repeat(labels, 3))
        return self._use_model(model, training, (levels, filled, feats, ratios))

    @classmethod
    def from_model(cls, model, training, **params):
        """A fitted estimator around a DSGPLVM trained before (e.g. read from MODEL.npz) on
        `training` (TrainingSet): loading, not fitting. params: the constructor's arguments.
        A model stored without its 2D rows gets them back from the training tables."""
        return cls(**params)._use_model(model, training)

    def _use_model(self, model, training, rows=None):
        """Set the fitted state from a trained DSGPLVM and its training set; returns self."""
        self.training_ = training
        self.levels_, self.filled_, feats, ratios = training_rows(training) if rows is None else rows
        self.model_ = model
        if self.model_.view_data_["2d"].data is None:
            restore_rows(self.model_, "2d", ratios)
        with np.errstate(invalid="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)   # columns no training row has
            self.ratio_range_ = (np.nanmin(ratios, axis=0), np.nanmax(ratios, axis=0))
        self.bin_variance_ = loo_bin_variance(self.model_.posteriors_["2d"],
                                              self.model_.view_data_["2d"].data)
        return self

    def _channel_weights(self, rho):
        """(levels (3,), filled slice (90, 3), weights (3, 3N), GP variance (3,) in scaled units)."""
        levels = channel_levels(rho)
        w, var = self.model_.posteriors_["2d"].weights(
            self.model_.project(slice_features(rho, levels)))
        w = w + (1.0 - w.sum(1, keepdims=True)) / w.shape[1]          # fold the view mean in
        return levels, fill_slice(rho), w, var

    def _predict_2d(self, rho):
        levels, filled, w, var = self._channel_weights(rho)
        data = self.model_.view_data_["2d"]
        ratio = np.full((3, len(data.keep)), np.nan)
        ratio[:, data.keep] = data.mean[data.keep] + data.scale * (w @ data.data)
        ratio = clip_to_range(ratio, *self.ratio_range_)
        ratio = np.moveaxis(ratio.reshape(3, N_THETA_H, N_THETA_D), 0, -1)
        table = from_ratio(ratio, filled, levels)
        table[~valid_mask_2d()] = np.nan
        variance = self.bin_variance(var)
        variance[~valid_mask_2d()] = np.nan
        return table, variance

    def bin_variance(self, gp_variance):
        """Per-bin predictive variance (90, 90, 3) of the ratio, in feature units², from the GP's
        per-channel variance (3,): κ · v_c · LOO shape(bin) · scale²; 0 on the θd = 0 row, which is
        the observation."""
        data = self.model_.view_data_["2d"]
        shape = np.full(len(data.keep), np.nan)
        shape[data.keep] = self.bin_variance_
        v = self.calibration * np.asarray(gp_variance)[:, None] * shape[None] * data.scale ** 2
        return np.moveaxis(v.reshape(3, N_THETA_H, N_THETA_D), 0, -1)

    def _predict_3d(self, rho):
        levels, filled, w, var = self._channel_weights(rho)
        ratio = stream_relative(self.training_, w, self.levels_, self.filled_)
        ih = valid_bins_3d()[0]
        return scatter_valid(from_ratio(ratio, filled, levels, theta_h_index=ih)), \
            np.float64(self.calibration * float(np.mean(var)) * self.model_.view_data_["2d"].scale ** 2)

    def novelty(self, flash_slice):
        """How far a slice lies from the training slices (infer.dsgplvm.DSGPLVM.novelty), worst
        channel: > 1 means outside what the model was trained on."""
        self.check_fitted()
        rho = check_slice(flash_slice)
        return float(np.max(self.model_.novelty(slice_features(rho, channel_levels(rho)))))


def stream_relative(training, weights, levels, filled, workers=None):
    """Σ_k w_ck r_k over the valid 3D bins, for per-channel weights (3, 3N) over the 3N channel rows
    r_k of the training tables' 3D ratio fields, read one table at a time. -> (n_valid, 3)."""
    ih = valid_bins_3d()[0]

    def one(i):
        rho = training.table_3d_valid(i, np.float32)
        ratio = log_relative(rho, levels[i]) - log_relative(filled[i], levels[i])[ih]
        return np.nan_to_num(ratio) @ weights[:, 3 * i:3 * i + 3].T

    total = np.zeros((len(ih), 3))
    for i in range(len(training)):
        total += one(i)
    return total
