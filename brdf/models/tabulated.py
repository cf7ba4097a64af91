"""A measured BRDF: a MERL-layout table, looked up at the nearest bin (or interpolated), with
importance sampling of its theta_h marginal. The interface is brdf.models.base's.
"""

import numpy as np

from flashbrdf.brdf.angles import check_finite, half_diff_from_local, merl_flat_index_local
from flashbrdf.brdf.lookup import evaluate_table
from flashbrdf.brdf.merl import N_THETA_H, theta_h_bin_coordinate, theta_h_from_bin_coordinate
from flashbrdf.brdf.models.base import INV_PI, LUMINANCE_RGB, HalfVectorMixture, half_vector


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
        lum = table @ LUMINANCE_RGB
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
            check_finite(wi, wo)
            value = self._flat[merl_flat_index_local(wi, wo, self.three_d)]
        return np.where(above[..., None], value, 0.0)

    def _h_bin(self, cos_h):
        theta_h = np.arccos(np.clip(cos_h, -1.0, 1.0))
        return np.clip(np.floor(theta_h_bin_coordinate(theta_h)).astype(np.int64), 0, N_THETA_H - 1)

    def sample_half_vector(self, u):
        u1 = np.clip(u[..., 0], 0.0, np.nextafter(1.0, 0))
        i = np.clip(np.searchsorted(self._h_cdf, u1, side="right") - 1, 0, 89)
        lo, hi = self._h_cdf[i], self._h_cdf[i + 1]
        f = np.clip((u1 - lo) / np.maximum(hi - lo, 1e-300), 0.0, 1.0)
        cos_t = self._cos_edges[i] + f * (self._cos_edges[i + 1] - self._cos_edges[i])
        sin_t = np.sqrt(np.maximum(0.0, 1.0 - cos_t ** 2))
        phi = 2.0 * np.pi * u[..., 1]
        return np.stack([sin_t * np.cos(phi), sin_t * np.sin(phi), cos_t], axis=-1)

    def pdf_local(self, wi, wo):
        h = half_vector(wi, wo)
        wo_h = np.sum(wo * h, axis=-1)
        density = self._h_density[self._h_bin(h[..., 2])]
        h_pdf = np.where((wo_h > 0) & (h[..., 2] > 0), density / np.maximum(4.0 * wo_h, 1e-300), 0.0)
        cos_pdf = np.maximum(wi[..., 2], 0.0) * INV_PI
        return self.cosine_fraction * cos_pdf + (1.0 - self.cosine_fraction) * h_pdf
