"""pipeline.report on synthetic inputs: files, contract keys, numbers that round-trip and are right."""

import json

import numpy as np
import pytest

from flashbrdf.brdf.merl import theta_h_centres
from flashbrdf.pipeline.report import coverage, image_errors, write_report


def _slice_and_tables():
    theta_h = theta_h_centres()
    lobe = np.exp(-(theta_h / 0.1) ** 2)[:, None]
    rho = 0.05 * np.array([1.0, 0.8, 0.6]) + 2.0 * lobe * np.array([1.0, 1.0, 1.0])
    n = np.where(np.degrees(theta_h) < 40.0, 50, 0)   # bins 0..59 seen: theta_h edge 40 deg
    observed = {"rho": np.where(n[:, None] > 0, rho, np.nan), "n": n, "spread": 0.1 * rho}
    table = np.repeat(rho[:, None, :], 90, axis=1)      # (90, 90, 3), constant over theta_d
    return observed, {"dsgplvm": {"table": table, "variance": np.full((90, 90, 3), 0.2),
                                  "variance_label": "posterior std"},
                      "pca": table * 1.2}


def _images():
    rng = np.random.default_rng(1)
    reference = rng.uniform(0.05, 2.0, (24, 32, 3))
    mask = np.zeros((24, 32), np.uint8)
    mask[4:20, 6:26] = 255
    return reference, mask


def test_report_files_keys_and_numbers(tmp_path):
    observed, predictions = _slice_and_tables()
    reference, mask = _images()
    given = {"delta_e_log_mean": 3.25, "delta_e_log_median": 3.0, "rel_rmse": 0.125, "pixels": 320}
    refs = [{"photo": "ref_a.exr", "method": "dsgplvm", "render": reference * 1.1,
             "reference": reference, "mask": mask, "light_angle_deg": 12.0},
            {"photo": "ref_a.exr", "method": "pca", "compare": given, "render": reference * 0.5,
             "reference": reference, "light_angle_deg": 12.0},
            {"photo": "ref_b.exr", "method": "dsgplvm", "delta_e_log_mean": 1.5, "rel_rmse": 0.02,
             "light_angle_deg": 30.0}]
    stages = {"extract": 1.25, "infer": 2.5, "render": 0.75, "compare": 0.125}
    report = write_report(tmp_path / "out", stages=stages, references=refs, observed=observed,
                          predictions=predictions, x_key="light_angle_deg")
    out = tmp_path / "out"
    for name in ("report.md", "report.json", "figures/slice.png", "figures/brdf_dsgplvm.png",
                 "figures/brdf_pca.png", "figures/errors.png", "figures/ref_ref_a.png"):
        assert (out / name).is_file() and (out / name).stat().st_size > 0, name
    assert not list(out.rglob("*.part*"))  # atomic writes leave no temp files

    loaded = json.loads((out / "report.json").read_text())
    assert loaded == json.loads(json.dumps(report))
    assert loaded["stages"] == stages  # exact round trip (binary fractions)
    assert [set(r) >= {"photo", "method", "delta_e_log_mean", "rel_rmse"}
            for r in loaded["references"]] == [True] * 3
    by = {(r["photo"], r["method"]): r for r in loaded["references"]}
    # Numbers handed in (directly or as compare.json) come back unchanged...
    assert {k: by["ref_a.exr", "pca"][k] for k in given} == given
    assert by["ref_b.exr", "dsgplvm"]["delta_e_log_mean"] == 1.5
    assert by["ref_a.exr", "dsgplvm"]["light_angle_deg"] == 12.0
    # ...and computed ones are right: a render 10% too bright has rel_rmse exactly 0.1, over the
    # 16 x 20 = 320 mask pixels, and Delta E log equal to colour-science's own CIE76 value.
    computed = by["ref_a.exr", "dsgplvm"]
    assert computed["pixels"] == 320
    assert computed["rel_rmse"] == pytest.approx(0.1, rel=1e-9)
    colour = pytest.importorskip("colour")
    inside = reference[4:20, 6:26].reshape(-1, 3)

    def lab(x):
        xyz = colour.RGB_to_XYZ(np.log1p(x), colour.RGB_COLOURSPACES["sRGB"],
                                apply_cctf_decoding=False)
        return colour.XYZ_to_Lab(xyz, colour.CCS_ILLUMINANTS["CIE 1931 2 Degree Standard Observer"]["D65"])
    expected = np.mean(np.linalg.norm(lab(inside * 1.1) - lab(inside), axis=1))
    assert computed["delta_e_log_mean"] == pytest.approx(expected, rel=1e-3)

    summary = loaded["summary"]["dsgplvm"]
    assert summary["references"] == 2
    assert summary["rel_rmse"]["mean"] == pytest.approx((0.1 + 0.02) / 2, rel=1e-9)
    # Coverage: bins with theta_h < 40 deg were observed, so the report says the rest is prior.
    assert "θh above 40.0° not observed: the prediction there comes from the prior" in loaded["warnings"]
    assert loaded["coverage"]["bins_observed"] == 60 and loaded["coverage"]["samples"] == 3000
    assert loaded["slice"]["rho"][70] == [None, None, None]  # NaN is null in JSON
    np.testing.assert_allclose(loaded["predictions"]["pca"]["theta_d0"],
                               predictions["pca"][:, 0, :])
    md = (out / "report.md").read_text()
    for needle in ("How to read the numbers", "θh above 40.0° not observed", "![slice](figures/slice.png)",
                   "figures/ref_ref_a.png", "| **total** | **4.62** |", "| ref_b.exr | dsgplvm | 1.50 |"):
        assert needle in md, needle


def test_report_without_references_or_slice(tmp_path):
    report = write_report(tmp_path, stages={"extract": 0.5})
    assert report["references"] == [] and report["stages"] == {"extract": 0.5}
    assert (tmp_path / "report.md").is_file() and "Stage timings" in (tmp_path / "report.md").read_text()


def test_coverage_full_and_empty():
    theta_h = np.degrees(theta_h_centres())
    full, warnings = coverage(theta_h, {"rho": np.ones((90, 3)), "n": np.full(90, 10)})
    assert warnings == [] and full["theta_h_observed_deg"] == [0.0, 90.0]
    n = np.full(90, 10)
    n[[0, 1, 30]] = 0
    info, warnings = coverage(theta_h, {"rho": np.ones((90, 3)), "n": n})
    assert info["bins_observed"] == 87 and len(warnings) == 2  # the peak, and one gap
    _, warnings = coverage(theta_h, {"rho": np.full((90, 3), np.nan), "n": np.zeros(90)})
    assert "prior" in warnings[0]


def test_image_errors_without_mask_uses_finite_nonzero_pixels():
    reference, _ = _images()
    render = reference.copy()
    render[0, 0] = np.nan
    reference[1, 1] = 0.0
    render[1, 1] = 0.0
    _, mean, median, rel, pixels = image_errors(render, reference)
    assert pixels == 24 * 32 - 2 and mean == 0.0 and rel == 0.0


def test_report_tolerates_missing_metrics_and_3d_inputs(tmp_path):
    """What `run` hands over: a reference without a photo (metrics None), 3D tables, 3D variance."""
    from flashbrdf.brdf.views import table_3d_from_2d
    observed, predictions = _slice_and_tables()
    table_3d = table_3d_from_2d(predictions["pca"])
    variance_3d = np.where(np.isfinite(table_3d), 0.5, np.nan)
    reference, mask = _images()
    refs = [{"photo": "ref_env", "method": "dsgplvm", "render": reference,
             "delta_e_log_mean": None, "rel_rmse": None},
            {"photo": "ref_b", "method": "dsgplvm", "delta_e_log_mean": 2.0, "rel_rmse": 0.25}]
    report = write_report(tmp_path, stages={"extract": 1.0}, references=refs, observed=observed,
                          predictions={"dsgplvm": {"table": table_3d, "variance": variance_3d}})
    rows = json.loads((tmp_path / "report.json").read_text())["references"]
    assert rows[0]["delta_e_log_mean"] is None and rows[1]["delta_e_log_mean"] == 2.0
    assert report["summary"]["dsgplvm"]["delta_e_log_mean"]["mean"] == 2.0  # NaN ignored
    assert report["predictions"]["dsgplvm"]["variance_mean"] == 0.5
    np.testing.assert_allclose(report["predictions"]["dsgplvm"]["theta_d0"],
                               predictions["pca"][:, 0, :])
    assert (tmp_path / "figures" / "brdf_dsgplvm.png").is_file()
    assert (tmp_path / "figures" / "ref_ref_env.png").is_file()


def test_level_note_only_when_every_method_shares_the_offset():
    """The level check speaks when every method's level is beyond 3% the same way in every
    channel (the DiLiGenT ball: 1.04-1.07 for all; pot2 0.89-0.96), and not when the methods
    disagree (the sample capture: 0.92-2.35 across methods) or stay within 3%."""
    from flashbrdf.pipeline.report import level_note

    def summary(*levels):
        return {f"m{k}": {"level_ratio_rgb": list(v)} for k, v in enumerate(levels)}
    note = level_note(summary((1.04, 1.05, 1.06), (1.045, 1.05, 1.06)))
    assert note is not None and "4–6% brighter than every method's renders" in note
    assert "darker" in level_note(summary((0.9, 0.92, 0.95), (0.8, 0.9, 0.96)))
    assert level_note(summary((1.04, 1.05, 1.06), (0.99, 1.05, 1.06))) is None   # one disagrees
    assert level_note(summary((1.02, 1.02, 1.02), (1.025, 1.01, 1.0))) is None   # within 3%
    assert level_note(summary((1.1, 1.1, None), (1.1, 1.1, 1.1))) is None        # unknown channel
    assert level_note({"m": {}}) is None                                          # no photo
    single = level_note(summary((1.2, 1.2, 1.2)))
    assert single.startswith("**Level check:** the reference photos are 20% brighter than the "
                             "renders") and "Either this method's BRDF is off" in single
    # an entry without a level (an export's fit of the same table) is not a second method
    with_export = {**summary((1.2, 1.2, 1.2)), "m0-principled": {"references": 1}}
    assert level_note(with_export) == single


def test_report_levels_are_medians_over_photos_and_the_note_is_written(tmp_path):
    """3 photos x 2 methods: the summary's level is the per-channel median over the photos (not
    the mean, not the first photo), a method whose photos have no level shows '–, –, –' and does
    not count, and report.md carries the note when the levels agree beyond 3%."""
    levels = {"a": [(1.10, 1.2, 1.05), (1.06, 1.0, 1.04), (1.20, 1.1, 1.30)],
              "b": [(1.05, 1.05, 1.05), (1.08, 1.08, 1.08), (1.07, 1.07, 1.07)]}
    rows = [{"photo": f"p{k}", "method": m, "delta_e_log_mean": 1.0, "rel_rmse": 0.1,
             "level_ratio_rgb": list(v)} for m, vs in levels.items() for k, v in enumerate(vs)]
    rows += [{"photo": f"p{k}", "method": "c", "delta_e_log_mean": 1.0, "rel_rmse": 0.1,
              "level_ratio_rgb": [float("nan")] * 3} for k in range(3)]
    report = write_report(tmp_path, stages={"x": 1.0}, references=rows)
    assert np.allclose(report["summary"]["a"]["level_ratio_rgb"], [1.10, 1.1, 1.05])
    assert np.allclose(report["summary"]["b"]["level_ratio_rgb"], [1.07, 1.07, 1.07])
    text = (tmp_path / "report.md").read_text()
    assert "| 1.10, 1.10, 1.05 |" in text and "| –, –, – |" in text
    # c has no finite level, so the check is over a and b alone: 5-10% brighter for both
    assert report["summary"]["c"]["level_ratio_rgb"] == [None, None, None]
    assert "**Level check:** the reference photos are 5–10% brighter than every method's" in text


def test_level_matched_error_removes_one_shared_offset(tmp_path):
    """Renders 10% too dark everywhere (a light calibrated 10% low): the calibrated ΔE-log is
    positive, the level-matched one 0 (renders x 1.1 are the photos), and a render whose shape is
    wrong keeps an error after the match."""
    from flashbrdf.pipeline.report import write_report
    rng = np.random.default_rng(0)
    photos = [rng.uniform(0.1, 2.0, (8, 8, 3)) for _ in range(3)]
    mask = np.ones((8, 8), bool)

    def row(photo, k, render, method):
        from flashbrdf.render.compare import compare_images, level_ratio
        metrics, _ = compare_images(render, photo, mask)
        return {"photo": f"p{k}", "method": method, "render": render, "reference": photo,
                "mask": mask, "compare_mask": mask, **metrics,
                "level_ratio_rgb": level_ratio(render, photo, mask).tolist()}

    rows = [row(p, k, p / 1.1, "dark") for k, p in enumerate(photos)]
    rows += [row(p, k, p[::-1] / 1.1, "wrong") for k, p in enumerate(photos)]
    report = write_report(tmp_path, stages={"x": 1.0}, references=rows)
    dark, wrong = report["summary"]["dark"], report["summary"]["wrong"]
    assert dark["delta_e_log_mean"]["mean"] > 0.5
    assert dark["level_matched"]["scale"] == pytest.approx(1.1, rel=1e-9)
    assert dark["level_matched"]["delta_e_log_mean"]["mean"] == pytest.approx(0.0, abs=1e-9)
    assert wrong["level_matched"]["delta_e_log_mean"]["mean"] > 1.0
    assert "level-matched" in (tmp_path / "report.md").read_text()


def test_photos_with_dots_get_a_figure_each_and_missing_photos_are_not_counted(tmp_path):
    """run names rows by the photo's stem: ref.dir and ref.cam2 both became figures/ref_ref.png
    (one overwrote the other). A reference photo missing on disk is rendered but not compared:
    the summary said "over 3 references" with the mean over 2."""
    reference, mask = _images()
    refs = [{"photo": "ref.dir", "method": "pca", "render": reference * 1.1,
             "reference": reference, "mask": mask},
            {"photo": "ref.cam2", "method": "pca", "render": reference * 0.9,
             "reference": reference, "mask": mask},
            {"photo": "ref_missing", "method": "pca", "render": reference,
             "delta_e_log_mean": None, "rel_rmse": None}]
    # shot.png.exr's stem is shot.png: its figure was shot.exr's, figures/ref_shot.png
    refs += [{"photo": stem, "method": "pca", "render": reference * k, "reference": reference,
              "mask": mask} for stem, k in (("shot.png", 1.2), ("shot", 0.8))]
    report = write_report(tmp_path / "out", stages={"render": 1.0}, references=refs)
    figures = report["figures"]["references"]
    assert figures["ref.dir"] == "figures/ref_ref.dir.png"
    assert figures["ref.cam2"] == "figures/ref_ref.cam2.png"
    assert len(set(figures.values())) == len(figures) == 5
    assert all((tmp_path / "out" / f).is_file() for f in figures.values())
    assert report["summary"]["pca"]["references"] == 4


def test_a_reference_figure_of_a_large_photo_is_drawn_from_block_averages(tmp_path):
    """A 24 MP photo's panels were tone-mapped in float64 at full size (2 GB a panel, the peak
    of `run`'s report): images past 1024 px are block-averaged first. For a 2400 x 3000 photo
    and one render, the figure's memory peak stays under four of its float32 images (the
    average's copy of an image, its finite mask as float32, their sums), where the float64 tone
    map took eleven."""
    import tracemalloc
    from flashbrdf.pipeline.report_figures import reference_figure
    rng = np.random.default_rng(0)
    photo = rng.random((2400, 3000, 3)).astype(np.float32)
    render = photo * np.float32(0.9)
    delta_e = rng.random((2400, 3000)).astype(np.float32)
    tracemalloc.start()
    try:
        reference_figure(tmp_path / "ref.png", "ref", photo, {"m": render}, {"m": delta_e},
                         {"m": 1.0})
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert (tmp_path / "ref.png").stat().st_size > 10_000
    assert peak < 4 * photo.nbytes, peak / photo.nbytes
