"""The slice files extraction writes: slice.csv (contract) with provenance comments and its JSON
sidecar (coverage, rejections, theta_d spread, timings); per material, material_<k>.csv and
coverage.json (sparse and narrow materials flagged). All or nothing per call.
"""

import json
from pathlib import Path

import numpy as np

from flashbrdf.brdf.merl import N_THETA_H
from flashbrdf.brdf.views import LEVEL_COMMENT, slice_coverage, write_slice_csv
from flashbrdf.capture import same_view
from flashbrdf.files.atomic import write_text
from flashbrdf.files.outputs import sidecar_json
from flashbrdf.slice_extract.samples import REASONS

SPARSE_BINS = 10  # a material slice with fewer filled theta_h bins than this is flagged sparse
# a material slice whose filled bins all lie below this theta_h is flagged "narrow": it never
# sees the off-lobe level (slice_extract.segment's off-lobe body starts at 20 deg), so past its
# last bin the table is the model's extrapolation (held-out MERL/RGL (NBRDF proxy) slices cut to
# 0-19 deg: the theta_d = 0 row past 19 deg off by 1.33x, mean |ln|; benchmarks/sparse_slices.md)
NARROW_LAST_THETA_H_DEG = 20.0


def material_coverage(slices, labels):
    """{"materials": [{label, pixels, bins_filled, pixels_used, theta_h_deg_filled, sparse,
    narrow}],
    "warnings": [...]} for {k: SliceResult or None} and the label image."""
    entries, warnings = [], []
    for k, result in slices.items():
        entry = {"label": k, "slice": f"material_{k}.csv",
                 "pixels": int(np.count_nonzero(labels == k))}
        if result is None:
            entry.update(bins_filled=0, pixels_used=0, sparse=True)
            warnings.append(f"material {k}: no usable pixel (all rejected or clipped); its slice "
                            "is empty")
        else:
            cov = result.coverage
            entry.update(bins_filled=cov["bins_filled"], pixels_used=cov["pixels_used"],
                         theta_h_deg_filled=cov["theta_h_deg_filled"],
                         sparse=cov["bins_filled"] < SPARSE_BINS,
                         narrow=cov["theta_h_deg_filled"][1] < NARROW_LAST_THETA_H_DEG)
            lo, hi = cov["theta_h_deg_filled"]
            if entry["sparse"]:
                warnings.append(f"material {k}: sparse slice, {cov['bins_filled']} of 90 theta_h "
                                f"bins filled ({lo:.1f}-{hi:.1f} deg); inference treats the "
                                "rest as missing")
            elif entry["narrow"]:
                warnings.append(f"material {k}: narrow slice, theta_h {lo:.1f}-{hi:.1f} deg only "
                                "(no off-lobe bin); past it the table is the model's "
                                "extrapolation")
        entries.append(entry)
    return {"materials": entries, "warnings": warnings}


def write_material_slices(out, scene_dir, slices, options, labels):
    """DIR/material_<k>.csv per material and DIR/coverage.json; returns {k: rho (90, 3)}."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    written, rhos = [], {}
    try:
        for k, result in slices.items():
            path = out / f"material_{k}.csv"
            if result is None:
                rho, n = np.full((N_THETA_H, 3), np.nan), np.zeros(N_THETA_H, int)
                write_slice_csv(path, rho, n, comments=[f"flashbrdf extract --labels: material "
                                                        f"{k} has no usable pixel"])
            else:
                rho, n = result.rho, result.n
                cov = result.coverage
                write_slice_csv(path, rho, n, comments=[
                    f"flashbrdf extract {Path(scene_dir).resolve()} --labels: material {k}",
                    f"pixels used {cov['pixels_used']}; bins filled {cov['bins_filled']}/90",
                    f"estimator {options.estimator}; max theta_d {options.max_theta_d_deg} deg; "
                    f"min cos {options.min_cos}; silhouette {options.silhouette_px} px"])
            written.append(path)
            rhos[k] = rho
        report = material_coverage(slices, labels)
        report["per_material"] = {str(k): None if r is None else r.report
                                  for k, r in slices.items()}
        path = out / "coverage.json"
        write_text(path, json.dumps(report, indent=1) + "\n")
    except BaseException:
        for path in written:
            path.unlink(missing_ok=True)
        raise
    return rhos


def write_extraction(out, scene_dir, result, options, final_path=None):
    """Write slice.csv (with provenance comments) and the JSON sidecar beside it, both or neither.

    final_path: where slice.csv will end up, when `out` is in a staged folder (run) that is
    renamed afterwards; the sidecar records it. Default `out`.

    Returns the slice as written: rho (90, 3) in 1/sr, NaN where empty.
    """
    out = Path(out)
    cov = result.coverage
    comments = [
        f"flashbrdf extract {Path(scene_dir).resolve()}",
        f"pixels used {cov['pixels_used']}; bins filled {cov['bins_filled']}/90; theta_h observed "
        f"{cov['theta_h_deg_observed'][0]:.3f}..{cov['theta_h_deg_observed'][1]:.3f} deg",
        "rejected " + ", ".join(f"{k} {v}" for k, v in result.rejected.items()),
        f"estimator {options.estimator} (MAD k={options.outlier_k}); max theta_d "
        f"{options.max_theta_d_deg} deg; min cos {options.min_cos}; silhouette "
        f"{options.silhouette_px} px",
    ]
    if result.report.get("level"):
        comments.append(LEVEL_COMMENT + result.report["level"]["note"])
    clamped = result.report.get("clamped_negative_bins", 0)
    if clamped:
        comments.append(f"{clamped} bin(s) had a slightly negative estimate (noise around 0) and "
                        "are written as 0")
    rho = result.rho
    report = dict(result.report, slice_csv=str(Path(final_path or out).resolve()),
                  spread=[[None if not np.isfinite(v) else float(v) for v in row]
                          for row in result.spread])
    json_path = Path(sidecar_json(out))  # --out x.json: keep the slice, x.report.json beside it
    text = json.dumps(report, indent=1) + "\n"
    write_slice_csv(out, rho, result.n, comments=comments)
    try:
        write_text(json_path, text)
    except BaseException:
        out.unlink(missing_ok=True)  # never leave half of the output behind
        raise
    return rho


def extraction_report(scene, options, per_photo, theta_h, theta_d, inlier, n, timings, bin_clipped,
                      censored):
    """SLICE.json's body: what was observed, rejected (by reason), the theta_d spread of the
    inliers, the options, every photo's record and the timings (s)."""
    total_pixels = sum(p.camera.width * p.camera.height for p in scene.photos_with_role("flash"))
    rejected = {"unusable": total_pixels - sum(p["usable"] + p["clipped"] for p in per_photo),
                "clipped": sum(p["clipped"] for p in per_photo),
                "miss": sum(p["usable"] - p["on_surface"] for p in per_photo)}
    rejected.update({k: sum(p[k] for p in per_photo) for k in REASONS})
    rejected["outlier"] = int(np.count_nonzero(~inlier & ~censored))
    used = theta_h[inlier]
    filled = slice_coverage(n > 0)
    coverage = {
        "theta_h_deg_observed": [float(np.degrees(used.min())), float(np.degrees(used.max()))],
        **{k: filled[k] for k in ("bins_filled", "first_bin", "last_bin", "theta_h_deg_filled",
                                  "empty_bins")},
        "clipped_per_bin": {int(i): int(bin_clipped[i]) for i in np.flatnonzero(bin_clipped)},
        "pixels_total": int(total_pixels), "pixels_used": int(inlier.sum()),
    }
    return {"scene": str(scene.json_path),
            "options": {k: getattr(options, k) for k in ("max_theta_d_deg", "min_cos",
                                                         "silhouette_px", "outlier_k",
                                                         "estimator", "refine_poses")},
            "coverage": coverage, "rejected": {k: int(v) for k, v in rejected.items()},
            "warnings": theta_d_warnings(rejected, int(inlier.sum()), options.max_theta_d_deg)
            + exposure_series_warnings(scene.photos_with_role("flash"), per_photo),
            "theta_d_deg": _stats_deg(theta_d[inlier]), "photos": per_photo,
            "n": [int(v) for v in n], "timings_s": {k: round(v, 4) for k, v in timings.items()}}


def exposure_series_warnings(flashes, per_photo):
    """A warning line per flash photo whose clipped pixels hold no value (+inf, a float image's
    way to mark them) and that shares its view and light with a flash photo of another `scale`
    (an exposure series given as separate photos). A clipped pixel's value is a lower bound, set
    aside where another photo measured its bin above it; without a value it counts as brighter
    than every measured sample of its bin and can void the bins the short photo measured.
    `brackets` merge such a series per pixel first."""
    out = []
    for photo, record in zip(flashes, per_photo):
        if not record.get("clipped_unbounded"):
            continue
        other = next((q for q in flashes if q is not photo and q.scale != photo.scale
                      and same_view(q.camera, photo.camera) and _same_flash(q.light, photo.light)),
                     None)
        if other is not None:
            out.append(f"photos[{photo.index}] clips {record['clipped_unbounded']} pixels stored "
                       f"without a value (+inf) and photos[{other.index}] is the same view and "
                       "flash at another scale: give an exposure series as one photo's "
                       "`brackets` (merged per pixel), or store the clip level, not +inf; as "
                       "it is, those pixels outrank the measured ones in their θh bins")
    return out


def _same_flash(a, b):
    """Whether two photos' lights sit at one place (point: position; directional: direction)."""
    if a.type != b.type:
        return False
    where = "position" if a.type == "point" else "direction"
    return bool(np.array_equal(getattr(a, where), getattr(b, where)))


THETA_D_WARN_SHARE = 0.5  # the flash's own sample lost more pixels than it kept


# A flash photo whose pixels read under half or over twice the slice the photos pool is not lit
# as scene.json says: a photo without flash (SfM run on every photo, ambient shots imported as
# flash photos: the peak bins read 0.52x), or an exposure whose `scale` is not given.
PHOTO_LEVEL_RANGE = (0.5, 2.0)
_LEVEL_SAMPLES = 200_000


def photo_levels(per_photo, bins, rho, censored, photo, estimate):
    """({photo index: its level}, [a warning] naming the flash photos whose level is off the
    pooled slice): a photo's level is the median over its unclipped samples (up to
    _LEVEL_SAMPLES of the pooled, evenly spaced) of their channel mean over their bin's. bins
    (N,) θh bin, rho (N, 3) 1/sr, censored (N,), photo (N,) index into per_photo (records with
    "photo", the name), estimate (90, 3) the slice. Photos with under 20 such samples have none."""
    level = np.asarray(estimate, float).mean(axis=1)                          # (90,), NaN empty
    pick = slice(None, None, max(1, len(bins) // _LEVEL_SAMPLES))
    with np.errstate(divide="ignore", invalid="ignore"):    # black and empty bins: no ratio
        ratio = rho[pick].mean(axis=1) / np.where(level > 0, level, np.nan)[bins[pick]]
    ok = ~censored[pick] & np.isfinite(ratio)
    ratio, photo = ratio[ok], photo[pick][ok]
    levels, off = {}, []
    for k, record in enumerate(per_photo):
        mine = ratio[photo == k]
        if len(mine) < 20:
            continue
        levels[k] = value = float(np.median(mine))
        if not PHOTO_LEVEL_RANGE[0] <= value <= PHOTO_LEVEL_RANGE[1]:
            off.append(f"{record['photo']} ({value:.2g}x)")
    if not off:
        return levels, []
    return levels, [f"{len(off)} of {len(per_photo)} flash photos read under half or over twice "
                    f"the slice the photos pool: {', '.join(off[:5])}"
                    f"{', ...' if len(off) > 5 else ''}; a photo without flash, or an exposure "
                    "whose scale is not given? Leave it out or give its scale: it pulls the "
                    "slice's bins"]


def theta_d_warnings(rejected, used, max_theta_d_deg):
    """[a warning] when most of the object's pixels seen lit fell past max_theta_d_deg: the
    flash sits far from the lens for the distance shot from (θd ≈ half the angle between them,
    seen from the object), and the slice rests on a few pixels, or none."""
    past = int(rejected.get("theta_d", 0))
    # the pixels that reached the θd test: those it passed were used or rejected after it
    reached = past + used + int(rejected.get("shadowed", 0)) + int(rejected.get("outlier", 0))
    if past == 0 or past <= THETA_D_WARN_SHARE * reached:
        return []
    return [f"{100 * past / reached:.0f}% of the object's pixels lie past θd "
            f"{max_theta_d_deg:g}° (the flash is far from the lens for this distance): shoot "
            "from further away or with the flash nearer the lens (docs/capture.md)"]


def _stats_deg(values):
    if len(values) == 0:
        return None
    d = np.degrees(values)
    return {"min": float(d.min()), "median": float(np.median(d)), "mean": float(d.mean()),
            "p95": float(np.percentile(d, 95)), "max": float(d.max())}
