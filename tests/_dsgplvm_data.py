"""Synthetic training sets for the DS-GPLVM tests (no MERL needed)."""

import numpy as np

from flashbrdf.brdf.colour import rho_to_features


def latent_views(n, seed=0, d1=30, d2=300):
    """n samples of a 2-D latent z ~ U(-1, 1)² through smooth nonlinear maps to two views.

    Returns (z (n, 2), view1 (n, d1), view2 (n, d2)); the maps are fixed (seed 1234) so different
    `seed`s draw different samples from the same manifold.
    """
    maps = np.random.default_rng(1234)
    w1, b1 = maps.normal(size=(2, d1)) * 1.5, maps.uniform(0, 2 * np.pi, d1)
    w2, b2 = maps.normal(size=(2, d2)) * 1.5, maps.uniform(0, 2 * np.pi, d2)
    c2 = maps.normal(size=(3, d2))
    z = np.random.default_rng(seed).uniform(-1, 1, size=(n, 2))
    view1 = np.sin(z @ w1 + b1) + 0.3 * z[:, :1] ** 2
    view2 = np.cos(z @ w2 + b2) + np.tanh(np.c_[z, z[:, :1] * z[:, 1:]] @ c2)
    return z, view1, view2


def analytic_brdf(n, seed=0, n_h=90, n_d=90):
    """n analytic BRDFs (diffuse + microfacet lobe with Schlick Fresnel) on the MERL (θh, θd) grid.

    Returns rho_1d (n, n_h, 3) and rho_2d (n, n_h, n_d, 3) in 1/sr; rho_1d is the θd bin-0 column.
    """
    rng = np.random.default_rng(seed)
    theta_h = 0.5 * np.pi * ((np.arange(n_h) + 0.5) / n_h) ** 2
    theta_d = np.radians(np.arange(n_d) + 0.5)
    rho = np.empty((n, n_h, n_d, 3))
    for i in range(n):
        kd = rng.uniform(0.0, 0.8, 3) / np.pi
        ks = rng.uniform(0.0, 1.0) * rng.uniform(0.5, 1.0, 3)
        alpha = 10 ** rng.uniform(-1.7, -0.3)
        r0 = rng.uniform(0.02, 0.9)
        c2 = np.cos(theta_h) ** 2
        d = np.exp((c2 - 1) / (c2 * alpha ** 2)) / (np.pi * alpha ** 2 * c2 ** 2)
        f = r0 + (1 - r0) * (1 - np.cos(theta_d)) ** 5
        lobe = d[:, None] * f[None, :] / (4 * np.cos(theta_d)[None, :] ** 2 + 0.1)
        rho[i] = kd + ks[None, None, :] * lobe[:, :, None]
    return rho[:, :, 0, :], rho


def to_features(rho):
    """brdf.colour.rho_to_features (Lab of ln(1 + ρ/1e-3)), flattened per material: (n, ..., 3) ->
    (n, D); NaN where ρ is NaN (missing)."""
    rho = np.asarray(rho, dtype=float)
    feats = rho_to_features(np.nan_to_num(rho))
    feats[~np.isfinite(rho).all(axis=-1)] = np.nan
    return feats.reshape(len(rho), -1)
