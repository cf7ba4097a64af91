"""The arrays report.html embeds, and how they are encoded (pure numpy; no HTML here).

Images are linear HDR in the photos' pixel units, cropped to the object and, when the page would
be too large, box-downsampled by an integer factor. They are stored as float16, scaled by a power
of two per photo (exact, so no precision is lost to the scale) so that values well above float16's
range (65504) still fit; bytes are split into a low-byte plane and a high-byte plane (the high
bytes, sign + exponent, compress well), deflated (zlib) and base64-encoded. The page inflates them
with the browser's DecompressionStream('deflate'), only when a photo is first shown.

The display maths the page runs in JavaScript is mirrored here (expose_to_srgb8,
overlay_delta_e) so that the tests can check the page's pixels against it.
"""

import base64
import math
import os
import zlib
from pathlib import Path

import cv2
import numpy as np

from flashbrdf.brdf.colour import FEATURE_OFFSET
from flashbrdf.brdf.views import table_2d_view, table_in_plane, variance_2d_view
from flashbrdf.files.errors import InputError
from flashbrdf.render import images

# A page's embedded image bytes (after deflate, before base64) are kept under this: the sample
# capture needs ~1 MB; a DiLiGenT object (95 photos x 5 methods) is downsampled to fit.
IMAGE_BUDGET_BYTES = 24 * 2**20
MAX_SIDE = 1024          # longest side of an embedded image, whatever the budget
CROP_MARGIN = 0.05       # of the object's larger side, around its bounding box
DEFLATE_LEVEL = 1        # zlib: 2x faster than 6 on a DiLiGenT page's planes, 7% larger
OVERLAY_ALPHA = 0.6      # weight of the ΔE colour over the image where ΔE is defined
HALF_TOP = 2.0 ** 14     # a photo's largest value is scaled to at most this (float16 max 65504)


# ---- exposure and overlay: the page's display maths ---------------------------------------

def srgb8(linear):
    """Linear [0, 1] -> 8-bit sRGB codes (uint8), clipped; NaN -> 0. As the page's encode()."""
    x = np.clip(np.nan_to_num(np.asarray(linear, dtype=np.float64), nan=0.0), 0.0, 1.0)
    encoded = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    return np.floor(encoded * 255 + 0.5).astype(np.uint8)


def srgb8_to_linear(codes):
    """8-bit sRGB codes -> linear [0, 1] (float64), the inverse of srgb8 at code centres."""
    c = np.asarray(codes, dtype=np.float64) / 255
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def expose_to_srgb8(linear, stops):
    """What the page shows for a linear value at `stops` of exposure: linear * 2**stops, clipped
    to [0, 1], sRGB-encoded to 8 bits. One stop doubles a linear value below the clip."""
    return srgb8(np.asarray(linear, dtype=np.float64) * 2.0 ** stops)


def overlay_delta_e(codes, delta_e, vmax, lut, alpha=OVERLAY_ALPHA):
    """The page's ΔE overlay on 8-bit codes (H, W, 3): where ΔE is finite, blend the colour map
    `lut` (256, 3) uint8 at index floor(ΔE / vmax * 255) (clipped) with weight alpha; elsewhere
    the image is left as it is."""
    codes = np.asarray(codes, dtype=np.float64)
    de = np.asarray(delta_e, dtype=np.float64)
    shown = np.isfinite(de)
    index = np.clip(np.floor(np.nan_to_num(de) / vmax * 255), 0, 255).astype(int)
    blended = (1 - alpha) * codes + alpha * np.asarray(lut, dtype=np.float64)[index]
    return np.floor(np.where(shown[..., None], blended, codes) + 0.5).astype(np.uint8)


def auto_stops(reference):
    """Exposure in stops (to 0.1) that maps the 99th percentile of the lit pixels to 1, as the
    report's PNG figures do (report_figures.exposure_for); 0 for an image with no lit pixel."""
    lit = np.asarray(reference, dtype=np.float64)
    lit = lit[np.isfinite(lit) & (lit > 0)]
    if not lit.size:
        return 0.0
    return round(-math.log2(float(np.percentile(lit, 99))), 1)


def delta_e_vmax(maps):
    """The top of the ΔE colour scale: max(5, 99th percentile over all maps), as the figures."""
    finite = [m[np.isfinite(m)] for m in maps if m is not None]
    finite = np.concatenate(finite) if finite else np.zeros(0)
    return max(5.0, float(np.percentile(finite, 99))) if finite.size else 5.0


def colour_lut(name):
    """A matplotlib colour map as (256, 3) uint8 (the page's heat maps and overlay)."""
    from matplotlib import colormaps
    rgba = colormaps[name](np.linspace(0.0, 1.0, 256))
    return np.round(rgba[:, :3] * 255).astype(np.uint8)


# ---- crop and downsample ------------------------------------------------------------------

def object_box(measured, margin=CROP_MARGIN):
    """(row0, row1, col0, col1) of the True pixels of (H, W) `measured`, plus a margin of the
    box's larger side, clipped to the image; the whole image when nothing is True."""
    measured = np.asarray(measured, dtype=bool)
    h, w = measured.shape
    rows, cols = np.nonzero(measured.any(1))[0], np.nonzero(measured.any(0))[0]
    if not rows.size:
        return 0, h, 0, w
    pad = int(math.ceil(margin * max(rows[-1] - rows[0] + 1, cols[-1] - cols[0] + 1)))
    return (max(rows[0] - pad, 0), min(rows[-1] + 1 + pad, h),
            max(cols[0] - pad, 0), min(cols[-1] + 1 + pad, w))


def downsample(image, factor):
    """Box-average `factor` x `factor` blocks of an (H, W[, C]) image as float32, ignoring NaN
    (a block of NaN only stays NaN); the last partial row/column of blocks averages what it has."""
    image = np.asarray(image, dtype=np.float32)
    if factor == 1:
        return image
    h, w = image.shape[:2]
    hp, wp = -(-h // factor) * factor, -(-w // factor) * factor
    if (hp, wp) != (h, w):
        padded = np.full((hp, wp) + image.shape[2:], np.nan, dtype=np.float32)
        padded[:h, :w] = image
        image = padded
    finite = np.isfinite(image)
    values = np.where(finite, image, np.float32(0))

    def block_sums(a):  # rows then columns: two contiguous reductions, ~2x one over (1, 3)
        a = a.reshape(hp // factor, factor, wp, *a.shape[2:]).sum(axis=1, dtype=np.float32)
        return a.reshape(hp // factor, wp // factor, factor, *a.shape[2:]).sum(
            axis=2, dtype=np.float32)

    with np.errstate(invalid="ignore", divide="ignore"):
        return block_sums(values) / block_sums(finite.astype(np.float32))


def downsample_factor(pixels, sides, bytes_per_pixel, budget=IMAGE_BUDGET_BYTES, ratio=1.0,
                      max_side=MAX_SIDE):
    """The smallest integer factor f such that the images fit: the sum over photos of
    pixels / f^2 * bytes_per_pixel * ratio (ratio: the expected deflate ratio) within `budget`,
    and every side / f within max_side. pixels, sides (longest), bytes_per_pixel: per photo."""
    raw = float(np.dot(np.asarray(pixels, float), np.asarray(bytes_per_pixel, float))) * ratio
    factor = max(1, math.ceil(max(sides, default=1) / max_side))
    while raw / factor**2 > budget:
        factor += 1
    return factor


# ---- encoding -----------------------------------------------------------------------------

def power_of_two_scale(arrays):
    """2^k such that the largest finite |value| of `arrays`, divided by it, is at most HALF_TOP
    and as close as possible (1 when they hold no nonzero value). Exact in float16 and float32."""
    # finite values only: an inf pixel (a hot pixel in a merged HDR) is stored as inf, as NaN
    # is stored as NaN, and must not set the scale of the rest
    top = max((float(np.max(np.abs(a[np.isfinite(a)]))) for a in arrays
               if a is not None and np.isfinite(a).any()), default=0.0)
    if top <= 0:
        return 1.0
    return 2.0 ** math.ceil(math.log2(top / HALF_TOP))


def half_planes(array):
    """float16 bytes of `array` as a low-byte plane then a high-byte plane (bytes)."""
    halfs = np.ascontiguousarray(array, dtype="<f2").reshape(-1).view(np.uint8)
    return halfs.reshape(-1, 2).T.tobytes()


def from_half_planes(data, count):
    """The inverse of half_planes for `count` values: float32 (count,)."""
    planes = np.frombuffer(data, dtype=np.uint8, count=2 * count).reshape(2, count)
    return np.ascontiguousarray(planes.T).view("<f2").reshape(-1).astype(np.float32)


def encode_halfs(arrays, level=DEFLATE_LEVEL):
    """(base64 text, deflated byte count) of the arrays, each as half_planes, concatenated and
    deflated (zlib format, which the browser's DecompressionStream('deflate') reads)."""
    packed = zlib.compress(b"".join(half_planes(a) for a in arrays), level)
    return base64.b64encode(packed).decode("ascii"), len(packed)


def decode_halfs(text, counts):
    """The inverse of encode_halfs: [float32 (count,)] for each count (the tests use it)."""
    data = zlib.decompress(base64.b64decode(text))
    out, offset = [], 0
    for count in counts:
        out.append(from_half_planes(data[offset:offset + 2 * count], count))
        offset += 2 * count
    return out


def float32_b64(array):
    """base64 of little-endian float32 values (small arrays: BRDF tables, slices)."""
    return base64.b64encode(np.ascontiguousarray(array, dtype="<f4").tobytes()).decode("ascii")


def uint8_b64(array):
    return base64.b64encode(np.ascontiguousarray(array, dtype=np.uint8).tobytes()).decode("ascii")


# ---- BRDF tables --------------------------------------------------------------------------

def uniform_value(values):
    """The one value of a non-empty array whose values all agree (to 1e-9 relative), else None:
    an uncertainty that is one number in every bin (one isotropic GP per view) is said, not
    painted, on the page and in the figures alike."""
    values = np.asarray(values, dtype=float)
    if values.size and np.ptp(values) <= 1e-9 * max(float(np.abs(values).max()), 1e-300):
        return float(values.flat[0])
    return None


def variance_description(method):
    """{"variance_label", "interval_offset"} of a fitted method's predictive variance, for the
    report's figures and page. interval_offset: ε in 1/sr when the variance is per channel of
    ln(1 + ρ/ε) (brdf.colour's log-RGB features, the shipped model's), so that the page can show
    the central 90% interval (ρ + ε)·exp(±1.645 σ) − ε in 1/sr; None for other feature spaces
    (CIELAB mixes the channels: no per-channel interval follows from its variance)."""
    return {"variance_label": "predictive variance ("
                              + getattr(method, "feature_label", "features") + ")",
            "interval_offset": (FEATURE_OFFSET if getattr(method, "feature_space", None) == "rgb"
                                else None)}


def brdf_entry(table, variance=None, variance_label="uncertainty", variance_note=None,
               interval_offset=None):
    """One method's BRDF for the page: the 2D table (a 3D one's phi_d mean) and, for a 3D
    table, its plane of incidence (the polar plot's); its uncertainty as a map, as one number
    (every bin alike: one isotropic GP per view), or absent (variance_note: why);
    interval_offset: see variance_description."""
    entry = {"table": float32_b64(table_2d_view(table)), "variance_label": variance_label}
    if interval_offset is not None:
        entry["interval_offset"] = float(interval_offset)
    if np.ndim(table) == 4:
        entry["in_plane"] = float32_b64(table_in_plane(table))
    if variance_note:
        entry["variance_note"] = variance_note
    variance = variance_2d_view(variance)
    if variance is not None:
        values = variance[np.isfinite(variance)]
        if uniform_value(values) is not None:
            entry["variance_constant"] = uniform_value(values)
        elif values.size:
            entry["variance"] = float32_b64(np.broadcast_to(
                variance[..., None] if variance.ndim == 2 else variance, (90, 90, 3)))
    return entry


def slice_entry(rho, n, spread=None):
    """The observed flash slice for the page: rho (90, 3), n (90,), spread (90, 3) or None."""
    return {"rho": float32_b64(np.asarray(rho, dtype=np.float64).reshape(90, 3)),
            "n": [int(v) for v in np.asarray(n).reshape(-1)],
            "spread": None if spread is None else float32_b64(
                np.asarray(spread, dtype=np.float64).reshape(90, 3))}


def jsonable(value):
    """JSON-safe copy: numpy -> Python, NaN/inf -> None, paths -> str."""
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return jsonable(value.tolist())
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, (np.floating, float)):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    return value


def read_image(source):
    """An array passes through; a path is read: EXR/HDR/PFM with render.images.read_image (the
    one linear-image reader), .npy memory-mapped, else OpenCV as stored (RGB: masks, ΔE PNGs). None where it is
    missing or unreadable, where render.images.read_image raises: the report is written without it."""
    if source is None or isinstance(source, np.ndarray):
        return source
    path = Path(source)
    if path.suffix.lower() == ".npy":  # run's arrays kept for the report: read as needed
        try:
            return np.load(path, mmap_mode="r", allow_pickle=False)
        except (OSError, ValueError):
            return None
    if path.suffix.lower() in (".exr", ".hdr", ".pfm"):
        try:
            return images.read_image(path)
        except InputError:
            return None
    image = cv2.imread(os.fspath(path), cv2.IMREAD_UNCHANGED)
    if image is None:
        return None
    return image[..., 2::-1] if image.ndim == 3 else image
