"""OUT_DIR/report.html: one self-contained page to look at a `run` (no server, no network).

The page (pipeline/report_page/: report.html, report.css and the .js parts, inlined in order)
shows the summary table of report.md, each reference photo with every method's render (flip,
split, ΔE overlay, one exposure control over the linear data, linear values on hover), the BRDFs
(heat maps with uncertainty, the observed slice, the lobe in the plane of incidence, the
Principled fit of `run --export`) and, with several materials, the label image and each
material's slice and share.

write_report_html takes values (pipeline/report.py:write_report calls it last), the label image
and each material's slice and tables included; only the Principled fit (export/principled.json)
is read from OUT_DIR. The images are encoded by pipeline/report_photos.py.
"""

import base64
import html
import json
import re
import time
from pathlib import Path

import numpy as np

from flashbrdf.files.atomic import write_text
from flashbrdf.pipeline import report_data as data
from flashbrdf.pipeline import report_photos
from flashbrdf.pipeline.report_text import PAGE_DIR, PAGE_NAME, finite, summary_html

SCRIPTS = ("common.js", "renders.js", "brdf.js", "main.js")   # inlined in this order
LABELS_MAX_SIDE = 512     # the label image is shown at most this large (nearest sampling)


def write_report_html(out_dir, report, references=(), observed=None, predictions=None, *,
                      materials=None, level_note=None, how_to_read=None,
                      budget=data.IMAGE_BUDGET_BYTES):
    """Write OUT_DIR/report.html; return {"path", "bytes", "seconds", "image_factor",
    "image_bytes"}.

    report: the dict write_report wrote to report.json; references: its reference rows with
    arrays (or image paths) "render", "reference", "delta_e_map", "mask"; observed: {"rho",
    "n", "spread"} or None; predictions: {method: {"table", "variance", "variance_label", "interval_offset"}} or
    None; materials: with several materials, {"labels": (H, W) int label image, "each": {k:
    {"observed": like observed, "predictions": like predictions}}} (what `run` has in memory:
    nothing is read back from OUT_DIR); level_note, how_to_read: report.md's texts
    (markdown), shown in the summary."""
    start = time.perf_counter()
    out_dir = Path(out_dir)
    rows = list(references or ())
    methods = list(dict.fromkeys(str(r["method"]) for r in rows))
    photos, blocks, image_info = report_photos.encode_photos(report_photos.gather(rows),
                                                             methods, budget)
    brdf = _brdf_datasets(observed, predictions, materials)
    meta = {
        "title": report.get("title", "flashbrdf report"),
        "methods": methods,
        "brdf_methods": list(dict.fromkeys(methods + [m for d in brdf for m in d["methods"]])),
        "photos": photos,
        "exposure": {"initial": float(np.median([p["auto_stops"] for p in photos]))
                     if photos else 0.0},
        "delta_e_vmax": image_info.get("vmax", 5.0),
        "overlay_alpha": data.OVERLAY_ALPHA,
        "luts": {name: data.uint8_b64(data.colour_lut(name))
                 for name in ("inferno", "magma", "viridis")},
        "brdf": brdf,
        "principled": _principled(out_dir),
        "materials": _materials(report, materials),
        "previews": _previews(out_dir, report.get("previews")),
        "images": image_info,
    }
    meta["exposure"]["initial"] = round(meta["exposure"]["initial"], 1)
    title = html.escape(meta["title"])
    blocks_html = "\n".join(f'<script type="application/octet-stream" id="{k}">{v}</script>'
                            for k, v in blocks.items())
    values = {
        "TITLE": title,
        "CSS": _read("report.css"),
        "SUMMARY": summary_html(report, level_note, how_to_read),
        "META": json.dumps(data.jsonable(meta), allow_nan=False).replace("<", "\\u003c"),
        "BLOCKS": blocks_html,
        "JS": "\n".join(_read(name) for name in SCRIPTS),
    }
    template = _read("report.html")
    size = len(template) + sum(len(v) for v in values.values())  # ASCII but for a few labels
    factor = image_info.get("factor", 1)
    info = (f"{size / 2**20:.1f} MB, written in {time.perf_counter() - start:.2f} s"
            + (f"; images downsampled {factor}×" if factor > 1 else ""))
    values["PAGE_INFO"] = html.escape(info)
    values["FOOTER"] = html.escape(
        f"flashbrdf report.html: {info}. Self-contained: nothing is loaded from outside this "
        "file. Images are float16 linear data in the photos' pixel units, cropped to the object.")
    page = _fill(template, values)
    path = out_dir / PAGE_NAME
    write_text(path, page)
    return {"path": path, "bytes": path.stat().st_size,
            "seconds": time.perf_counter() - start, "image_factor": factor,
            "image_bytes": image_info.get("bytes", 0)}


def _previews(out_dir, previews):
    """{"envmap", "renders": [{"method", "what", "src" (a PNG data URI)}]} of report.json's
    "previews" (pipeline/previews.py wrote the PNGs into OUT_DIR first), or None. They are
    embedded as written, outside the photos' image budget: a few tone-mapped PNGs of ~30 KB
    each per method (an object and a sphere per material)."""
    if not previews:
        return None
    renders = []
    for method, files in previews.get("renders", {}).items():
        spheres = files.get("spheres", {})
        named = [("the object", files.get("object"))] + [
            ("a sphere" if len(spheres) == 1 else f"a sphere of material {k}", path)
            for k, path in spheres.items()]
        for what, rel in named:
            path = out_dir / rel if rel else None
            if path is not None and path.is_file():
                renders.append({"method": method, "what": what, "src": "data:image/png;base64,"
                                + base64.b64encode(path.read_bytes()).decode("ascii")})
    return {"envmap": Path(previews.get("envmap", "")).name, "renders": renders}


def _read(name):
    return (PAGE_DIR / name).read_text(encoding="utf-8")


def _fill(template, values):
    """Replace every {{KEY}} of the template in one pass (what the values hold, braces
    included, is inserted as it is)."""
    pieces = re.split(r"\{\{([A-Z_]+)\}\}", template)
    return "".join(values.get(p, "{{" + p + "}}") if k % 2 else p for k, p in enumerate(pieces))


# ---- the BRDF and the materials, from the arguments --------------------------------------

def _brdf_datasets(observed, predictions, materials=None):
    """[{"name", "material" (label or None), "observed", "methods": {method: brdf_entry}}]:
    the whole object's and, with several materials, each material's."""
    def entries(predictions):
        return {str(method): data.brdf_entry(p["table"], p.get("variance"),
                                             p.get("variance_label", "uncertainty"),
                                             interval_offset=p.get("interval_offset"))
                for method, p in (predictions or {}).items()}
    datasets = [{"name": "the whole object", "material": None,
                 "observed": _observed_entry(observed), "methods": entries(predictions)}]
    for k, each in sorted(((materials or {}).get("each") or {}).items()):
        datasets.append({"name": f"material {k}", "material": int(k),
                         "observed": _observed_entry(each.get("observed")),
                         "methods": entries(each.get("predictions"))})
    return [d for d in datasets if d["methods"]]


def _observed_entry(observed):
    if observed is None or observed.get("rho") is None:
        return None
    return data.slice_entry(observed["rho"], observed["n"], observed.get("spread"))


def _materials(report, materials):
    """The label image (nearest-sampled to LABELS_MAX_SIDE) and each material's share, or None
    for one material."""
    entries_json = report.get("materials") or []
    labels = None if materials is None else materials.get("labels")
    if len(entries_json) < 2 or labels is None or np.ndim(labels) != 2:
        return None
    labels = np.asarray(labels)
    step = max(1, -(-max(labels.shape) // LABELS_MAX_SIDE))
    shown = np.clip(labels[::step, ::step], 0, 255)
    total = sum(int(m.get("pixels", 0)) for m in entries_json) or 1
    each = materials.get("each") or {}
    entries = []
    for m in entries_json:
        observed = (each.get(int(m["label"])) or {}).get("observed")
        entries.append({"label": int(m["label"]), "pixels": int(m.get("pixels", 0)),
                        "share": int(m.get("pixels", 0)) / total,
                        "bins_filled": None if observed is None else
                        int(np.count_nonzero(np.asarray(observed["n"]) > 0))})
    reason = (report.get("segmentation") or {}).get("reason", "")
    return {"labels": {"width": int(shown.shape[1]), "height": int(shown.shape[0]),
                       "step": step, "data": data.uint8_b64(shown)},
            "entries": entries,
            "reason": f"Segmentation of the flash photo into {len(entries_json)} materials"
                      + (f": {reason}" if reason else "") + "."}


def _principled(out_dir):
    """[{"name", "params", "fit"}] from OUT_DIR/export/principled.json and
    export/material_<k>/principled.json (run --export), [] where export did not run."""
    export = out_dir / "export"
    files = [export / "principled.json"] + sorted(export.glob("material_*/principled.json"))
    fits = []
    for path in files:
        try:
            fit = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
        params = {k: fit[k] for k in ("base_color", "roughness", "metallic", "specular",
                                      "spec_tint", "sheen", "sheen_tint", "clearcoat",
                                      "clearcoat_gloss") if k in fit}
        numbers = {k: finite((fit.get("fit") or {}).get(k))
                   for k in ("lab_log_2d", "render_delta_e_log")}
        fits.append({"name": path.relative_to(out_dir).as_posix(), "params": params,
                     "fit": numbers})
    return fits


def page_data(path):
    """(metadata dict, {block id: base64 text}) of a written report.html: what the page's
    scripts read (the tests check the page against it; report_data.decode_halfs decodes a
    photo's block, in the order of its "arrays")."""
    text = Path(path).read_text(encoding="utf-8")
    meta = re.search(r'<script id="report-meta" type="application/json">(.*?)</script>', text,
                     re.S)
    blocks = dict(re.findall(r'<script type="application/octet-stream" id="([^"]+)">([^<]*)'
                             r'</script>', text))
    return json.loads(meta.group(1)), blocks
