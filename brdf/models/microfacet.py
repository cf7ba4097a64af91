"""Microfacet terms, written once for every model that uses them (GGX, Mitsuba's principled).

All take cosines (...) and return (...); alpha is the GGX roughness (alpha = roughness^2 in the
principled parameterisation).
"""

import numpy as np


def ggx_d(cos_h, alpha):
    """GGX normal distribution D(h) for cos theta_h (...) and roughness alpha; 0 below."""
    a2 = alpha * alpha
    c2 = cos_h * cos_h
    denom = np.pi * (c2 * (a2 - 1.0) + 1.0) ** 2
    return np.where(cos_h > 0, a2 / np.maximum(denom, 1e-300), 0.0)


def gtr1_d(cos_h, alpha):
    """Burley's GTR1 distribution (clearcoat) for cos theta_h (...) and alpha in (0, 1)."""
    a2 = alpha * alpha
    d = (a2 - 1.0) / (np.pi * np.log(a2) * (1.0 + (a2 - 1.0) * cos_h * cos_h))
    return np.where(cos_h > 0, d, 0.0)


def smith_g1(cos_v, cos_vh, alpha):
    """Smith GGX masking for a direction with cos theta_v (...) and v.h (...); 0 when v sees
    the back of the microfacet."""
    c2 = np.maximum(cos_v * cos_v, 1e-300)
    tan2 = np.maximum(1.0 - c2, 0.0) / c2
    g = 2.0 / (1.0 + np.sqrt(1.0 + alpha * alpha * tan2))
    return np.where(cos_vh * cos_v > 0, g, 0.0)


def schlick_weight(cos_theta):
    """(1 - cos)^5 with cos clamped to [0, 1]; (...)."""
    m = np.clip(1.0 - cos_theta, 0.0, 1.0)
    return (m * m) * (m * m) * m


def fresnel_dielectric(cos_theta_i, eta):
    """Unpolarised Fresnel reflectance of a dielectric interface, light arriving from outside
    (cos_theta_i >= 0) with relative IOR eta >= 1; (...)."""
    cos_i = np.clip(cos_theta_i, 0.0, 1.0)
    sin_t2 = (1.0 - cos_i * cos_i) / (eta * eta)
    cos_t = np.sqrt(np.maximum(1.0 - sin_t2, 0.0))
    r_s = (cos_i - eta * cos_t) / np.maximum(cos_i + eta * cos_t, 1e-300)
    r_p = (eta * cos_i - cos_t) / np.maximum(eta * cos_i + cos_t, 1e-300)
    return 0.5 * (r_s * r_s + r_p * r_p)
