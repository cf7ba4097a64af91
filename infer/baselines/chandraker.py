"""Chandraker-style θd-invariant prediction (Chandraker & Ramamoorthi, CVPR 2011 [6] of the paper).

Their semi-parametric model assumes reflectance stable over θd, so from the flash slice
    ρ(θh, θd, φd) = ρ_slice(θh)          (1/sr)
at every valid bin. Empty slice bins are filled by log-space interpolation along θh (missing data).
It reproduces the observed slice exactly at θd bin 0.
"""

import numpy as np

from flashbrdf.brdf.bins import scatter_valid, valid_bins_3d, valid_mask_2d
from flashbrdf.brdf.merl import N_THETA_D
from flashbrdf.infer.estimator import InferenceMethod
from flashbrdf.infer.slices import fill_slice


class Chandraker(InferenceMethod):
    name = "chandraker"
    closed_form_3d = True
    needs_fit = False

    def fit(self, training=None):
        """Nothing to learn; `training` is accepted for the common interface."""
        self.fitted_ = True
        return self

    def _predict_2d(self, rho):
        table = np.repeat(fill_slice(rho)[:, None, :], N_THETA_D, axis=1)
        table[~valid_mask_2d()] = np.nan
        return table, None

    def predict_valid_3d(self, rho, sel=slice(None)):
        return fill_slice(rho)[valid_bins_3d()[0][sel]]

    def _predict_3d(self, rho):
        return scatter_valid(self.predict_valid_3d(rho)), None
