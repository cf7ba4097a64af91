"""report.html's embedded data (pipeline/report_data.py, report_photos.py, report_html.py):
shapes, the exposure maths, the ΔE overlay, the encoding's precision and the page's size."""

import base64
import json

import numpy as np
import pytest

from flashbrdf.brdf.views import table_3d_from_2d
from flashbrdf.pipeline import report_data as data
from flashbrdf.pipeline.report import write_report
from flashbrdf.pipeline.report_html import page_data, write_report_html
from flashbrdf.pipeline.report_text import inline_markdown
from flashbrdf.pipeline.report_photos import decode_photo, encode_photos, gather

# float16 keeps 11 significant bits: a stored value is within 2^-11 of it, relatively.
HALF_REL = 2.0 ** -11


def _code_step(codes):
    """Half the linear width of an 8-bit sRGB code (the rounding error of reading it back)."""
    codes = np.asarray(codes, float)
    return 0.5 * (data.srgb8_to_linear(np.minimum(codes + 1, 255))
                  - data.srgb8_to_linear(np.maximum(codes - 1, 0))) / 2


def test_one_stop_doubles_a_linear_value_below_the_clip():
    linear = np.geomspace(0.01, 0.45, 200)          # 2x stays below the clip at 0 stops
    low, high = data.expose_to_srgb8(linear, 0.0), data.expose_to_srgb8(linear, 1.0)
    back_low, back_high = data.srgb8_to_linear(low), data.srgb8_to_linear(high)
    ratio = back_high / back_low
    # each read-back is off by at most half a code: the ratio's relative error is the sum
    tolerance = _code_step(low) / back_low + _code_step(high) / back_high
    assert np.all(np.abs(ratio - 2.0) <= 2.0 * tolerance)
    assert np.median(ratio) == pytest.approx(2.0, rel=0.01)
    # above the clip every exposure shows white, and NaN or negative shows black
    assert np.all(data.expose_to_srgb8([0.6, 5.0, 1e9], 1.0) == 255)
    assert np.all(data.expose_to_srgb8([np.nan, -1.0, 0.0], 3.0) == 0)
    # the codes are the sRGB curve's: 0.5 linear is code 188, 0.0031308 is 12.92x (code 10)
    assert data.srgb8(0.5) == 188 and data.srgb8(0.0031308) == 10


def test_srgb_codes_round_trip():
    codes = np.arange(256)
    assert np.array_equal(data.srgb8(data.srgb8_to_linear(codes)), codes)


def test_delta_e_overlay_blends_the_colour_map_where_delta_e_is_defined():
    lut = data.colour_lut("inferno")
    assert lut.shape == (256, 3) and lut.dtype == np.uint8
    codes = np.full((2, 3, 3), 100, np.uint8)
    de = np.array([[np.nan, 0.0, 2.5], [5.0, 50.0, -1.0]])
    out = data.overlay_delta_e(codes, de, vmax=5.0, lut=lut, alpha=0.6)
    assert np.array_equal(out[0, 0], codes[0, 0])                      # NaN: image as it is
    for (r, c), index in {(0, 1): 0, (0, 2): 127, (1, 0): 255, (1, 1): 255, (1, 2): 0}.items():
        expected = np.floor(0.4 * 100 + 0.6 * lut[index].astype(float) + 0.5)
        assert np.array_equal(out[r, c], expected), (r, c)
    # the scale's top: max(5, 99th percentile of every map)
    assert data.delta_e_vmax([np.array([1.0, 2.0, np.nan])]) == 5.0
    assert data.delta_e_vmax([np.linspace(0, 100, 1001)]) == pytest.approx(99.0)


def test_half_encoding_keeps_float16_precision_and_nan():
    rng = np.random.default_rng(3)
    values = rng.lognormal(0, 3, (7, 5, 3)).astype(np.float32)
    values[0, 0, 0] = np.nan
    values[0, 0, 1] = np.inf                     # a hot pixel: kept as inf, not the scale's top
    scale = data.power_of_two_scale([values])
    assert np.log2(scale) == int(np.log2(scale))                        # a power of two
    assert np.max(values[np.isfinite(values)]) / scale <= data.HALF_TOP
    text, nbytes = data.encode_halfs([values / scale])
    (back,) = data.decode_halfs(text, [values.size])
    back = back.reshape(values.shape) * scale
    assert np.isnan(back[0, 0, 0]) and back[0, 0, 1] == np.inf
    ok = np.isfinite(values) & (values / scale > 2.0 ** -14)            # float16's normal range
    assert np.all(np.abs(back[ok] - values[ok]) <= HALF_REL * np.abs(values[ok]))
    assert nbytes == len(base64.b64decode(text))


def test_crop_and_downsample():
    measured = np.zeros((100, 80), bool)
    measured[20:40, 10:30] = True
    r0, r1, c0, c1 = data.object_box(measured, margin=0.1)
    assert (r0, r1, c0, c1) == (18, 42, 8, 32)                          # 2 px = 10% of 20
    image = np.arange(5 * 5, dtype=np.float32).reshape(5, 5)
    image[0, 0] = np.nan
    small = data.downsample(image, 2)
    assert small.shape == (3, 3)
    assert small[0, 0] == pytest.approx(np.mean([1, 5, 6]))           # NaN left out
    assert small[2, 2] == image[4, 4]                                  # a partial block
    assert data.downsample_factor([100 * 100] * 10, [100] * 10, [40] * 10, budget=4_000_000) == 1
    assert data.downsample_factor([100 * 100] * 10, [100] * 10, [40] * 10, budget=1_000_000) == 2
    assert data.downsample_factor([10], [5000], [40], max_side=1024) == 5


def _rows(photos=2, methods=("dsgplvm", "pca"), size=(40, 60), seed=0):
    rng = np.random.default_rng(seed)
    h, w = size
    mask = np.zeros((h, w), bool)
    mask[h // 4:3 * h // 4, w // 4:3 * w // 4] = True   # (40, 60): rows 10-29, cols 15-44
    rows = []
    for p in range(photos):
        reference = np.where(mask[..., None], rng.uniform(0.01, 0.5, (h, w, 3)), 0.0)
        for k, m in enumerate(methods):
            render = reference * (1.0 + 0.1 * k)
            de = np.where(mask, rng.uniform(0, 8, (h, w)), np.nan)
            rows.append({"photo": f"ref_{p}", "method": m, "render": render,
                         "reference": reference, "mask": mask, "delta_e_map": de,
                         "delta_e_log_mean": float(np.nanmean(de)), "rel_rmse": 0.1})
    return rows


def test_photos_are_cropped_shared_and_decode_to_the_inputs():
    rows = _rows()
    photos, blocks, info = encode_photos(gather(rows), ["dsgplvm", "pca"])
    assert info["factor"] == 1 and len(photos) == 2
    first = photos[0]
    # the mask's box (20 x 30) plus 5% of 30 -> 2 px each side
    assert first["box"] == [8, 32, 13, 47] and (first["height"], first["width"]) == (24, 34)
    # the photo once, then per method its render and its ΔE map
    assert [k for k, _ in first["arrays"]] == ["reference", "render:dsgplvm", "de:dsgplvm",
                                               "render:pca", "de:pca"]
    arrays = decode_photo(first, blocks[first["block"]])
    crop = (slice(8, 32), slice(13, 47))
    for key, source in (("reference", rows[0]["reference"]), ("render:pca", rows[1]["render"]),
                        ("de:dsgplvm", rows[0]["delta_e_map"][..., None])):
        expected = np.asarray(source, np.float32)[crop]
        assert arrays[key].shape == expected.shape
        finite = np.isfinite(expected) & (np.abs(expected) > 1e-3)
        assert np.all(np.abs(arrays[key][finite] - expected[finite])
                      <= HALF_REL * np.abs(expected[finite])), key
        assert np.array_equal(np.isnan(arrays[key]), np.isnan(expected)), key


def test_a_page_over_its_budget_is_downsampled_to_fit():
    rows = _rows(photos=12, size=(120, 160), seed=4)
    photos, _, info = encode_photos(gather(rows), ["dsgplvm", "pca"], budget=150_000)
    # uniform noise barely deflates, so the first photo's ratio predicts the rest's: the bytes
    # land within the budget, and a factor one smaller would not have fitted
    assert info["factor"] > 1 and info["bytes"] <= 150_000 * 1.1
    full = photos[0]["box"]
    h, w = full[1] - full[0], full[3] - full[2]
    f = info["factor"]
    assert (photos[0]["height"], photos[0]["width"]) == (-(-h // f), -(-w // f))
    per_pixel = 2 * (3 + 2 * (3 + 1))
    ratio = info["bytes"] / info["raw_bytes"]
    assert 12 * h * w / (f - 1) ** 2 * per_pixel * ratio > 150_000


def _tables():
    rho = np.linspace(0.02, 2.0, 90 * 90 * 3).reshape(90, 90, 3)[::-1]
    return rho, {"dsgplvm": {"table": rho, "variance": np.full((90, 90, 3), 0.2),
                             "variance_label": "posterior variance"},
                 "pca": {"table": rho * 1.5, "variance": None}}


def test_write_report_writes_the_page_with_tables_slice_and_summary(tmp_path):
    rho, predictions = _tables()
    observed = {"rho": rho[:, 0, :], "n": np.arange(90), "spread": 0.1 * rho[:, 0, :]}
    report = write_report(tmp_path, stages={"extract": 1.0}, references=_rows(),
                          observed=observed, predictions=predictions,
                          notes=["a note with <script>alert(1)</script> and `code`"])
    meta, blocks = page_data(tmp_path / "report.html")
    assert set(blocks) == {"photo-0", "photo-1"}
    assert meta["methods"] == ["dsgplvm", "pca"]
    (whole,) = meta["brdf"]
    table = np.frombuffer(base64.b64decode(whole["methods"]["pca"]["table"]),
                          "<f4").reshape(90, 90, 3)
    assert np.allclose(table, rho * 1.5, rtol=2.0 ** -23)
    assert whole["methods"]["dsgplvm"]["variance_constant"] == pytest.approx(0.2)
    assert whole["observed"]["n"] == list(range(90))
    page = (tmp_path / "report.html").read_text()
    # the size: base64 of the deflated images (4/3), at most three 90 x 90 x 3 float32 arrays
    # (two tables, a variance map; 4/3 again) and the template, scripts and colour maps (53 KB)
    images = meta["images"]["bytes"]
    tables = 3 * 90 * 90 * 3 * 4 * 4 / 3
    assert len(page.encode()) <= 4 / 3 * images + tables + 100_000
    assert "<script>alert(1)</script>" not in page and "&lt;script&gt;" in page
    assert "http://" not in page and "https://" not in page       # nothing from the network
    # report.md and report.json are as before: the page is an addition
    assert set(json.loads((tmp_path / "report.json").read_text())) == set(report)
    assert "report.html" not in (tmp_path / "report.md").read_text()


def test_materials_are_shown_and_the_principled_fit_read_from_out_dir(tmp_path):
    labels = np.zeros((30, 40), np.uint16)
    labels[5:25, 5:20], labels[5:25, 20:35] = 1, 2
    rho, _ = _tables()
    materials, each = [], {}
    for k in (1, 2):
        materials.append({"label": k, "pixels": int((labels == k).sum()),
                          "slice": f"materials/material_{k}.csv",
                          "brdf": {"pca": f"pca/material_{k}/brdf.binary"}})
        each[k] = {"observed": {"rho": rho[:, 0] * k, "n": np.full(90, 10 * k)},
                   "predictions": {"pca": {"table": table_3d_from_2d(rho * k)}}}
    (tmp_path / "export").mkdir()
    (tmp_path / "export" / "principled.json").write_text(json.dumps(
        {"base_color": [0.5, 0.2, 0.1], "roughness": 0.3, "fit": {"lab_log_2d": 4.5,
                                                                  "render_delta_e_log": None}}))
    report = {"title": "t", "summary": {}, "materials": materials,
              "segmentation": {"reason": "chosen"}}
    write_report_html(tmp_path, report, materials={"labels": labels, "each": each})
    meta, _ = page_data(tmp_path / "report.html")
    entries = meta["materials"]["entries"]
    assert [e["pixels"] for e in entries] == [300, 300]
    assert [e["bins_filled"] for e in entries] == [90, 90]
    assert sum(e["share"] for e in entries) == pytest.approx(1.0)
    shown = np.frombuffer(base64.b64decode(meta["materials"]["labels"]["data"]),
                          np.uint8).reshape(30, 40)
    assert np.array_equal(shown, labels)
    assert [d["material"] for d in meta["brdf"]] == [1, 2]
    table = meta["brdf"][1]["methods"]["pca"]["table"]
    table = np.frombuffer(base64.b64decode(table), "<f4").reshape(90, 90, 3)
    valid = np.isfinite(table)
    assert valid[:, 0].all() and np.allclose(table[valid], (2 * rho)[valid], rtol=1e-6)
    assert meta["principled"][0]["params"]["roughness"] == 0.3
    assert meta["principled"][0]["fit"] == {"lab_log_2d": 4.5, "render_delta_e_log": None}


def test_a_3d_table_carries_its_plane_of_incidence():
    """φd = 0 (folded) is the plane of incidence: a 3D table's entry holds the mean of φd bins 0
    and 179 beside its φd mean; a 2D table (the same at every φd) needs none."""
    from flashbrdf.brdf.merl import merl_valid_mask
    table = np.ones((90, 90, 180, 3))
    table[:, :, 0] = 2.0
    table[:, :, 179] = 4.0
    table[~merl_valid_mask()] = np.nan
    entry = data.brdf_entry(table)
    plane = np.frombuffer(base64.b64decode(entry["in_plane"]), np.float32).reshape(90, 90, 3)
    valid = merl_valid_mask()[:, :, 0]          # bins 0 and 179 are mirror images: same mask
    assert np.array_equal(valid, merl_valid_mask()[:, :, 179])
    assert np.all(plane[valid] == 3.0) and np.all(np.isnan(plane[~valid]))
    assert "in_plane" not in data.brdf_entry(table[:, :, 90])


def test_inline_markdown_escapes_and_links_figures():
    html = inline_markdown("**Level:** `x<y` ![map](figures/a.png)")
    assert html == ('<strong>Level:</strong> <code>x&lt;y</code> '
                    '<a href="figures/a.png">map (figure)</a>')


def test_batch_index_links_each_report_and_is_known_to_the_next_batch(tmp_path):
    from flashbrdf.pipeline.report_index import INDEX_HEAD, write_batch_index
    (tmp_path / "cap a").mkdir()
    (tmp_path / "cap a" / "report.html").write_text("<!doctype html>")
    (tmp_path / "cap a" / ".batch_complete.json").write_text("{}")
    rows = [{"capture": "cap a", "status": "ok", "reason": "", "seconds": 12.5,
             "delta_e_log": {"dsgplvm": 1.5, "pca": 1.25, "pca/ref_1": 1.0}},
            {"capture": "b<c>", "status": "failed", "reason": "InputError: x", "seconds": None,
             "delta_e_log": {}},
            {"capture": "rerun", "status": "failed", "reason": "InputError: y", "seconds": 1.0,
             "delta_e_log": {}},
            {"capture": "no photo", "status": "ok", "reason": "", "seconds": 9.0,
             "delta_e_log": {}}]
    (tmp_path / "no photo").mkdir()
    (tmp_path / "no photo" / "report.html").write_text("<!doctype html>")
    (tmp_path / "rerun").mkdir()  # a capture whose rerun failed keeps its earlier run's folder
    (tmp_path / "rerun" / "report.html").write_text("<!doctype html>")
    (tmp_path / "logs").mkdir()
    (tmp_path / "logs" / "rerun.log").write_text("Traceback ...")
    write_batch_index(tmp_path, rows, ["dsgplvm", "pca"], ["- 2 capture(s)"])
    page = (tmp_path / "index.html").read_text()
    # a failed capture's reason links its log (the traceback); one without a log links nothing
    assert '<td class=reason>InputError: y (<a href="logs/rerun.log">log</a>)</td>' in page
    assert '<td class=reason>InputError: x</td>' in page
    assert page.startswith(INDEX_HEAD)
    assert '<a href="cap%20a/report.html">cap a</a>' in page
    assert "b&lt;c&gt;" in page and "b<c>" not in page        # no report: no link, escaped
    # failed with an earlier report on disk: linked as that, not as this run's
    assert ("<td>rerun (<a href=\"rerun/report.html\">an earlier run's report</a>, not of these "
            "inputs or options)</td>") in page
    assert "<td class=best>1.250</td>" in page and "pca/ref_1" not in page
    # an ok capture with no reference photo: a dash that says why, not a blank
    row = page.split("no photo</a></td>")[1].split("</tr>")[0]
    assert row.count("<td title='nothing compared: no reference photo, or none that sees the object'>–</td>") == 2
    # (test_batch.py's summary test checks that a second batch accepts the index: write_summary
    # writes it, and the folder check knows it by INDEX_HEAD)


def test_the_page_keeps_its_image_budget_when_the_first_photo_deflates_better(tmp_path):
    """The deflate ratio was measured on the first photo alone: a flat first photo among 11
    noisy ones predicted 1/20 of the real size, and a page of 40 such photos held 11 times its
    budget (367 MB). The whole page is checked now and encoded again smaller."""
    rng = np.random.default_rng(0)
    size = 160
    yy, xx = np.mgrid[0:size, 0:size]
    mask = (yy - size / 2) ** 2 + (xx - size / 2) ** 2 < (0.45 * size) ** 2
    rows = []
    for k in range(12):
        if k == 0:
            ref = np.where(mask[..., None], 0.25, 0.0) * np.ones(3)
            ren, de = ref.copy(), np.where(mask, 1.0, np.nan)
        else:
            ref, ren = ((rng.random((size, size, 3)) + 0.1) * mask[..., None] for _ in range(2))
            de = np.where(mask, rng.random((size, size)) * 3, np.nan)
        rows.append({"photo": f"p{k:02d}", "method": "m", "render": ren.astype(np.float32),
                     "reference": ref.astype(np.float32), "mask": mask,
                     "delta_e_map": de.astype(np.float32), "delta_e_log_mean": 1.0})
    # 12 photos x 160² x 7 halfs = 4.3 MB raw; noise deflates to ~0.9 of it, the flat photo to
    # ~0.01: a 1 MB budget needs a factor of at least 2
    info = write_report_html(tmp_path, {"title": "budget"}, rows, budget=1 << 20)
    assert info["image_bytes"] <= 1 << 20 and info["image_factor"] >= 2


def test_a_per_channel_log_variance_carries_its_interval_offset_and_cielab_does_not():
    """The page turns a variance per channel of ln(1 + rho/eps) into a 90% interval in 1/sr; a
    CIELAB variance mixes the channels, so no offset is given for it (and none is shown)."""
    from types import SimpleNamespace
    from flashbrdf.brdf.colour import FEATURE_OFFSET
    from flashbrdf.pipeline.report_data import brdf_entry, variance_description
    rgb = variance_description(SimpleNamespace(feature_space="rgb", feature_label="RGB of x"))
    lab = variance_description(SimpleNamespace(feature_space="lab", feature_label="CIELAB of x"))
    assert rgb == {"variance_label": "predictive variance (RGB of x)",
                   "interval_offset": FEATURE_OFFSET}
    assert lab["interval_offset"] is None and variance_description(object())["interval_offset"] is None
    table = np.full((90, 90, 3), 0.5)
    assert brdf_entry(table, None, **rgb)["interval_offset"] == FEATURE_OFFSET
    assert "interval_offset" not in brdf_entry(table, None, **lab)
