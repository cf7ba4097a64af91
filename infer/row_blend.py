"""Trust the observation near θd = 0: blend a predicted table toward the observed row, extended along θd.

Why: the flash slice *is* the θd = 0 row, and for every measured material ρ(θh, θd) changes slowly
with θd near 0 (Fresnel and shadowing terms are flat there). Extending the observed row flatly along
θd (what Chandraker & Ramamoorthi's isotropic-in-θd assumption gives) is the best predictor of the
θd 0–30° band off MERL (RGL (NBRDF proxy): 1.64 against 2.8 for the anchored DS-GPLVM trained on MERL
only), while the DS-GPLVM knows how a material falls off toward grazing θd. Anchoring
(infer.anchoring.anchor_to_slice) moves the whole prediction by a θh correction smoothed over a few
bins, so the slice's fine θh structure never reaches the low-θd rows. The blend is

    ln(ρ + e) = (1 − w(θd)) · ln(ρ_pred + e) + w(θd) · ln(ρ_row(θh) · g + e),   w(θd) = exp(−θd² / 2τ²),

with e = brdf.colour.FEATURE_OFFSET (the log features' offset) and τ = ROW_BLEND_DEG, on the θh
bins the slice observes; w = 0 on the others, so missing bins stay the model's guess and a one-bin
or all-grazing slice changes nothing elsewhere. g(θh, θd, φd) is the microfacet shadowing/
normalisation ratio (brdf.shadowing.geometry_ratio_valid): the row is extended as a microfacet BRDF
with an unchanged distribution would be, not flat. Its φd-mean is 1 at θd = 0, within 7% up to
θd = 20° and 16% at 30°, where w has fallen to 0.32, so the blend changes little on MERL (NBRDF
proxy) 80/20 splits (LAB-log 5.071 flat, 5.070 with g) or RGL (NBRDF proxy) folds (9.70, 9.71); a
render sees its φd structure: the DiLiGenT ball's ΔE-log went from 1.365 to 1.355
(docs/results.md, "One-off investigations": slice_fit).

τ was chosen on MERL (NBRDF proxy) cross-validation, before looking at RGL (benchmarks/results/
generalisation.md states the measurements).
"""

import numpy as np

from flashbrdf.brdf import merl
from flashbrdf.brdf.colour import FEATURE_OFFSET
from flashbrdf.brdf.bins import valid_bins_3d
from flashbrdf.brdf.shadowing import geometry_ratio_2d, geometry_ratio_valid
from flashbrdf.infer.estimator import LinearSpace

ROW_BLEND_DEG = 20.0     # τ in degrees of θd: w = 0.61 at 20°, 0.11 at 40°, < 0.01 past 60°


def row_weights(scale_deg=ROW_BLEND_DEG):
    """w(θd) (90,) over the θd bin centres: exp(−θd²/2τ²); all 0 when scale_deg <= 0."""
    if not scale_deg or scale_deg <= 0:
        return np.zeros(merl.N_THETA_D)
    theta_d = np.degrees(merl.theta_d_centres())
    return np.exp(-0.5 * (theta_d / scale_deg) ** 2)


def blend_weights(flash_slice, scale_deg=ROW_BLEND_DEG):
    """(ρ_row (90, 3) in 1/sr, w (90, 90) over (θh, θd)) for a (90, 3) slice, NaN where empty:
    ρ_row is the slice with empty bins set to 0, w = row_weights on observed θh bins, 0 elsewhere."""
    rho = np.asarray(flash_slice, dtype=float)
    seen = np.isfinite(rho).all(axis=1)
    return np.where(seen[:, None], rho, 0.0), seen[:, None] * row_weights(scale_deg)[None, :]


def blend_log(rho, row, weights):
    """The blend of ρ (..., 3) toward ρ_row, both 1/sr, broadcastable, with weights w broadcastable
    to ρ[..., 0]. Negative ρ counts as 0; NaN in ρ stays NaN; returns ρ ≥ 0."""
    e = FEATURE_OFFSET
    w = np.asarray(weights, dtype=float)[..., None]
    log_rho = (1.0 - w) * np.log(np.maximum(rho, 0.0) + e) + w * np.log(np.maximum(row, 0.0) + e)
    return np.maximum(np.exp(log_rho) - e, 0.0)


def blend_toward_row(table, flash_slice, scale_deg=ROW_BLEND_DEG):
    """A 2D (90, 90, 3) or 3D (90, 90, 180, 3) predicted table (1/sr, NaN where no data) blended
    toward the observed (90, 3) slice extended along θd by the microfacet geometry (module
    docstring)."""
    table = np.asarray(table, dtype=float)
    row, w = blend_weights(flash_slice, scale_deg)
    if table.ndim == 3:
        target = row[:, None, :] * np.nan_to_num(geometry_ratio_2d(), nan=1.0)[..., None]
        return blend_log(table, target, w)
    ratio = np.ones(merl.MERL_SHAPE)
    ratio[valid_bins_3d()] = geometry_ratio_valid()
    return blend_log(table, row[:, None, None, :] * ratio[..., None], w[..., None])


class RowBlendSpace(LinearSpace):
    """Another method's combination space whose inverse also blends toward the observed row of
    `flash_slice` (90, 3), so streamed 3D predictions are blended like the 2D ones."""

    def __init__(self, base, flash_slice, scale_deg=ROW_BLEND_DEG):
        self.base = base
        self.row, self.weights = blend_weights(flash_slice, scale_deg)
        self.clip_to_training = base.clip_to_training

    def forward(self, rho, sel=slice(None)):
        return self.base.forward(rho, sel)

    def inverse(self, mapped, sel=slice(None)):
        ih, jd, _ = valid_bins_3d()
        target = self.row[ih[sel]] * geometry_ratio_valid()[sel][:, None]
        return blend_log(self.base.inverse(mapped, sel), target, self.weights[ih[sel], jd[sel]])
