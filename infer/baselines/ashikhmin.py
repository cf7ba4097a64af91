"""Ashikhmin–Premože distribution-based BRDF ([1] of the paper) driven by the flash slice.

Model (Ashikhmin & Premože 2007, "Distribution-based BRDFs"), all of the BRDF in its specular term:
    ρ(ωi, ωo) = c · p(θh) · F(cos θd) / (4 (cos θi + cos θo − cos θi cos θo))
with p the microfacet (half-vector) distribution, c its normalisation, and the shadowing/
normalisation denominator D(θh, θd, φd) = 4 (cos θi + cos θo − cos θi cos θo) > 0 above the horizon.
Fresnel is Schlick's, F(cos θd) = r0 + (1 − r0)(1 − cos θd)^5.

Derivation. The flash slice is the φd-mean of ρ at θd bin 0 (θd0 = 0.5°), so
    ρ_slice(θh) = c p(θh) F(cos θd0) · ⟨1/D(θh, θd0, ·)⟩_φd   =>   c p(θh) = ρ_slice(θh) / (F0 ⟨1/D0⟩)
and at every valid bin
    ρ(θh, θd, φd) = ρ_slice(θh) · F(cos θd) / F(cos θd0) · 1 / (D(θh, θd, φd) ⟨1/D0⟩(θh)).
(At θd → 0, D → 4(2 cos θh − cos² θh); using the slice's own bin centre keeps the model exact on
bin-centred data.) As in the paper, the slice is taken as perfectly represented; only the θd/φd
extrapolation is the model's. r0 (one scalar) is fitted on the training set only: it minimises the mean
LAB-log error of the 2D predictions of the training materials from their own slices.
"""

import numpy as np
from scipy.optimize import minimize_scalar

from flashbrdf.brdf import merl, metrics
from flashbrdf.brdf.bins import scatter_valid, valid_bins_3d
from flashbrdf.brdf.shadowing import geometry_ratio_2d, geometry_ratio_valid
from flashbrdf.infer.estimator import InferenceMethod
from flashbrdf.infer.slices import fill_slice


def schlick(cos_theta_d, r0):
    """Schlick's Fresnel approximation, dimensionless, broadcasting."""
    return r0 + (1.0 - r0) * (1.0 - cos_theta_d) ** 5


def ratio_2d(r0):
    """ρ_2D(θh, θd) / ρ_slice(θh), (90, 90), NaN where no valid φd."""
    cos_d = np.cos(merl.theta_d_centres())
    fresnel = schlick(cos_d, r0) / schlick(cos_d[0], r0)
    return geometry_ratio_2d() * fresnel[None, :]


class Ashikhmin(InferenceMethod):
    name = "ashikhmin"
    closed_form_3d = True

    def __init__(self, r0=None):
        self.r0 = r0  # None: fit on the training set

    def fit(self, training=None):
        if self.r0 is not None:
            self.r0_ = float(self.r0)
            return self
        if training is None:
            raise ValueError("ashikhmin needs a training set to fit r0 (or r0=...)")
        slices = np.array([fill_slice(s) for s in training.slices])[:, :, None, :]

        reference = metrics.lab_log_reference(training.tables_2d)   # the truth's Lab, once

        def cost(log_r0):
            # every material has the same valid bins, so the pooled mean is the mean of the means
            pred = slices * ratio_2d(np.exp(log_r0))[None, :, :, None]
            return metrics.lab_log_error(pred, reference)

        grid = np.linspace(np.log(1e-3), 0.0, 15)
        costs = [cost(g) for g in grid]
        k = int(np.argmin(costs))
        lo, hi = grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]
        best = minimize_scalar(cost, bounds=(lo, hi), method="bounded", options={"xatol": 1e-4})
        self.r0_ = float(np.exp(best.x if best.fun <= costs[k] else grid[k]))
        return self

    def fitted_params(self):
        return {"r0": self.r0_}

    def _predict_2d(self, rho):
        return fill_slice(rho)[:, None, :] * ratio_2d(self.r0_)[:, :, None], None

    def predict_valid_3d(self, rho, sel=slice(None)):
        ih, jd, _ = valid_bins_3d()
        ih = ih[sel]
        cos_d = np.cos(merl.theta_d_centres())
        fresnel = schlick(cos_d, self.r0_) / schlick(cos_d[0], self.r0_)
        factor = geometry_ratio_valid()[sel] * fresnel[jd[sel]]
        return fill_slice(rho)[ih] * factor[:, None]

    def _predict_3d(self, rho):
        return scatter_valid(self.predict_valid_3d(rho)), None
