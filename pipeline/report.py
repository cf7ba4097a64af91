"""OUT_DIR/report.md and OUT_DIR/report.json for `flashbrdf run` (and the benchmarks).

Built from plain inputs, so any caller can use it:
- stages: {name: seconds}, in run order.
- observed: {"rho": (90,3) 1/sr NaN where empty, "n": (90,) int, "spread": (90,3) 1/sr or None}.
- predictions: {method: {"table": (90,90,3) or (90,90,180,3) 1/sr, "variance": (90,90[,3]) or None,
  "variance_label": str, optional "interval_offset" (report_data.variance_description), "file":
  path}} (a bare table is accepted as the value too).
- references: [{"photo", "method", "delta_e_log_mean", "rel_rmse", optional "delta_e_log_median",
  "pixels", "render", "reference", "delta_e_map", "mask" (arrays or image paths), and any extra
  JSON scalars such as "light_angle_deg", or "level_ratio_rgb" (3,) (render.compare.level_ratio):
  the summary gives its median over photos and report.md a level check}]. A "compare" dict
  (compare.json) may carry the numbers.

report.json follows the contract, {"stages": {name: seconds}, "references": [{"photo", "method",
"delta_e_log_mean", "rel_rmse"}, ...]}, plus summary, slice, predictions, coverage, warnings and
figures. Every file is written atomically; NaN is written as null.
"""

import json
import os
import warnings
from pathlib import Path

import numpy as np

from flashbrdf.brdf import merl
from flashbrdf.files.atomic import write_text
from flashbrdf.brdf.merl import theta_h_centres
from flashbrdf.brdf.metrics import summarise
from flashbrdf.brdf.views import slice_coverage, table_2d_view, variance_2d_view
from flashbrdf.capture.photo import PHOTO_EXTENSIONS
from flashbrdf.brdf.metrics import delta_e_log
from flashbrdf.render.compare import compare_images, comparison_mask
from flashbrdf.pipeline import report_figures as figs
from flashbrdf.pipeline.report_data import jsonable, read_image
from flashbrdf.pipeline.report_html import write_report_html

HOW_TO_READ = """\
**How to read the numbers.**
- **ΔE log** (the paper's Table 2 metric, `delta_e_log_mean`): per pixel, take ln(1 + value) of the
  render and of the reference photo, convert both to CIELAB (as linear sRGB, D65, Y = 1) and measure
  the CIE76 colour distance ΔE*ab; then average over the object's pixels. The log makes highlights
  and shadows count alike. Roughly: below 1 the two are indistinguishable, 1-3 is a close match
  (the paper's DS-GPLVM averages 1.2-1.5 on MERL spheres under environment maps, the simpler
  baselines 2-4), 3-10 is a visible brightness or colour difference, above 10 it looks like a
  different material. Because of the log, values for dim images (pixel values << 1) are small:
  compare methods on the same scene, not across scenes.
- **rel_rmse**: the root-mean-square pixel difference divided by the RMS of the reference (0 is
  perfect, 1 means the error is as large as the signal). It is dominated by the brightest pixels,
  i.e. by the highlights.
- **level-matched ΔE log**: the same, with each method's renders multiplied by one number (the
  median over the photos of the mean over channels of reference / render). It removes one
  light-calibration or exposure offset that all the photos share, which no BRDF can predict, and
  keeps the angular shape of the BRDF: compare methods on it when the lights' calibration is in
  doubt (both are printed, the calibrated one first). The number is a ratio of sums, so it is set
  by the highlights and by all three channels at once: it is not the factor that minimises ΔE,
  and where a render's error is a colour shift (one channel off) it can raise the figure above
  the calibrated one; then the colour, not the level, is what differs.
- **reference / render** (`level_ratio_rgb`): per channel, the sum of the photo over the sum of
  the render on the compared pixels, median over the photos; 1.00 when the levels agree. Methods
  differ here where their BRDFs do; an offset they all share gets a level-check note.
- **Observed vs predicted.** A flash photo measures only the θd = 0 slice ρ(θh) of the BRDF. Every
  value at θd > 0, and every θh bin with no observed pixels, is predicted by the method from what
  it learned from the model's training tables (MERL, plus RGL for the shipped model), not measured.
- **Uncertainty panels**: the predictive variance σ² of each bin in the model's feature space,
  which the panel's label names (the shipped model: ln(1 + ρ/ε) per channel, ε = 1e-3 1/sr). A
  central 90% interval on ρ is then (ρ + ε)·exp(±1.645 σ) − ε: σ = 0.3 is about ×0.6 to ×1.6.
"""


def _fmt(x, digits=2):
    return "–" if x is None or not np.isfinite(x) else f"{x:.{digits}f}"


def image_errors(render, reference, mask=None):
    """(delta_e_map (H,W) NaN outside, delta_e_log_mean, delta_e_log_median, rel_rmse, pixels):
    render.compare.compare_images (the contract's compare rule) as a tuple, NaN for no pixel.
    mask: nonzero = object, (H, W) or (H, W, C)."""
    if mask is not None:
        mask = np.asarray(mask)
        mask = (mask.reshape(mask.shape[0], mask.shape[1], -1).max(-1) > 0)
    metrics, delta_e = compare_images(render, reference, mask)
    nan = lambda v: float("nan") if v is None else v   # noqa: E731
    return (delta_e, nan(metrics["delta_e_log_mean"]), nan(metrics["delta_e_log_median"]),
            nan(metrics["rel_rmse"]), metrics["pixels"])


def coverage(theta_h_deg, observed):
    """(coverage dict, warnings list) from the observed slice: which theta_h the flash photo saw."""
    n = np.asarray(observed["n"])
    seen = (n > 0) & np.all(np.isfinite(observed["rho"]), axis=1)
    if not seen.any():
        return {"bins_observed": 0, "samples": 0}, [
            "no θh bin was observed: the whole prediction comes from the prior"]
    filled = slice_coverage(seen)
    low, high = filled["theta_h_deg_range"]
    info = {"bins_observed": filled["bins_filled"], "samples": int(n[seen].sum()),
            "theta_h_observed_deg": [low, high]}
    warnings = []
    if filled["last_bin"] < merl.N_THETA_H - 1:
        warnings.append(f"θh above {high:.1f}° not observed: the prediction there comes "
                        "from the prior")
    if filled["first_bin"] > 0:
        warnings.append(f"θh below {low:.2g}° not observed (the specular peak): the peak "
                        "height comes from the prior")
    gaps = filled["gaps"]
    if gaps:
        warnings.append(f"{gaps} θh bins inside the observed range are empty: interpolated by the "
                        "method")
    thin = int((seen & (n < 5)).sum())
    if thin:
        warnings.append(f"{thin} observed θh bins rest on fewer than 5 pixels: noisy")
    return info, warnings


def _number(value):
    """A metric as float, NaN when missing (None: the photo had no reference to compare with)."""
    try:
        return float(value)
    except (TypeError, ValueError):
        return float("nan")


def _reference_rows(references, fig_dir, max_figures):
    """Numbers per (photo, method), and one figure per photo (up to max_figures). A row's images
    (arrays or paths) are read for its photo's figure only, one photo at a time."""
    rows, by_photo = [], {}
    for ref in references:
        row = {k: v for k, v in ref.items()
               if k not in ("render", "reference", "delta_e_map", "mask", "compare",
                             "compare_mask")}
        row.update({k: ref["compare"][k] for k in ("delta_e_log_mean", "delta_e_log_median",
                                                   "rel_rmse", "pixels")
                    if k in ref.get("compare", {}) and k not in ref})
        if "delta_e_log_mean" not in row:
            render, reference = read_image(ref.get("render")), read_image(ref.get("reference"))
            if render is not None and reference is not None:
                _, mean, median, rel, pixels = image_errors(render, reference,
                                                            read_image(ref.get("mask")))
                for key, value in (("delta_e_log_mean", mean), ("delta_e_log_median", median),
                                   ("rel_rmse", rel), ("pixels", pixels)):
                    row.setdefault(key, value)
        row["delta_e_log_mean"] = _number(row.get("delta_e_log_mean"))
        row["rel_rmse"] = _number(row.get("rel_rmse"))
        rows.append(row)
        by_photo.setdefault(row["photo"], []).append((row, ref))
    figures = {}
    for photo, members in list(by_photo.items())[:max_figures]:
        reference, renders, maps, means = None, {}, {}, {}
        for row, ref in members:
            render, photo_image = read_image(ref.get("render")), read_image(ref.get("reference"))
            reference = photo_image if photo_image is not None else reference
            de_map = ref.get("delta_e_map")
            de_map = read_image(de_map) if isinstance(de_map, (str, os.PathLike)) else de_map
            if de_map is None and render is not None and photo_image is not None:
                de_map = image_errors(render, photo_image, read_image(ref.get("mask")))[0]
            renders[row["method"]], maps[row["method"]] = render, de_map
            means[row["method"]] = row["delta_e_log_mean"]
        if reference is None and all(r is None for r in renders.values()):
            continue
        name = f"ref_{_figure_stem(photo, by_photo)}.png"
        figs.reference_figure(fig_dir / name, photo, reference, renders, maps, means)
        figures[photo] = f"figures/{name}"
    return rows, figures, len(by_photo)


def _figure_stem(photo, photos):
    """A reference photo's name for its figure: its file name without a photo extension, unless
    another of `photos` would then share it (shot.png.exr, as `run` names its stem shot.png, beside
    shot.exr); a stem as `run` gives it stays whole (ref.dir and ref.cam2 were both "ref")."""
    path = Path(str(photo))
    if path.suffix.lower() not in PHOTO_EXTENSIONS:
        return path.name
    return path.stem if sum(str(p) == path.stem or Path(str(p)).stem == path.stem
                            for p in photos) == 1 else path.name


def _summary(rows, sources=None):
    """Per method: ΔE-log and rel_rmse over its references, their level (reference / render), and
    the level-matched ΔE-log (level_matched). sources: the rows with their images, when `rows`
    are the report's copies without them."""
    out = {}
    sources = rows if sources is None else sources
    for method in dict.fromkeys(r["method"] for r in rows):
        mine = [r for r in rows if r["method"] == method]
        out[method] = {key: summarise([r[key] for r in mine])
                       for key in ("delta_e_log_mean", "rel_rmse")}
        # the references compared: a reference photo missing on disk is rendered, not scored
        out[method]["references"] = sum(bool(np.isfinite(r["delta_e_log_mean"])) for r in mine)
        levels = [r["level_ratio_rgb"] for r in mine if r.get("level_ratio_rgb") is not None]
        if levels:
            with warnings.catch_warnings():     # an all-NaN channel stays NaN
                warnings.simplefilter("ignore", RuntimeWarning)
                out[method]["level_ratio_rgb"] = np.nanmedian(np.asarray(levels, float),
                                                              axis=0).tolist()
            matched = level_matched([r for r in sources if r["method"] == method], levels)
            if matched is not None:
                out[method]["level_matched"] = matched
    return out


def level_matched(rows, levels):
    """{"scale", "delta_e_log_mean": {mean, median, ...}}: ΔE-log of one method's renders each
    multiplied by one number, the median over its references of the mean over channels of
    reference / render (level_ratio_rgb), over the pixels each comparison used. It removes one
    light-calibration (or exposure) offset that the photos share and keeps the BRDF's angular
    shape. None without the images or a finite scale."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        scale = float(np.nanmedian(np.nanmean(np.asarray(levels, float), axis=1)))
    if not np.isfinite(scale) or scale <= 0:
        return None
    errors = []
    for r in rows:
        render, reference = read_image(r.get("render")), read_image(r.get("reference"))
        if render is None or reference is None or r.get("delta_e_log_mean") is None:
            continue
        mask = r.get("compare_mask")
        used = comparison_mask(render, reference, read_image(mask) if mask is not None
                               else None)
        if used.any():
            # mask first, then float64: no float64 copy of whole images per photo
            errors.append(float(np.mean(delta_e_log(
                np.asarray(render)[used].astype(float) * scale,
                np.asarray(reference)[used].astype(float)))))
    if not errors:
        return None
    return {"scale": scale, "delta_e_log_mean": summarise(errors)}


LEVEL_NOTE = 0.03     # |reference / render − 1| beyond which a shared level offset is pointed out


def level_note(summary):
    """One line when every method's renders are darker (or brighter) than the reference photos
    by more than LEVEL_NOTE in every channel (summary: _summary's dict; entries without a level,
    such as an export's fit of a method's own table, do not count), else None.

    The level is render.compare.level_ratio per photo (sum of photo / sum of render over the
    compared pixels), then its median over the photos. A BRDF error moves each method its own
    way; what none of them models moves them all alike: an exposure `scale` or a light intensity
    that differs between the flash photo and the references (the DiLiGenT ball: 1.04–1.07 for
    every method, the flash light's calibration against the others), shadows and
    interreflections the geometry does not give, or a material darker away from the flash than
    any method expects (DiLiGenT pot2, a rough clay, reads 0.89–0.96; which of these it is, the
    check cannot tell). 3% is well above what photo or render noise do to a ratio of sums over
    thousands of pixels (the sample capture's noll level moved ≤ 0.01 from its default spp to 4
    spp), and a uniform 3% level error is ~0.1 of ΔE-log.
    """
    levels = np.asarray([s.get("level_ratio_rgb") or [None] * 3 for s in summary.values()],
                        dtype=float)
    levels = levels[np.isfinite(levels).any(axis=1)]    # no level at all: not a method here
    if not len(levels) or not np.isfinite(levels).all():    # a channel unknown: say nothing
        return None
    for sign, word in ((1, "brighter"), (-1, "darker")):
        if (sign * (levels - 1) > LEVEL_NOTE).all():
            low, high = (f"{100 * v:.0f}" for v in (abs(levels - 1).min(), abs(levels - 1).max()))
            span = low if low == high else f"{low}–{high}"
            seen = (f"**Level check:** the reference photos are {span}% "
                    f"{word} than {{}}, in every channel (sum of photo / sum of render over the "
                    "compared pixels, median over the photos). ")
            causes = ("an exposure `scale` or a light intensity calibrated differently from the "
                      "flash photo's, shadows or interreflections the geometry does not give (a "
                      "normal map casts no shadow), or a material that changes away from the "
                      "flash direction more than a method expects (a rough material's "
                      "back-scatter).")
            if len(levels) == 1:
                return (seen.format("the renders") + "Either this method's BRDF is off, or "
                        + causes + " A second method (`--methods dsgplvm,chandraker`) tells "
                        "the two apart: what none of them models moves them all alike.")
            return (seen.format("every method's renders") + "Every method starts from the same "
                    "flash slice, so an offset they share is something none of them predicts: "
                    + causes)
    return None


def write_report(out_dir, *, stages, references=(), observed=None, predictions=None, warnings=(),
                 title="flashbrdf report", notes=(), max_reference_figures=24, x_key=None,
                 x_label=None, extra=None, sections=(), materials=None):
    """Write OUT_DIR/report.md, OUT_DIR/report.json and OUT_DIR/figures/*.png; return the JSON dict.

    extra: more JSON fields for report.json (e.g. "materials"); sections: markdown lines put
    after the notes and warnings (figures they name must already be in OUT_DIR); materials:
    each material's slice and predictions for report.html (pipeline.report_html)."""
    out_dir = Path(out_dir)
    fig_dir = out_dir / "figures"
    fig_dir.mkdir(parents=True, exist_ok=True)
    theta_h_deg = np.degrees(theta_h_centres())
    predictions = {m: (p if isinstance(p, dict) else {"table": p})
                   for m, p in (predictions or {}).items()}
    # each prediction as the figures and the page show it: the 2D table and its 2D variance
    variance_means = {m: (float(np.nanmean(p["variance"])) if p.get("variance") is not None
                          and np.isfinite(p["variance"]).any() else None)
                      for m, p in predictions.items()}
    predictions = {m: {**p, "table": table_2d_view(p["table"]),
                       "variance": variance_2d_view(p.get("variance"))}
                   for m, p in predictions.items()}
    tables = {m: p["table"] for m, p in predictions.items()}
    figures, warnings = {}, list(warnings)
    cover = None
    if observed is not None:
        observed = {k: (None if v is None else np.asarray(v, float)) for k, v in observed.items()}
        cover, auto = coverage(theta_h_deg, observed)
        warnings = auto + [w for w in warnings if w not in auto]
    if observed is not None or tables:
        figs.slice_plot(fig_dir / "slice.png", theta_h_deg, observed,
                        {m: t[:, 0, :] for m, t in tables.items()})
        figures["slice"] = "figures/slice.png"
    for method, p in predictions.items():
        figs.brdf_images(fig_dir / f"brdf_{method}.png", method, tables[method],
                         p["variance"], p.get("variance_label", "uncertainty"))
        figures[f"brdf_{method}"] = f"figures/brdf_{method}.png"
    rows, ref_figures, n_photos = _reference_rows(references, fig_dir, max_reference_figures)
    if rows:
        x_key = x_key if x_key and all(x_key in r for r in rows) else None
        figs.error_plot(fig_dir / "errors.png", rows, x_key, x_label or x_key or "reference photo")
        figures["errors"] = "figures/errors.png"
    report = jsonable({
        "title": title,
        "stages": {k: float(v) for k, v in stages.items()},
        "references": rows,
        "summary": _summary(rows, references),
        "slice": None if observed is None else {
            "theta_h_deg": theta_h_deg, "rho": observed["rho"], "n": observed["n"],
            "spread": observed.get("spread")},
        "predictions": {m: {"theta_d0": tables[m][:, 0, :], "file": p.get("file"),
                            "variance_mean": variance_means[m]}
                        for m, p in predictions.items()},
        "coverage": cover, "warnings": warnings, "notes": list(notes),
        "figures": {**figures, "references": ref_figures},
        "total_seconds": float(sum(stages.values())),
        **(extra or {}),
    })
    write_text(out_dir / "report.json", json.dumps(report, indent=1) + "\n")
    write_text(out_dir / "report.md", _markdown(report, n_photos, sections))
    write_report_html(out_dir, report, references, observed, predictions, materials=materials,
                      how_to_read=HOW_TO_READ,
                      level_note=level_note(report["summary"]) if report["summary"] else None)
    return report


def _markdown(report, n_photos, sections=()):
    lines = [f"# {report['title']}", ""]
    summary = report["summary"]
    if summary:
        lines += ["## Summary", "", "| method | references | ΔE log mean (mean / median over "
                  "references) | ΔE log level-matched (mean / median; scale) | rel_rmse (mean / "
                  "median) | reference / render (R, G, B) |", "|---|---|---|---|---|---|"]
        for method, s in summary.items():
            level = s.get("level_ratio_rgb")
            level = "–" if level is None else ", ".join(_fmt(v) for v in level)
            matched = s.get("level_matched")
            matched = "–" if matched is None else (
                f"{_fmt(matched['delta_e_log_mean']['mean'])} / "
                f"{_fmt(matched['delta_e_log_mean']['median'])}; ×{_fmt(matched['scale'], 3)}")
            lines.append(f"| {method} | {s['references']} | {_fmt(s['delta_e_log_mean']['mean'])} / "
                         f"{_fmt(s['delta_e_log_mean']['median'])} | {matched} | "
                         f"{_fmt(s['rel_rmse']['mean'], 3)} / {_fmt(s['rel_rmse']['median'], 3)}"
                         f" | {level} |")
        lines.append("")
        note = level_note(summary)
        if note:
            lines += [note, ""]
    lines += [HOW_TO_READ]
    for note in report["notes"]:
        lines += [note, ""]
    if report["warnings"]:
        lines += ["## Coverage warnings", ""] + [f"- {w}" for w in report["warnings"]] + [""]
    lines += list(sections)
    figures = report["figures"]
    if "slice" in figures:
        cover = report["coverage"]
        lines += ["## The observed slice and the predictions at θd = 0", ""]
        if cover and cover.get("bins_observed"):
            lo, hi = cover["theta_h_observed_deg"]
            lines += [f"The flash photo filled {cover['bins_observed']} of 90 θh bins "
                      f"({cover['samples']} pixels), the bins from θh {lo:.2g}° to {hi:.1f}° (bin "
                      "edges). Dots are the "
                      "observed bins (bars: spread), lines each method's prediction.", ""]
        lines += [f"![slice]({figures['slice']})", ""]
    brdf_figs = [k for k in figures if k.startswith("brdf_")]
    if brdf_figs:
        lines += ["## Predicted BRDFs (θh × θd, per channel)", "",
                  "log10 ρ with θd across and θh down (square-root bin scale); only the θd = 0 "
                  "column was measured. Where the method has one, its uncertainty is beside it.", ""]
        lines += [f"![{k}]({figures[k]})" for k in brdf_figs] + [""]
    if report["references"]:
        lines += ["## Renders against reference photos", "", f"![errors]({figures['errors']})", "",
                  "| photo | method | ΔE log mean | ΔE log median | rel_rmse | pixels |",
                  "|---|---|---|---|---|---|"]
        for r in report["references"]:
            lines.append(f"| {r['photo']} | {r['method']} | {_fmt(r.get('delta_e_log_mean'))} | "
                         f"{_fmt(r.get('delta_e_log_median'))} | {_fmt(r.get('rel_rmse'), 3)} | "
                         f"{r.get('pixels', '–')} |")
        lines.append("")
        shown = figures["references"]
        if shown:
            lines += ["Each row: the reference photo, then per method its render (same exposure) "
                      "and the per-pixel ΔE log map.", ""]
            lines += [f"![{photo}]({path})" for photo, path in shown.items()] + [""]
        if len(shown) < n_photos:
            lines += [f"({n_photos - len(shown)} more references are in report.json only.)", ""]
    lines += ["## Stage timings", "", "| stage | seconds |", "|---|---|"]
    lines += [f"| {k} | {v:.2f} |" for k, v in report["stages"].items()]
    lines += [f"| **total** | **{report['total_seconds']:.2f}** |", ""]
    return "\n".join(lines)
