"""Mitsuba 3's `principled` BSDF as a vectorised numpy BRDF, and its tabulation in the MERL layout.

This follows Mitsuba 3's principled.cpp / principledhelpers.h (Burley 2012/2015) for reflection
only (spec_trans = 0, flatness = 0, anisotropic = 0), so a table made here is what Mitsuba renders:
- diffuse: (1 - metallic) base_color / pi (f_diff + f_retro), with Schlick weights
  F_i, F_o of cos theta_i, cos theta_o, f_diff = (1 - F_i/2)(1 - F_o/2),
  R_r = 2 roughness cos^2 theta_d, f_retro = R_r (F_o + F_i + F_o F_i (R_r - 1));
- sheen: sheen (1 - metallic) F_d lerp(1, base_color / lum, sheen_tint), F_d the Schlick weight
  of cos theta_d (Mitsuba has no 1/pi here, and neither do we);
- main specular: F D G / (4 cos_i cos_o), GGX with alpha = max(0.001, roughness^2) and separable
  Smith G; F = (1 - m)(1 - spec_tint) F_dielectric(eta) + m Schlick(base_color)
  + (1 - m) spec_tint Schlick(base_color / lum * R0(eta)), eta = 2 / (1 - sqrt(0.08 specular)) - 1;
  Mitsuba evaluates this lobe only where F_dielectric > 0: at specular below 1.1e-14 (eta = 1
  in float32) it is gone, metallic part included;
- clearcoat: 0.25 clearcoat Schlick(0.04) D_GTR1(lerp(0.1, 0.001, clearcoat_gloss)) G_cc with
  Smith GGX alpha 0.25 (Mitsuba's lobe has no 1/(4 cos cos) either).
Mitsuba's eval returns f cos theta_o; the values here are f itself, in 1/sr. lum is Mitsuba's RGB
luminance (0.212671, 0.715160, 0.072169).

Parameters are a dict in Mitsuba's names (PARAMETER_NAMES); base_color is RGB (3,), the rest
are floats in [0, 1].
"""

import numpy as np

from flashbrdf.brdf.merl import merl_valid_mask, phi_d_centres, theta_d_centres, theta_h_centres
from flashbrdf.brdf.models.microfacet import (fresnel_dielectric, ggx_d, gtr1_d, schlick_weight,
                                              smith_g1)

PARAMETER_NAMES = ("base_color", "roughness", "metallic", "specular", "spec_tint", "sheen",
                   "sheen_tint", "clearcoat", "clearcoat_gloss")
DEFAULTS = {"base_color": (0.5, 0.5, 0.5), "roughness": 0.5, "metallic": 0.0, "specular": 0.5,
            "spec_tint": 0.0, "sheen": 0.0, "sheen_tint": 0.0, "clearcoat": 0.0,
            "clearcoat_gloss": 0.0}
MITSUBA_LUMINANCE = np.array([0.212671, 0.715160, 0.072169])
CLEARCOAT_G_ALPHA = 0.25
MIN_ALPHA = 0.001


def full_parameters(params):
    """`params` completed with Mitsuba's defaults; base_color as a (3,) float array."""
    unknown = set(params) - set(PARAMETER_NAMES)
    if unknown:
        raise ValueError(f"unknown principled parameter(s): {sorted(unknown)}")
    out = {**DEFAULTS, **params}
    out["base_color"] = np.broadcast_to(np.asarray(out["base_color"], dtype=np.float64), (3,))
    for name in PARAMETER_NAMES[1:]:
        out[name] = float(out[name])
    return out


def eta_from_specular(specular):
    """Mitsuba's relative IOR for a `specular` value: 2 / (1 - sqrt(0.08 specular)) - 1."""
    return 2.0 / (1.0 - np.sqrt(0.08 * specular)) - 1.0


def principled_brdf_angles(cos_i, cos_o, cos_h, cos_d, params):
    """Principled BRDF (..., 3) in 1/sr from the four cosines of a reflection configuration.

    cos_i, cos_o: of the two directions to the normal; cos_h: of the half vector to the normal;
    cos_d: of either direction to the half vector (all (...), broadcastable). 0 below the horizon.
    """
    p = full_parameters(params)
    base, rough, metal = p["base_color"], p["roughness"], p["metallic"]
    cos_i, cos_o, cos_h, cos_d = np.broadcast_arrays(cos_i, cos_o, cos_h, cos_d)
    above = (cos_i > 0) & (cos_o > 0)
    ci = np.where(above, cos_i, 1.0)
    co = np.where(above, cos_o, 1.0)
    lum = float(base @ MITSUBA_LUMINANCE)
    tint = base / lum if lum > 0 else np.ones(3)
    eta = eta_from_specular(p["specular"])

    # Diffuse and retro-reflection.
    f_i, f_o = schlick_weight(ci), schlick_weight(co)
    f_diff = (1.0 - 0.5 * f_i) * (1.0 - 0.5 * f_o)
    r_r = 2.0 * rough * cos_d * cos_d
    f_retro = r_r * (f_o + f_i + f_o * f_i * (r_r - 1.0))
    value = ((1.0 - metal) / np.pi * (f_diff + f_retro))[..., None] * base
    f_d = schlick_weight(cos_d)
    if p["sheen"] > 0:
        c_sheen = 1.0 + p["sheen_tint"] * (tint - 1.0)
        value = value + (p["sheen"] * (1.0 - metal) * f_d)[..., None] * c_sheen

    # Main specular lobe. Mitsuba evaluates it only where its dielectric Fresnel term is positive,
    # so at eta = 1 (specular below 1.1e-14, in float32) the metallic and tinted reflection go
    # too; the port does the same, or a fit there would not be what Mitsuba renders.
    if not main_lobe_exists(p["specular"]):
        return _with_clearcoat(value, p, ci, co, cos_h, cos_d, f_d, above)
    alpha = max(MIN_ALPHA, rough * rough)
    g = smith_g1(ci, cos_d, alpha) * smith_g1(co, cos_d, alpha)
    spec = ggx_d(cos_h, alpha) * g / (4.0 * ci * co)
    f_diel = fresnel_dielectric(cos_d, eta)
    r0 = ((eta - 1.0) / (eta + 1.0)) ** 2
    w = f_d[..., None]
    fresnel = ((1.0 - metal) * (1.0 - p["spec_tint"]) * f_diel)[..., None] \
        + metal * (base + (1.0 - base) * w) \
        + (1.0 - metal) * p["spec_tint"] * (tint * r0 + (1.0 - tint * r0) * w)
    value = value + fresnel * spec[..., None]
    return _with_clearcoat(value, p, ci, co, cos_h, cos_d, f_d, above)


def main_lobe_exists(specular):
    """Whether Mitsuba's main specular lobe is there: its eta, computed in float32 as Mitsuba
    computes it, above 1."""
    s = np.float32(specular)
    eta = np.float32(2.0) / (np.float32(1.0) - np.sqrt(np.float32(0.08) * s)) - np.float32(1.0)
    return bool(eta > np.float32(1.0))


def clearcoat_alpha(clearcoat_gloss):
    """Mitsuba's GTR1 alpha of the clearcoat: lerp(0.1, 0.001, clearcoat_gloss)."""
    return 0.1 + (0.001 - 0.1) * clearcoat_gloss


def _with_clearcoat(value, p, ci, co, cos_h, cos_d, f_d, above):
    """value plus the clearcoat lobe, zero below the horizon."""
    if p["clearcoat"] > 0:
        f_cc = 0.04 + 0.96 * f_d
        g_cc = smith_g1(ci, cos_d, CLEARCOAT_G_ALPHA) * smith_g1(co, cos_d, CLEARCOAT_G_ALPHA)
        value = value + (0.25 * p["clearcoat"] * f_cc * gtr1_d(cos_h, clearcoat_alpha(
            p["clearcoat_gloss"])) * g_cc)[..., None]
    return np.where(above[..., None], value, 0.0)


def principled_brdf_local(wi, wo, params):
    """Principled BRDF (..., 3) in 1/sr of local-frame unit directions wi, wo (..., 3), normal +z."""
    wi, wo = np.broadcast_arrays(np.asarray(wi, dtype=np.float64), np.asarray(wo, dtype=np.float64))
    h = wi + wo
    h = h / np.maximum(np.linalg.norm(h, axis=-1, keepdims=True), 1e-300)
    cos_d = np.einsum("...k,...k->...", wi, h)
    return principled_brdf_angles(wi[..., 2], wo[..., 2], h[..., 2], cos_d, params)


def bin_cosines(theta_h, theta_d, phi_d):
    """(cos_i, cos_o, cos_h, cos_d) of Rusinkiewicz angles in radians (broadcastable arrays).

    With h tilted by theta_h about y and d = (sin td cos pd, sin td sin pd, cos td) in the half
    frame: cos_i,o = cos td cos th -/+ sin td cos pd sin th (the pair is symmetric about h).
    """
    theta_h, theta_d, phi_d = np.broadcast_arrays(theta_h, theta_d, phi_d)
    along = np.sin(theta_d) * np.cos(phi_d) * np.sin(theta_h)
    base = np.cos(theta_d) * np.cos(theta_h)
    return base - along, base + along, np.cos(theta_h), np.cos(theta_d)


def merl_bin_cosines(flat_index=None):
    """bin_cosines at MERL bin centres: all valid bins' or the given flat indices' (n,) arrays."""
    if flat_index is None:
        flat_index = np.flatnonzero(merl_valid_mask())
    i, rest = np.divmod(np.asarray(flat_index), 90 * 180)
    j, k = np.divmod(rest, 180)
    return bin_cosines(theta_h_centres()[i], theta_d_centres()[j], phi_d_centres()[k])


def tabulate_principled(params):
    """The principled BRDF at every MERL bin centre: (90, 90, 180, 3) in 1/sr, NaN where MERL
    has no data. Takes about a second (1.1 M valid bins)."""
    valid = merl_valid_mask()
    table = np.full(valid.shape + (3,), np.nan)
    table[valid] = principled_brdf_angles(*merl_bin_cosines(), params)
    return table
