"""report.html's renders: per reference photo, the photo, each method's render and ΔE map, cropped
to the object, downsampled to the page's budget and encoded (pipeline/report_data.py).

The photo is stored once per photo and shared by every method's frame; each photo's arrays are one
base64 block, which the page inflates only when that photo is first shown.
"""

import os

import numpy as np

from flashbrdf.pipeline import report_data as data
from flashbrdf.render.compare import compare_images


def delta_e_map(render, reference, mask=None):
    """(H, W) ΔE-log per pixel, NaN where not compared (render.compare.compare_images)."""
    if mask is not None:
        mask = _plane(mask) > 0
    return compare_images(render, reference, mask)[1]


def _plane(array):
    """A (H, W) float array from a mask or ΔE map given as (H, W) or (H, W, C); None for none."""
    if array is None:
        return None
    array = np.asarray(array)
    return array if array.ndim == 2 else array.reshape(array.shape[0], array.shape[1], -1)[..., 0]


def gather(references):
    """{photo: {"rows": [report rows], "mask": (H, W) bool union of the rows' hit masks or None,
    "means": {method: ΔE-log mean}}} from write_report's reference rows. Images stay as given
    (arrays or paths) until load() reads one photo's."""
    photos = {}
    for row in references:
        entry = photos.setdefault(str(row["photo"]), {"rows": [], "mask": None, "means": {}})
        entry["rows"].append(row)
        mask = data.read_image(row.get("mask"))
        if mask is not None:
            mask = _plane(mask) > 0
            entry["mask"] = mask if entry["mask"] is None or entry["mask"].shape != mask.shape \
                else entry["mask"] | mask
        mean = row.get("delta_e_log_mean", (row.get("compare") or {}).get("delta_e_log_mean"))
        entry["means"][row["method"]] = None if mean is None or not np.isfinite(mean) else \
            float(mean)
    return photos


def load(entry):
    """One photo's images: {"reference", "renders": {method: (H,W,3)}, "maps": {method: (H,W)
    ΔE}}. Paths are read (pipeline.report.read_image); a ΔE map given as a false-colour PNG
    holds no ΔE values: it is recomputed from the render and the photo."""
    out = {"reference": None, "renders": {}, "maps": {}}
    for row in entry["rows"]:
        render, reference = data.read_image(row.get("render")), data.read_image(row.get("reference"))
        de = row.get("delta_e_map")
        de = data.read_image(de) if isinstance(de, (str, os.PathLike)) else de
        if (de is None or np.ndim(de) != 2 or np.asarray(de).dtype.kind != "f") and (
                render is not None and reference is not None):
            de = delta_e_map(render, reference, data.read_image(row.get("mask")))
        elif de is not None and (np.ndim(de) != 2 or np.asarray(de).dtype.kind != "f"):
            de = None
        # kept as given: only the object's crop is made float32 (report_data.downsample)
        if reference is not None and out["reference"] is None:  # one photo for all methods
            out["reference"] = np.asarray(reference)
        if render is not None:
            out["renders"][row["method"]] = np.asarray(render)
        if de is not None:
            out["maps"][row["method"]] = np.asarray(de)
    return out


def _all_named(entry):
    """Whether every row names its render and ΔE map as files (what `run` writes), so what a
    photo holds is known without reading its images."""
    return all(isinstance(row.get(key), (str, os.PathLike)) for row in entry["rows"]
               for key in ("render", "delta_e_map") if row.get(key) is not None) and all(
        row.get("render") is not None for row in entry["rows"])


def _named(entry):
    """(photo present, {methods with a render}, {methods with a ΔE map}) of rows that name files."""
    rows = entry["rows"]
    return (any(row.get("reference") is not None for row in rows),
            {row["method"] for row in rows},
            {row["method"] for row in rows if row.get("delta_e_map") is not None})


def _shape(images):
    for image in [images["reference"], *images["renders"].values()]:
        if image is not None:
            return image.shape[:2]
    return None


def _measured(entry, images, shape):
    """Where the object is: the renders' hit masks, else finite ΔE, else nonzero render/photo."""
    if entry["mask"] is not None and entry["mask"].shape == shape:
        return entry["mask"]
    maps = [m for m in images["maps"].values() if m.shape == shape]
    if maps:
        return np.any([np.isfinite(m) for m in maps], axis=0)
    found = [i for i in [images["reference"], *images["renders"].values()] if i is not None]
    return np.any([np.nan_to_num(i).max(-1) > 0 for i in found], axis=0)


def _arrays(images, methods, box, factor):
    """[(key, channels, array)] of one photo, cropped and downsampled, in the page's order."""
    r0, r1, c0, c1 = box
    out = []
    if images["reference"] is not None:
        out.append(("reference", 3, images["reference"]))
    for method in methods:
        if method in images["renders"]:
            out.append((f"render:{method}", 3, images["renders"][method]))
        if method in images["maps"]:
            out.append((f"de:{method}", 1, images["maps"][method]))
    return [(key, ch, data.downsample(np.asarray(a)[r0:r1, c0:c1], factor))
            for key, ch, a in out if np.asarray(a).shape[:2] == images["shape"]]


def encode_photos(photos, methods, budget=data.IMAGE_BUDGET_BYTES):
    """(photo list for the page's metadata, {block id: base64 text}, info dict).

    Every photo is cropped to the object's box; one downsampling factor for the page, the
    smallest that keeps the deflated images within `budget` (its deflate ratio estimated on the
    first photo, then checked on the whole page, which is encoded again smaller when it does
    not fit)."""
    usable = {}
    for name, entry in photos.items():  # one photo's images at a time
        if entry["mask"] is not None and _all_named(entry):  # run's rows: nothing to read yet
            shape, has = entry["mask"].shape, _named(entry)
            measured = entry["mask"]
        else:
            images = load(entry)
            shape = _shape(images)
            if shape is None:
                continue
            has = (images["reference"] is not None, set(images["renders"]), set(images["maps"]))
            measured = _measured(entry, images, shape)
            del images
        entry.update(shape=shape, measured=measured, box=data.object_box(measured), has=has)
        usable[name] = entry
    if not usable:
        return [], {}, {"factor": 1, "bytes": 0, "raw_bytes": 0}
    sizes = [(e["box"][1] - e["box"][0]) * (e["box"][3] - e["box"][2]) for e in usable.values()]
    sides = [max(e["box"][1] - e["box"][0], e["box"][3] - e["box"][2]) for e in usable.values()]
    per_pixel = [2 * (3 * e["has"][0] + sum(3 * (m in e["has"][1]) + (m in e["has"][2])
                                            for m in methods)) for e in usable.values()]
    # the deflate ratio, measured on the first photo at the factor that fits uncompressed (at
    # full size its copies made the report's peak: 1.5 GB at 24 MP), then checked on the page
    first = next(iter(usable.values()))
    widest = data.downsample_factor(sizes, sides, per_pixel, budget, 1.0)
    first_arrays = _arrays(_loaded(first), methods, first["box"], widest)
    first_encoded = _encode(first_arrays)
    raw_first = 2 * sum(a.size for _, _, a in first_arrays)
    ratio = first_encoded[1] / raw_first if raw_first else 1.0
    factor = data.downsample_factor(sizes, sides, per_pixel, budget, ratio)
    while True:
        listed, blocks, total, raw, maps = _encode_all(
            usable, methods, factor, (first_arrays, first_encoded) if factor == widest else None)
        if total <= budget or not raw or factor >= max(sides):
            break
        # the first photo deflated better than the rest (a dim one among textured ones): again,
        # at the factor the whole page's own deflate ratio asks for
        factor = max(factor + 1, data.downsample_factor(sizes, sides, per_pixel, budget,
                                                        total / raw))
    info = {"factor": factor, "bytes": total, "raw_bytes": raw, "photos": len(listed),
            "vmax": data.delta_e_vmax(maps)}
    return listed, blocks, info


def _encode_all(usable, methods, factor, first=None):
    """(photo list, {block id: base64 text}, deflated bytes, raw bytes, ΔE maps) of every usable
    photo at one downsampling factor; first: the first photo's (arrays, encoding) at it."""
    listed, blocks, total, raw, maps = [], {}, 0, 0, []
    for index, (name, entry) in enumerate(usable.items()):
        images = _loaded(entry)
        if index == 0 and first is not None:  # already encoded to measure the deflate ratio
            arrays, (text, nbytes, scale) = first
        else:
            arrays = _arrays(images, methods, entry["box"], factor)
            text, nbytes, scale = _encode(arrays)
        maps += [a for _, ch, a in arrays if ch == 1]   # the ΔE scale: of what is shown
        block = f"photo-{index}"
        blocks[block] = text
        total += nbytes
        raw += 2 * sum(a.size for _, _, a in arrays)
        h, w = arrays[0][2].shape[:2] if arrays else (0, 0)
        r0, r1, c0, c1 = entry["box"]
        exposed = next((i for i in [images["reference"], *images["renders"].values()]
                        if i is not None))          # the photo, else a render
        lit = np.asarray(exposed[r0:r1, c0:c1])[entry["measured"][r0:r1, c0:c1]]
        del images, exposed
        listed.append({
            "name": name, "block": block, "width": int(w), "height": int(h),
            "factor": factor, "box": [int(v) for v in entry["box"]],
            "full": [int(v) for v in entry["shape"]], "scale": scale,
            "arrays": [[key, ch] for key, ch, _ in arrays],
            "delta_e": entry["means"], "auto_stops": data.auto_stops(lit)})
    return listed, blocks, total, raw, maps


def _loaded(entry):
    """load(entry) with the photo's full shape, as _arrays wants it."""
    return load(entry) | {"shape": entry["shape"]}


def _encode(arrays):
    """(base64, deflated bytes, scale): the colour arrays divided by a power of two that fits
    them in float16 (ΔE maps are stored as they are)."""
    scale = data.power_of_two_scale([a for _, ch, a in arrays if ch == 3])
    text, nbytes = data.encode_halfs([a / scale if ch == 3 else a for _, ch, a in arrays])
    return text, nbytes, scale


def decode_photo(photo, text):
    """{key: float32 (H, W, C)} of one photo's block as the page decodes it ("reference",
    "render:<method>" with the scale applied, "de:<method>"): the inverse of encode_photos."""
    h, w = photo["height"], photo["width"]
    arrays = data.decode_halfs(text, [h * w * ch for _, ch in photo["arrays"]])
    return {key: (a * np.float32(photo["scale"]) if ch == 3 else a).reshape(h, w, ch)
            for (key, ch), a in zip(photo["arrays"], arrays)}
