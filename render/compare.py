"""Image comparison: per-pixel log-CIELAB Delta E*ab (Table 2's metric) and relative RMSE.

Measured over a mask, or, without one, over the pixels where both images are finite and nonzero
(contract, `compare`):
    delta_e_log = Delta E*ab(Lab(ln(1 + pred)), Lab(ln(1 + ref)))   per pixel (brdf.metrics)
    rel_rmse    = sqrt(sum (pred - ref)^2 / sum ref^2)              over the pixels and channels
"""

import gc
import json
import os

import numpy as np

from flashbrdf.files.atomic import atomic_path, write_text
from flashbrdf.brdf.metrics import delta_e_log

COMPARE_JSON = "compare.json"
DELTA_E_PNG = "delta_e.png"


COMPARE_CHUNK = 1 << 20   # pixels per block of the ΔE computation
_FONTS_PARSED = []        # non-empty once the first ΔE figure has been drawn and collected


def comparison_mask(pred, ref, mask=None):
    """(H, W) bool of the pixels compared: mask (if given) and both finite; without a mask,
    also both nonzero (any channel)."""
    finite = np.all(np.isfinite(pred), axis=-1) & np.all(np.isfinite(ref), axis=-1)
    if mask is not None:
        return np.asarray(mask, dtype=bool) & finite
    return finite & np.any(pred != 0, axis=-1) & np.any(ref != 0, axis=-1)


def compare_images(pred, ref, mask=None):
    """Compare two (H, W, 3) linear images.

    Returns (metrics, delta_e): metrics = {"delta_e_log_mean", "delta_e_log_median",
    "rel_rmse", "pixels"} (None for the means when no pixel qualifies) and delta_e (H, W)
    with NaN outside the compared pixels.
    """
    # float64 only for the compared pixels: whole-image float64 copies were 1.15 GB at 24 MP
    pred = np.asarray(pred)
    ref = np.asarray(ref)
    if pred.shape != ref.shape:
        raise ValueError(f"image shapes differ: {pred.shape} vs {ref.shape}")
    used = comparison_mask(pred, ref, mask)
    delta_e = np.full(used.shape, np.nan)
    count = int(used.sum())
    if count == 0:
        return ({"delta_e_log_mean": None, "delta_e_log_median": None, "rel_rmse": None,
                 "pixels": 0}, delta_e)
    p, r = pred[used].astype(np.float64), ref[used].astype(np.float64)
    # per pixel, so in blocks: the CIELAB conversion's temporaries over every compared pixel at
    # once were ~0.6 GB at 24 MP
    values = np.empty(count)
    for start in range(0, count, COMPARE_CHUNK):
        block = slice(start, start + COMPARE_CHUNK)
        values[block] = delta_e_log(p[block], r[block])
    delta_e[used] = values
    ref_energy = float(np.sum(r * r))
    rel_rmse = float(np.sqrt(np.sum((p - r) ** 2) / ref_energy)) if ref_energy > 0 else None
    return ({"delta_e_log_mean": float(np.mean(values)),
             "delta_e_log_median": float(np.median(values)),
             "rel_rmse": rel_rmse,
             "pixels": count}, delta_e)


def level_ratio(pred, ref, mask=None):
    """(3,) per channel, sum(ref) / sum(pred) over the compared pixels (comparison_mask); NaN
    where the render sums to 0 there. pred, ref: (H, W, 3) linear; mask: (H, W) or None.

    A ratio of sums, not a median of per-pixel ratios: a Monte Carlo render's per-pixel noise is
    skewed, and the median of ref / pred read 1.04 at 8 spp for the true BRDF, where the sums
    stay unbiased. What the level tells: pipeline.report.level_note.
    """
    pred, ref = np.asarray(pred), np.asarray(ref)
    used = comparison_mask(pred, ref, None if mask is None else np.asarray(mask, dtype=bool))
    # sums in float64 of the compared pixels only: no float64 copy of whole images per photo
    total_pred = pred[used].sum(axis=0, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(total_pred > 0, ref[used].sum(axis=0, dtype=np.float64) / total_pred,
                        np.nan)


def write_delta_e_png(path, delta_e, title="log-CIELAB ΔE*ab", vmax=None):
    """False-colour Delta E map with a colour bar, cropped to the compared pixels (plus a
    4-pixel margin); NaN (not compared) pixels are grey."""
    # matplotlib.pyplot costs 1.2 s to import (python -X importtime): only this figure needs it
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    rows, cols = np.nonzero(np.isfinite(delta_e))
    if rows.size:   # crop to the compared pixels (an object often fills a small part)
        margin = 4
        delta_e = delta_e[max(rows.min() - margin, 0):rows.max() + margin + 1,
                          max(cols.min() - margin, 0):cols.max() + margin + 1]
    finite = delta_e[np.isfinite(delta_e)]
    if vmax is None:
        vmax = float(np.percentile(finite, 99)) if finite.size else 1.0
    vmax = max(vmax, 1e-6)
    h, w = delta_e.shape
    fig, ax = plt.subplots(figsize=(5.5, 5.5 * h / max(w, 1) * 0.9 + 0.6), dpi=100)
    cmap = matplotlib.colormaps["inferno"].with_extremes(bad=(0.5, 0.5, 0.5))
    im = ax.imshow(np.ma.masked_invalid(delta_e), cmap=cmap, vmin=0.0, vmax=vmax,
                   interpolation="nearest")
    ax.set_axis_off()
    ax.set_title(title)
    fig.colorbar(im, ax=ax, fraction=0.046, pad=0.04, label="ΔE*ab")
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", bbox_inches="tight")
    plt.close(fig)
    if not _FONTS_PARSED:
        # matplotlib's first figure parses its font patterns with pyparsing, whose caught
        # exceptions keep their tracebacks, and through them this call's frames and the callers'
        # (the render, the full-size delta_e map, the masks: ~0.6 GB a photo at 24 MP), in a
        # reference cycle: collected once here. Later figures make none (plain-text labels: a
        # mathtext label makes such a cycle at every figure).
        gc.collect()
        _FONTS_PARSED.append(True)


def write_comparison(out_dir, pred, ref, mask=None, json_name=COMPARE_JSON,
                     png_name=DELTA_E_PNG, return_map=False):
    """Compare and write OUT_DIR/compare.json (+ the Delta E PNG). Returns the metrics dict, or
    (metrics, delta_e (H, W)) with `return_map`."""
    metrics, delta_e = compare_images(pred, ref, mask)
    os.makedirs(out_dir, exist_ok=True)
    if png_name:
        write_delta_e_png(os.path.join(out_dir, png_name), delta_e)
    write_text(os.path.join(out_dir, json_name), json.dumps(metrics, indent=2) + "\n")
    return (metrics, delta_e) if return_map else metrics
