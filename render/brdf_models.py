"""BRDFs behind one interface: evaluation and importance sampling.

Every model works in the local shading frame (normal = +z; isotropic, so no tangent is needed):
    evaluate_local(wi, wo) -> (..., 3) in 1/sr, 0 where wi or wo is below the horizon
    sample_local(wo, u)    -> wi (..., 3), pdf (...) solid-angle density (wi may come back below
                              the horizon: the caller's f = 0 discards it, the pdf stays valid)
    pdf_local(wi, wo)      -> (...) the solid-angle density of sample_local
and, for convenience, in world space: evaluate(wi, wo, normal) -> (..., 3).
wi points toward the light, wo toward the viewer; all vectors are unit (..., 3).
"""

import numpy as np

from flashbrdf.brdf.angles import half_diff_from_local, merl_flat_index_local
from flashbrdf.brdf.frame import Frame
from flashbrdf.brdf.lookup import evaluate_table
from flashbrdf.brdf.merl import N_THETA_H, theta_h_bin_coordinate, theta_h_from_bin_coordinate

INV_PI = 1.0 / np.pi


def sample_cosine(u):
    """Cosine-weighted hemisphere directions (..., 3) for u (..., 2); pdf = cos / pi."""
    r = np.sqrt(u[..., 0])
    phi = 2.0 * np.pi * u[..., 1]
    z = np.sqrt(np.maximum(0.0, 1.0 - u[..., 0]))
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=-1)


def _reflect(wo, h):
    return 2.0 * np.sum(wo * h, axis=-1, keepdims=True) * h - wo


def _half_vector(wi, wo):
    h = wi + wo
    return h / np.maximum(np.linalg.norm(h, axis=-1, keepdims=True), 1e-300)


def _luminance(rgb):
    return float(np.dot(np.asarray(rgb, float), [0.2126, 0.7152, 0.0722]))


class BRDFModel:
    """Base class: the world-space wrapper around the local-frame interface."""

    def evaluate(self, wi, wo, normal):
        frame = Frame.from_normal(normal)
        return self.evaluate_local(frame.to_local(wi), frame.to_local(wo))


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


class HalfVectorMixture(BRDFModel):
    """Sampling shared by GGX and tabulated BRDFs: a cosine-weighted direction with probability
    `cosine_fraction`, else omega_o reflected about a half vector from the subclass's
    `_sample_h(u)`; `pdf_local` is the subclass's mixture density."""

    cosine_fraction = 0.25

    def sample_local(self, wo, u):
        c = self.cosine_fraction
        use_cos = u[..., 0] < c
        # Reuse the component-selecting uniform so stratification survives.
        u_cos = np.stack([np.where(use_cos, u[..., 0] / max(c, 1e-300), 0.0), u[..., 1]], -1)
        u_h = np.stack([np.where(use_cos, 0.0, (u[..., 0] - c) / max(1.0 - c, 1e-300)),
                        u[..., 1]], -1)
        wo_b = np.broadcast_to(wo, np.broadcast_shapes(wo.shape, u.shape[:-1] + (3,)))
        wi = np.where(use_cos[..., None], sample_cosine(u_cos), _reflect(wo_b, self._sample_h(u_h)))
        return wi, self.pdf_local(wi, wo_b)


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
        ld, ls = _luminance(self.diffuse), _luminance(self.specular)
        self.cosine_fraction = ld / (ld + ls) if ld + ls > 0 else 1.0

    def _d(self, cos_h):
        a2 = self.alpha ** 2
        c2 = cos_h ** 2
        return np.where(cos_h > 0, a2 / (np.pi * (c2 * (a2 - 1.0) + 1.0) ** 2), 0.0)

    def _g1(self, cos_t):
        a2 = self.alpha ** 2
        c2 = np.maximum(cos_t ** 2, 1e-300)
        return 2.0 / (1.0 + np.sqrt(1.0 + a2 * (1.0 - c2) / c2))

    def evaluate_local(self, wi, wo):
        ci, co = wi[..., 2], wo[..., 2]
        above = (ci > 0) & (co > 0)
        h = _half_vector(wi, wo)
        cos_d = np.clip(np.sum(wi * h, axis=-1), 0.0, 1.0)
        fresnel = (self.specular + (1.0 - self.specular) * ((1.0 - cos_d) ** 5)[..., None]
                   if self.fresnel else self.specular)
        spec = self._d(h[..., 2]) * self._g1(ci) * self._g1(co) / np.maximum(4 * ci * co, 1e-300)
        value = self.diffuse * INV_PI + fresnel * spec[..., None]
        return np.where(above[..., None], value, 0.0)

    def _sample_h(self, u):
        # D(h) cos(theta_h) sampling: tan^2 theta_h = alpha^2 u / (1 - u).
        u1 = np.minimum(u[..., 0], 1.0 - 1e-12)
        cos2 = (1.0 - u1) / (1.0 + (self.alpha ** 2 - 1.0) * u1)
        cos_t = np.sqrt(np.clip(cos2, 0.0, 1.0))
        sin_t = np.sqrt(np.maximum(0.0, 1.0 - cos2))
        phi = 2.0 * np.pi * u[..., 1]
        return np.stack([sin_t * np.cos(phi), sin_t * np.sin(phi), cos_t], axis=-1)

    def pdf_local(self, wi, wo):
        h = _half_vector(wi, wo)
        cos_h = h[..., 2]
        wo_h = np.sum(wo * h, axis=-1)
        spec_pdf = np.where((wo_h > 0) & (cos_h > 0),
                            self._d(cos_h) * cos_h / np.maximum(4.0 * wo_h, 1e-300), 0.0)
        cos_pdf = np.maximum(wi[..., 2], 0.0) * INV_PI
        return self.cosine_fraction * cos_pdf + (1.0 - self.cosine_fraction) * spec_pdf


def _theta_h_edges():
    """MERL theta_h bin edges (91,) in radians: (pi/2) (i/90)^2."""
    return theta_h_from_bin_coordinate(np.arange(N_THETA_H + 1))


class TabulatedBRDF(HalfVectorMixture):
    """A MERL-layout table, 3D (90, 90, 180, 3) or 2D (90, 90, 3), in 1/sr.

    Negative, NaN or no-data bins evaluate to 0 (with `interpolate`, brdf.lookup renormalises
    over valid neighbours). Sampling mixes cosine-weighted directions (fraction
    `cosine_fraction`) with half vectors drawn from the table's theta_h marginal: a piecewise-
    constant density over the 90 theta_h bins (uniform in solid angle within a bin, uniform in
    phi_h), proportional to the bin's mean luminance over valid (theta_d, phi_d); wi is wo
    reflected about h, pdf(wi) = p(h) / (4 wo.h). With `split_diffuse` (the Mitsuba plugin's
    choice) the marginal's floor over theta_h is taken as a diffuse body: the half vectors follow
    the rest, and cosine_fraction is the body's share of the albedo.
    """

    def __init__(self, table, interpolate=False, cosine_fraction=0.25, split_diffuse=False):
        table = np.asarray(table, dtype=np.float64)
        if table.shape not in ((90, 90, 180, 3), (90, 90, 3)):
            raise ValueError(f"table must be (90,90,180,3) or (90,90,3), got {table.shape}")
        table = np.where(np.isfinite(table) & (table >= 0), table, np.nan)
        self.three_d = table.ndim == 4
        self.interpolate = bool(interpolate)
        # Only interpolation needs the NaN-marked table (brdf.lookup renormalises over data).
        self.table = table if self.interpolate else None
        # Nearest-bin fast path: a flat (bins, 3) copy with no-data as 0 (same indexing as
        # brdf.angles.merl_bin_index, checked against brdf.lookup.evaluate_table in the tests).
        self._flat = (None if self.interpolate else
                      np.ascontiguousarray(np.nan_to_num(table, nan=0.0).reshape(-1, 3)))
        self.cosine_fraction = float(cosine_fraction)
        lum = table @ np.array([0.2126, 0.7152, 0.0722])
        axes = tuple(range(1, lum.ndim))
        with np.errstate(invalid="ignore"):
            valid = np.isfinite(lum)
            count = valid.sum(axis=axes)
            marginal = np.where(valid, lum, 0.0).sum(axis=axes) / np.maximum(count, 1)
        edges = _theta_h_edges()
        self._cos_edges = np.cos(edges)
        bin_solid_angle = 2.0 * np.pi * (self._cos_edges[:-1] - self._cos_edges[1:])
        marginal = np.maximum(marginal, 0.0)
        if split_diffuse:
            with np.errstate(invalid="ignore"):
                row = lum[:, 0].reshape(90, -1)
                flash = np.where(np.isfinite(row), row, 0.0).sum(axis=1) \
                    / np.maximum(np.isfinite(row).sum(axis=1), 1)
            marginal = self._split_diffuse(marginal, count > 0, flash, bin_solid_angle)
        weight = marginal * bin_solid_angle
        if not weight.sum() > 0:
            self.cosine_fraction = 1.0
            weight = bin_solid_angle.copy()
        prob = weight / weight.sum()
        self._h_cdf = np.concatenate([[0.0], np.cumsum(prob)])
        self._h_cdf /= self._h_cdf[-1]
        self._h_density = prob / bin_solid_angle             # solid-angle density of h per bin

    def _split_diffuse(self, marginal, has_data, flash, bin_solid_angle):
        """The marginal less its floor over theta_h (a diffuse body), with cosine_fraction set to
        the body's share of the albedo at normal incidence, from the theta_d = 0 row `flash`
        (90,): pi floor against the lobe's sum over bins of (flash - floor) * solid angle *
        4 cos theta_h * cos 2 theta_h (dw_o = 4 (w.h) dw_h). The marginal over theta_d would
        overstate the lobe (grazing Fresnel and 1/cos). Kept within [0.1, 0.9]."""
        floor = float(np.min(marginal[has_data])) if has_data.any() else 0.0
        lobe = np.maximum(marginal - floor, 0.0)
        flash_floor = float(np.min(flash[has_data])) if has_data.any() else 0.0
        centres = 0.5 * (np.arccos(self._cos_edges[:-1]) + np.arccos(self._cos_edges[1:]))
        lobe_albedo = float(np.sum(np.maximum(flash - flash_floor, 0.0) * bin_solid_angle * 4
                                   * np.cos(centres) * np.maximum(np.cos(2 * centres), 0.0)))
        floor = flash_floor
        total = np.pi * floor + lobe_albedo
        if total > 0:
            self.cosine_fraction = float(np.clip(np.pi * floor / total, 0.1, 0.9))
        return lobe

    def half_vector_distribution(self):
        """The sampler's parameters, for other renderers that sample this table the same way:
        (bin probabilities (90,), cos theta_h bin edges (91,), solid-angle density of h per bin
        (90,), cosine_fraction)."""
        return np.diff(self._h_cdf), self._cos_edges.copy(), self._h_density.copy(), \
            self.cosine_fraction

    def evaluate_local(self, wi, wo):
        wi, wo = np.broadcast_arrays(wi, wo)
        above = (wi[..., 2] > 0) & (wo[..., 2] > 0)
        if self.interpolate:
            theta_h, theta_d, phi_d = half_diff_from_local(wi, wo)
            value = evaluate_table(self.table, theta_h, theta_d, phi_d, interpolate=True)
            value = np.where(np.isfinite(value) & (value > 0), value, 0.0)
        else:
            value = self._flat[merl_flat_index_local(wi, wo, self.three_d)]
        return np.where(above[..., None], value, 0.0)

    def _h_bin(self, cos_h):
        theta_h = np.arccos(np.clip(cos_h, -1.0, 1.0))
        return np.clip(np.floor(theta_h_bin_coordinate(theta_h)).astype(np.int64), 0, N_THETA_H - 1)

    def _sample_h(self, u):
        u1 = np.clip(u[..., 0], 0.0, np.nextafter(1.0, 0))
        i = np.clip(np.searchsorted(self._h_cdf, u1, side="right") - 1, 0, 89)
        lo, hi = self._h_cdf[i], self._h_cdf[i + 1]
        f = np.clip((u1 - lo) / np.maximum(hi - lo, 1e-300), 0.0, 1.0)
        cos_t = self._cos_edges[i] + f * (self._cos_edges[i + 1] - self._cos_edges[i])
        sin_t = np.sqrt(np.maximum(0.0, 1.0 - cos_t ** 2))
        phi = 2.0 * np.pi * u[..., 1]
        return np.stack([sin_t * np.cos(phi), sin_t * np.sin(phi), cos_t], axis=-1)

    def pdf_local(self, wi, wo):
        h = _half_vector(wi, wo)
        wo_h = np.sum(wo * h, axis=-1)
        density = self._h_density[self._h_bin(h[..., 2])]
        h_pdf = np.where((wo_h > 0) & (h[..., 2] > 0), density / np.maximum(4.0 * wo_h, 1e-300), 0.0)
        cos_pdf = np.maximum(wi[..., 2], 0.0) * INV_PI
        return self.cosine_fraction * cos_pdf + (1.0 - self.cosine_fraction) * h_pdf
