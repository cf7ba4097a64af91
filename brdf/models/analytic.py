"""Analytic BRDFs: Lambert, and Lambert + GGX microfacet specular (the renderer's test models)."""

import numpy as np

from flashbrdf.brdf.models.base import (INV_PI, BRDFModel, HalfVectorMixture, half_vector,
                                        luminance, sample_cosine)
from flashbrdf.brdf.models.microfacet import ggx_d, smith_g1


class Lambert(BRDFModel):
    """rho = albedo / pi (albedo (3,) in [0, 1]); cosine-weighted sampling (exact)."""

    def __init__(self, albedo):
        self.albedo = np.broadcast_to(np.asarray(albedo, dtype=np.float64), (3,)).copy()

    def evaluate_local(self, wi, wo):
        above = (wi[..., 2] > 0) & (wo[..., 2] > 0)
        return np.where(above[..., None], self.albedo * INV_PI, 0.0)

    def sample_local(self, wo, u):
        wi = sample_cosine(u)
        return wi, wi[..., 2] * INV_PI

    def pdf_local(self, wi, wo):
        return np.maximum(wi[..., 2], 0.0) * INV_PI


class GGX(HalfVectorMixture):
    """Lambert diffuse + GGX microfacet specular (Walter et al. 2007):
        rho = diffuse/pi + F D G / (4 cos_i cos_o),
    D = GGX with roughness alpha, G = separable Smith, F = Schlick from `specular` (F0, (3,)), or
    F = `specular` itself with fresnel=False (then it equals tests/synthetic.py's ggx_lambert).
    Sampling: a mixture of cosine and D(h) cos(theta_h) half vectors (exact pdf), mixed by the
    diffuse and specular luminances.
    """

    def __init__(self, alpha, specular=(1.0, 1.0, 1.0), diffuse=(0.0, 0.0, 0.0), fresnel=True):
        self.alpha = float(alpha)
        self.fresnel = bool(fresnel)
        self.specular = np.broadcast_to(np.asarray(specular, dtype=np.float64), (3,)).copy()
        self.diffuse = np.broadcast_to(np.asarray(diffuse, dtype=np.float64), (3,)).copy()
        ld, ls = luminance(self.diffuse), luminance(self.specular)
        self.cosine_fraction = ld / (ld + ls) if ld + ls > 0 else 1.0

    def evaluate_local(self, wi, wo):
        ci, co = wi[..., 2], wo[..., 2]
        above = (ci > 0) & (co > 0)
        h = half_vector(wi, wo)
        cos_d = np.clip(np.sum(wi * h, axis=-1), 0.0, 1.0)
        fresnel = (self.specular + (1.0 - self.specular) * ((1.0 - cos_d) ** 5)[..., None]
                   if self.fresnel else self.specular)
        masking = smith_g1(ci, cos_d, self.alpha) * smith_g1(co, cos_d, self.alpha)
        spec = ggx_d(h[..., 2], self.alpha) * masking / np.maximum(4 * ci * co, 1e-300)
        value = self.diffuse * INV_PI + fresnel * spec[..., None]
        return np.where(above[..., None], value, 0.0)

    def sample_half_vector(self, u):
        # D(h) cos(theta_h) sampling: tan^2 theta_h = alpha^2 u / (1 - u).
        u1 = np.minimum(u[..., 0], 1.0 - 1e-12)
        cos2 = (1.0 - u1) / (1.0 + (self.alpha ** 2 - 1.0) * u1)
        cos_t = np.sqrt(np.clip(cos2, 0.0, 1.0))
        sin_t = np.sqrt(np.maximum(0.0, 1.0 - cos2))
        phi = 2.0 * np.pi * u[..., 1]
        return np.stack([sin_t * np.cos(phi), sin_t * np.sin(phi), cos_t], axis=-1)

    def pdf_local(self, wi, wo):
        h = half_vector(wi, wo)
        cos_h = h[..., 2]
        wo_h = np.sum(wo * h, axis=-1)
        spec_pdf = np.where((wo_h > 0) & (cos_h > 0),
                            ggx_d(cos_h, self.alpha) * cos_h / np.maximum(4.0 * wo_h, 1e-300),
                            0.0)
        cos_pdf = np.maximum(wi[..., 2], 0.0) * INV_PI
        return self.cosine_fraction * cos_pdf + (1.0 - self.cosine_fraction) * spec_pdf
