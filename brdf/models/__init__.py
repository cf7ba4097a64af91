"""BRDF models, in one home: each answers evaluate / sample / pdf (brdf.models.base).

- base: BRDFModel (the interface, local frame and world frame), HalfVectorMixture, sample_cosine
- microfacet: GGX D, Smith G1, GTR1, Schlick and dielectric Fresnel, written once
- analytic: Lambert, GGX (Lambert + GGX specular)
- tabulated: TabulatedBRDF, a MERL-layout table (nearest bin or interpolated)
- principled: Mitsuba 3's `principled` BSDF (reflection) and its MERL tabulation; principled_fit
  fits its parameters to a table (`flashbrdf export`)
"""

from flashbrdf.brdf.models.analytic import GGX, Lambert
from flashbrdf.brdf.models.base import BRDFModel, HalfVectorMixture, sample_cosine
from flashbrdf.brdf.models.tabulated import TabulatedBRDF

__all__ = ["BRDFModel", "GGX", "HalfVectorMixture", "Lambert", "TabulatedBRDF", "sample_cosine"]
