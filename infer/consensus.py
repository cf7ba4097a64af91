"""Consensus: the anchored DS-GPLVM's 2D prediction averaged with the baselines', per (θh, θd), in
the space the error is measured in.

Why: off the training kinds the methods err differently (benchmarks/generalisation.py, kind
hold-out: the DS-GPLVM is best on felt, Nöll on satin, PCA on papers at grazing θd), so an average
beats each of them on most materials. The average is taken in CIELAB of ln(1 + ρ) (the LAB-log
metric's own space, brdf.metrics): ΔE*ab is a norm, so the error of a convex combination is never
more than the combination of the members' errors, bin by bin.

    f(θh, θd) = Σ_m w_m(θh, θd) · Lab(ln(1 + ρ_m(θh, θd))),     ρ = exp(Lab⁻¹(f)) − 1,

with w_m ≥ 0, Σ_m w_m = 1, bilinear between knots at θh THETA_H_KNOTS_DEG (the middles of
0–10°, the specular peak, 10–40°, its flank, and 40–90°, the diffuse body) and θd
THETA_D_KNOTS_DEG (the centres of the θd bands 0–30, 30–60, 60–75, 75–90° that the benchmarks
report), constant beyond the end knots. The knot weights CONSENSUS_WEIGHTS were chosen on the RGL
(NBRDF proxy) dev kind hold-out (benchmarks/consensus_weights.py: each kind's reported figure
comes from weights chosen on the other kinds' held-out predictions only).
"""

import numpy as np

from flashbrdf.brdf import merl
from flashbrdf.brdf.colour import FEATURE_OFFSET
from flashbrdf.brdf.metrics import lab_log_features, rho_from_lab_log
from flashbrdf.infer.baselines import PCA, Noll

THETA_H_KNOTS_DEG = (5.0, 25.0, 65.0)
THETA_D_KNOTS_DEG = (15.0, 45.0, 67.5, 82.5)
CONSENSUS_MEMBERS = ("dsgplvm", "noll", "pca")
# [θh knot, θd knot, member] (benchmarks/consensus_weights.py, "knots fitted on every kind")
CONSENSUS_WEIGHTS = np.array([[[0.698, 0.301, 0.001],
                               [0.232, 0.621, 0.147],
                               [0.013, 0.569, 0.417],
                               [0.000, 0.476, 0.524]],
                              [[0.999, 0.000, 0.001],
                               [0.146, 0.248, 0.607],
                               [0.011, 0.204, 0.785],
                               [0.031, 0.336, 0.633]],
                              [[1.000, 0.000, 0.000],
                               [0.387, 0.582, 0.031],
                               [0.846, 0.154, 0.000],
                               [1.000, 0.000, 0.000]]])


def weights_per_bin(knot_weights=CONSENSUS_WEIGHTS):
    """(90, 90, M) member weights per (θh, θd) bin: knot_weights (H, D, M) on the grid
    THETA_H_KNOTS_DEG × THETA_D_KNOTS_DEG (or (D, M): the same for every θh) interpolated
    bilinearly, held constant beyond the end knots, then renormalised to sum to 1."""
    knots = np.asarray(knot_weights, dtype=float)
    if knots.ndim == 2:
        knots = knots[None]
    theta_h = np.degrees(merl.theta_h_centres())
    theta_d = np.degrees(merl.theta_d_centres())
    along_d = np.stack([[np.interp(theta_d, THETA_D_KNOTS_DEG, k[:, m])
                         for m in range(knots.shape[2])] for k in knots])      # (H, M, 90)
    h_knots = THETA_H_KNOTS_DEG if len(knots) > 1 else (0.0,)
    w = np.stack([[np.interp(theta_h, h_knots[:len(knots)], along_d[:, m, j])
                   for j in range(len(theta_d))] for m in range(knots.shape[2])])   # (M, 90d, 90h)
    w = np.transpose(w, (2, 1, 0))
    return w / w.sum(axis=2, keepdims=True)


def consensus_table(tables, knot_weights=CONSENSUS_WEIGHTS):
    """The consensus of member 2D tables (M, 90, 90, 3) in 1/sr (NaN where no data), ordered as
    knot_weights' columns: (90, 90, 3), NaN where the first member (the DS-GPLVM) has none; where
    another member has none (a Nöll mixture over a training table with a hole there), the first
    member's value stands in for it."""
    tables = np.asarray(tables, dtype=float)
    tables = np.where(np.isnan(tables), tables[:1], tables)
    features = lab_log_features(tables)                                   # (M, 90, 90, 3)
    mixed = np.einsum("hdm,mhdc->hdc", weights_per_bin(knot_weights), features)
    out = rho_from_lab_log(np.nan_to_num(mixed))
    out[~np.isfinite(mixed).all(axis=-1)] = np.nan
    return out


def member_spread(member_features, knot_weights=CONSENSUS_WEIGHTS):
    """Σ_m w_m (x_m − x̄)² per bin and channel, x̄ = Σ_m w_m x_m: (90, 90, 3) ≥ 0 in the
    features' units², for member features (M, 90, 90, 3) in any per-bin feature space (the
    variance of the member the consensus draws, at its weights)."""
    x = np.asarray(member_features, dtype=float)
    w = np.moveaxis(weights_per_bin(knot_weights), 2, 0)[..., None]      # (M, 90, 90, 1)
    mean = (w * x).sum(axis=0)
    return (w * (x - mean) ** 2).sum(axis=0)


class ConsensusMembers:
    """The baselines the consensus averages with the DS-GPLVM, fitted on the DS-GPLVM's own
    training set: Nöll et al. (infer.baselines.noll) and PCA (infer.baselines.pca, with the
    hyperparameters `train` chose for it, or its defaults)."""

    def __init__(self, training, pca_params=None):
        self.noll = Noll().fit(training)
        self.pca = PCA(**(pca_params or {})).fit(training)

    def tables(self, flash_slice):
        """{"noll": (90, 90, 3), "pca": (90, 90, 3)} 2D predictions in 1/sr for a checked slice."""
        return {"noll": self.noll.predict(flash_slice, "2d")[0],
                "pca": self.pca.predict(flash_slice, "2d")[0]}


def consensus_log_correction(table_2d, consensus_2d):
    """ln(consensus + e) − ln(table + e) (90, 90, 3), 0 where either is NaN."""
    e = FEATURE_OFFSET
    out = np.log(np.maximum(consensus_2d, 0.0) + e) - np.log(np.maximum(table_2d, 0.0) + e)
    return np.nan_to_num(out)
