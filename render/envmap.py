"""Lat-long environment maps: radiance lookup and luminance importance sampling.

Convention (contract, INTERFACES.md "Envmaps"): a W x H map (W = 2H); pixel (row i, column j)
holds the radiance arriving from the envmap-frame direction
    d = (sin phi sin theta, cos theta, -cos phi sin theta),
    theta = pi (i + 0.5) / H,  phi = 2 pi (j + 0.5) / W - pi,
i.e. u = 0.5 + atan2(d.x, -d.z) / 2pi, v = arccos(d.y) / pi. A world direction w reads the map at
d = world_from_envmap^T w, times `scale`; bilinear between pixel centres, wrapping in u.

The sampler is a 2D piecewise-constant distribution over pixels (rows by their marginal, then
columns within the row), weighted by luminance times the pixel's exact solid angle (the sin theta
weighting, integrated over the pixel's row); within a pixel the direction is uniform in solid
angle, so the solid-angle pdf is constant over a pixel: pdf = P(pixel) / Omega(pixel).

With `compensate` (default) the luminance is replaced by max(0, luminance - mean luminance), MIS
compensation (Karlik et al. 2019): the BRDF strategy already covers the map's constant part, so
the envmap strategy only spends samples on what is brighter than average. A map with nothing above
its mean (a constant map) then has no envmap strategy at all (`can_sample` is False) and the
integrator uses BRDF sampling alone, which is unbiased because the BRDF samplers cover the whole
hemisphere where rho cos > 0.
"""

import os

import numpy as np

from flashbrdf.files.errors import InputError

# Rec. 709 / linear sRGB luminance weights.
LUMINANCE_RGB = np.array([0.2126, 0.7152, 0.0722])
# Table 2's maps when no --envmap names one. Nothing may be read from outside the project unless
# a flag names the file, and no third-party data is shipped, so the defaults are made here, in
# code: an outdoor sky with a sun, and a studio with two soft boxes. The paper's pisa, grace and
# uffizi (USC ICT, research use only) stay in ../shared: pass them with --envmap.
DEFAULT_ENVMAPS = ("sky", "studio")
DEFAULT_ENVMAP_HEIGHT = 128  # the USC probes' size: Table 2 renders stay as fast
ENVMAP_RINGING = 0.01  # negative values down to 1% of the brightest are filter ringing, clamped


def envmap_directions(height):
    """(H, 2H, 3) unit envmap-frame directions of the pixel centres of an H-row lat-long map."""
    theta = np.pi * (np.arange(height) + 0.5) / height
    phi = 2.0 * np.pi * (np.arange(2 * height) + 0.5) / (2 * height) - np.pi
    st, ct = np.sin(theta)[:, None], np.cos(theta)[:, None]
    return np.stack(np.broadcast_arrays(np.sin(phi)[None] * st, ct, -np.cos(phi)[None] * st), -1)


def _cap(d, elevation_deg, azimuth_deg, radius_deg):
    """(H, W) bool: pixel directions d within radius_deg of the direction at that elevation above
    the horizon and azimuth (phi, the map's own angle)."""
    el, az = np.radians(elevation_deg), np.radians(azimuth_deg)
    centre = np.array([np.sin(az) * np.cos(el), np.sin(el), -np.cos(az) * np.cos(el)])
    return d @ centre >= np.cos(np.radians(radius_deg))


def procedural_envmap(name, height=DEFAULT_ENVMAP_HEIGHT):
    """(height, 2 height, 3) linear RGB radiance of a default map, in the map's convention above.

    "sky": blue at the zenith, white at the horizon, a grey-brown ground, and a 3° sun 35° up
    holding about 60% of the light a horizontal surface receives (a hot spot like a probe's sun,
    which the importance sampler must find). "studio": a dark room with a large key box 45° up
    and a dimmer fill box opposite, with hard edges (a highlight's shape shows in the render)."""
    d = envmap_directions(height)
    up = d[..., 1]
    if name == "sky":
        horizon = np.clip(1.0 - up, 0.0, 1.0)[..., None] ** 2
        pixels = np.where((up >= 0)[..., None],
                          0.8 * ((1 - horizon) * np.array([0.35, 0.55, 1.0]) + horizon),
                          np.array([0.25, 0.22, 0.18]))
        pixels[_cap(d, 35.0, 40.0, 3.0)] = np.array([1.0, 0.95, 0.85]) * 500.0
    elif name == "studio":
        pixels = np.where((up >= 0)[..., None], 0.05, 0.1) * np.ones(3)
        pixels[_cap(d, 45.0, -50.0, 15.0)] = 6.0
        pixels[_cap(d, 20.0, 140.0, 12.0)] = np.array([1.2, 1.3, 1.5])
    else:
        raise ValueError(f"no default envmap {name!r}: one of {', '.join(DEFAULT_ENVMAPS)}")
    return pixels


def default_envmaps(height=DEFAULT_ENVMAP_HEIGHT):
    """{name: (height, 2 height, 3) radiance}: Table 2's default maps (procedural_envmap)."""
    return {name: procedural_envmap(name, height) for name in DEFAULT_ENVMAPS}


def read_envmap_pixels(path):
    """Read a lat-long map -> (H, W, 3) float32 linear RGB. InputError if unreadable or not 2:1."""
    # capture (cv2, Embree, OpenImageIO) adds 0.2-0.8 s to `import render` (python -X importtime,
    # 2 loaded cores) for commands that never read a picture (export, infer); so it loads here
    from flashbrdf.capture import read_float_image
    path = os.fspath(path)
    pixels = read_float_image(path)
    height, width = pixels.shape[:2]
    if height < 2:
        raise InputError(path, f"environment map needs at least 2 rows, got {height}")
    if width != 2 * height:
        raise InputError(path, f"environment map must be lat-long with width = 2 x height, "
                               f"got {width}x{height}")
    if not np.all(np.isfinite(pixels)):
        raise InputError(path, "environment map holds non-finite values")
    # Radiance is >= 0. Resampling filters leave small negative ringing beside bright pixels,
    # clamped to 0 here; a negative value beyond 1% of the map's brightest is no such artefact
    # (a map of negatives would render black), so it is refused.
    floor = -ENVMAP_RINGING * max(float(pixels.max()), 0.0)
    if pixels.min() < floor:
        count = int(np.count_nonzero(np.any(pixels < floor, axis=-1)))
        raise InputError(path, f"environment map holds negative radiance ({count} pixels, down to "
                               f"{float(pixels.min()):.3g}; the brightest is "
                               f"{max(float(pixels.max()), 0.0):.3g})")
    return np.maximum(pixels, 0.0)


def envmap_direction(i, j, height, width):
    """Envmap-frame unit direction (..., 3) for (fractional) row i, column j (pixel centres at .5
    offsets are i, j integers + 0.5 here: pass i + 0.5 for a centre)."""
    theta = np.pi * np.asarray(i, dtype=np.float64) / height
    phi = 2.0 * np.pi * np.asarray(j, dtype=np.float64) / width - np.pi
    st = np.sin(theta)
    return np.stack([np.sin(phi) * st, np.cos(theta), -np.cos(phi) * st], axis=-1)


def envmap_uv(d):
    """(u, v) in [0,1] for envmap-frame directions d (..., 3) (contract formula)."""
    u = 0.5 + np.arctan2(d[..., 0], -d[..., 2]) / (2.0 * np.pi)
    v = np.arccos(np.minimum(np.maximum(d[..., 1], -1.0), 1.0)) / np.pi
    return u, v


def _bilinear_patch_max(lum):
    """(H, W) max of the bilinear radiance over each pixel's footprint.

    Bilinear interpolation between pixel centres spreads a hot pixel into its neighbours'
    footprints; weighting the sampler by the footprint's maximum (attained at its centre, edge
    midpoints or corners) keeps L / pdf bounded there and so avoids fireflies next to a sun.
    """
    padded = np.pad(lum, ((1, 1), (0, 0)), mode="edge")                      # clamp in v
    padded = np.concatenate([padded[:, -1:], padded, padded[:, :1]], axis=1)  # wrap in u
    h, w = lum.shape

    def shifted(di, dj):
        return padded[1 + di:1 + di + h, 1 + dj:1 + dj + w]

    best = lum.copy()
    for di, dj in ((-1, 0), (1, 0), (0, -1), (0, 1)):                 # edge midpoints
        best = np.maximum(best, 0.5 * (lum + shifted(di, dj)))
    for di, dj in ((-1, -1), (-1, 1), (1, -1), (1, 1)):               # corners
        best = np.maximum(best, 0.25 * (lum + shifted(di, 0) + shifted(0, dj) + shifted(di, dj)))
    return best


class EnvMap:
    """A lat-long environment light with a luminance importance sampler.

    pixels: (H, W, 3) radiance (W/sr/m^2 or photo units), H x 2H.
    world_from_envmap: (3, 3) rotation; scale: float multiplier.
    """

    def __init__(self, pixels, world_from_envmap=None, scale=1.0, compensate=True):
        pixels = np.asarray(pixels, dtype=np.float64)
        if pixels.ndim != 3 or pixels.shape[2] != 3 or pixels.shape[1] != 2 * pixels.shape[0]:
            raise ValueError(f"envmap pixels must be (H, 2H, 3), got {pixels.shape}")
        if not np.all(np.isfinite(pixels)):
            raise ValueError("envmap pixels hold non-finite values")
        if not (np.isfinite(scale) and scale >= 0):  # a negative scale renders negative light
            raise ValueError(f"envmap scale must be a finite number >= 0, got {scale}")
        # small negatives are a resampling filter's ringing (read_envmap_pixels refuses more)
        self.pixels = np.maximum(pixels, 0.0) * float(scale)
        self.height, self.width = pixels.shape[:2]
        rot = np.eye(3) if world_from_envmap is None else np.asarray(world_from_envmap, float)
        self.world_from_envmap = rot
        self.compensate = bool(compensate)
        self._identity = bool(np.array_equal(rot, np.eye(3)))
        if self.height < 2:
            raise ValueError("envmap needs at least 2 rows")
        # Flat (H * (W + 2), 3) copy with one wrapped column on each side for bilinear lookups.
        wrapped = np.concatenate([self.pixels[:, -1:], self.pixels, self.pixels[:, :1]], axis=1)
        self._padded = np.ascontiguousarray(wrapped.reshape(-1, 3))
        self._build_sampler()

    @classmethod
    def from_file(cls, path, world_from_envmap=None, scale=1.0, compensate=True):
        return cls(read_envmap_pixels(path), world_from_envmap, scale, compensate)

    # -- radiance ---------------------------------------------------------------------------
    def radiance(self, world_dirs):
        """L(w) (..., 3) for unit world directions (..., 3): bilinear between pixel centres."""
        d = self._to_envmap(world_dirs)
        u, v = envmap_uv(d)
        h, w = self.height, self.width
        x = u * w + 0.5                      # column coordinate in the wrap-padded map
        y = np.minimum(np.maximum(v * h - 0.5, 0.0), h - 1.0)  # clamp at the poles
        x0 = np.minimum(np.maximum(np.floor(x), 0.0), w)
        y0 = np.minimum(np.floor(y), h - 2.0)
        fx = (x - x0)[..., None]
        fy = (y - y0)[..., None]
        flat = y0.astype(np.intp) * (w + 2) + x0.astype(np.intp)
        p = self._padded
        top = np.take(p, flat, axis=0)
        top += (np.take(p, flat + 1, axis=0) - top) * fx
        bottom = np.take(p, flat + (w + 2), axis=0)
        bottom += (np.take(p, flat + (w + 3), axis=0) - bottom) * fx
        return top + (bottom - top) * fy

    def _to_envmap(self, world_dirs):
        d = np.asarray(world_dirs, dtype=np.float64)
        return d if self._identity else d @ self.world_from_envmap  # = R^T w

    # -- importance sampling ----------------------------------------------------------------
    def _build_sampler(self):
        h, w = self.height, self.width
        edges = np.cos(np.pi * np.arange(h + 1) / h)          # cos theta at row edges
        self._row_solid_angle = (edges[:-1] - edges[1:]) * (2.0 * np.pi / w)  # per pixel, (H,)
        self._cos_edges = edges
        lum = _bilinear_patch_max(self.pixels @ LUMINANCE_RGB)
        if self.compensate:
            mean = (lum * self._row_solid_angle[:, None]).sum() / (4.0 * np.pi)
            # Relative slack so a constant map does not sample its rounding noise.
            lum = np.maximum(lum - mean * (1.0 + 1e-6), 0.0)
        weight = lum * self._row_solid_angle[:, None]
        total = weight.sum()
        self.can_sample = bool(total > 0)
        if not total > 0:
            # An all-black map: sample uniformly so the pdf stays a valid density.
            weight = np.broadcast_to(self._row_solid_angle[:, None], (h, w)).copy()
            total = weight.sum()
        self._pixel_prob = weight / total                      # (H, W), sums to 1
        row_prob = self._pixel_prob.sum(axis=1)
        self._row_cdf = np.concatenate([[0.0], np.cumsum(row_prob)])
        self._row_cdf /= self._row_cdf[-1]
        col = np.cumsum(self._pixel_prob, axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            col = col / col[:, -1:]
        col[~np.isfinite(col)] = (np.arange(1, w + 1) / w)[None].repeat(h, 0)[~np.isfinite(col)]
        self._col_cdf = np.concatenate([np.zeros((h, 1)), col], axis=1)  # (H, W+1)
        self._col_cdf_flat = self._col_cdf.ravel()
        self._col_edges_flat = (np.arange(h)[:, None] + self._col_cdf[:, 1:]).ravel()
        self._pdf_table = (self._pixel_prob / self._row_solid_angle[:, None]).ravel()  # 1/sr

    def sample(self, u):
        """Directions by luminance. u: (..., 2) uniforms in [0,1).

        Returns world directions (..., 3) and their solid-angle pdf (...). The fractional parts
        of u inside the chosen row/column are reused, so stratified u stay stratified.
        """
        u = np.asarray(u, dtype=np.float64)
        top = np.nextafter(1.0, 0)
        u1 = np.minimum(np.maximum(u[..., 0], 0.0), top)
        u2 = np.minimum(np.maximum(u[..., 1], 0.0), top)
        row = np.minimum(np.searchsorted(self._row_cdf, u1, side="right") - 1, self.height - 1)
        row = np.maximum(row, 0)
        lo, hi = self._row_cdf[row], self._row_cdf[row + 1]
        fy = np.minimum(np.maximum((u1 - lo) / np.maximum(hi - lo, 1e-300), 0.0), 1.0)
        # Column within the row: one searchsorted over all rows, row r's CDF shifted by r.
        idx = np.searchsorted(self._col_edges_flat, row + u2, side="right")
        col = np.maximum(np.minimum(idx - row * self.width, self.width - 1), 0)
        flat = row * (self.width + 1) + col
        clo = np.take(self._col_cdf_flat, flat)
        chi = np.take(self._col_cdf_flat, flat + 1)
        fx = np.minimum(np.maximum((u2 - clo) / np.maximum(chi - clo, 1e-300), 0.0), 1.0)
        # Uniform in solid angle within the pixel: cos theta linear, phi linear.
        cos_t = self._cos_edges[row] + fy * (self._cos_edges[row + 1] - self._cos_edges[row])
        sin_t = np.sqrt(np.maximum(0.0, 1.0 - cos_t ** 2))
        phi = 2.0 * np.pi * (col + fx) / self.width - np.pi
        d = np.stack([np.sin(phi) * sin_t, cos_t, -np.cos(phi) * sin_t], axis=-1)
        pdf = np.take(self._pdf_table, row * self.width + col)
        return (d if self._identity else d @ self.world_from_envmap.T), pdf

    def pdf(self, world_dirs):
        """Solid-angle pdf (...) of `sample` for unit world directions (..., 3)."""
        u, v = envmap_uv(self._to_envmap(world_dirs))
        col = np.minimum(np.maximum(u * self.width, 0.0), self.width - 1.0).astype(np.intp)
        row = np.minimum(np.maximum(v * self.height, 0.0), self.height - 1.0).astype(np.intp)
        return np.take(self._pdf_table, row * self.width + col)
