"""compare: log-CIELAB Delta E and relative RMSE on hand-computed images; the compare command."""

import json

import numpy as np
import pytest

from flashbrdf.cli.main import main
from flashbrdf.render.compare import compare_images
from flashbrdf.render.images import read_image, write_exr, write_png


def _lstar(y):
    """CIE 1976 L* of luminance y (white Y = 1), by hand."""
    d = 6 / 29
    f = np.where(y > d ** 3, np.cbrt(y), y / (3 * d * d) + 4 / 29)
    return 116 * f - 16


def test_grey_images_by_hand():
    ref = np.full((4, 5, 3), 0.5)
    pred = np.full((4, 5, 3), 1.0)
    metrics, delta_e = compare_images(pred, ref)
    # grey stays grey in CIELAB (a* = b* = 0), so Delta E is the L* step of ln(1 + value)
    expected = _lstar(np.log(2.0)) - _lstar(np.log(1.5))
    assert np.allclose(delta_e, expected, rtol=1e-6)   # the sRGB matrix rounds white to ~1e-9
    assert metrics["delta_e_log_mean"] == pytest.approx(expected, rel=1e-6)
    assert metrics["delta_e_log_median"] == pytest.approx(expected, rel=1e-6)
    assert metrics["rel_rmse"] == pytest.approx(1.0, rel=1e-12)      # pred = 2 ref
    assert metrics["pixels"] == 20
    same, _ = compare_images(ref, ref)
    assert same["delta_e_log_mean"] == 0 and same["rel_rmse"] == 0


def test_valid_pixels_and_mask():
    ref = np.full((2, 3, 3), 0.5)
    pred = np.full((2, 3, 3), 0.5)
    pred[0, 0] = 0.0            # zero in pred: not compared without a mask
    ref[0, 1] = np.nan          # non-finite: never compared
    pred[1, 2] = 1.0            # the only differing compared pixel
    metrics, delta_e = compare_images(pred, ref)
    assert metrics["pixels"] == 4
    step = _lstar(np.log(2.0)) - _lstar(np.log(1.5))
    assert metrics["delta_e_log_mean"] == pytest.approx(step / 4)
    assert metrics["delta_e_log_median"] == pytest.approx(0.0, abs=1e-12)
    assert metrics["rel_rmse"] == pytest.approx(np.sqrt(3 * 0.25 / (4 * 3 * 0.25)))
    assert np.isnan(delta_e[0, 0]) and np.isnan(delta_e[0, 1])
    mask = np.zeros((2, 3), bool)
    mask[0, 0] = mask[1, 2] = True   # with a mask, the zero pixel counts (as a real error)
    metrics, _ = compare_images(pred, ref, mask)
    assert metrics["pixels"] == 2
    zero_step = _lstar(np.log(1.5)) - _lstar(0.0)
    assert metrics["delta_e_log_mean"] == pytest.approx((step + zero_step) / 2)
    empty, _ = compare_images(np.zeros((2, 2, 3)), np.zeros((2, 2, 3)))
    assert empty["pixels"] == 0 and empty["delta_e_log_mean"] is None


def test_compare_command(tmp_path, capsys):
    rng = np.random.default_rng(0)
    ref = rng.random((16, 20, 3)).astype(np.float32) + 0.1
    pred = ref * 1.1
    write_exr(tmp_path / "pred.exr", pred)
    write_exr(tmp_path / "ref.exr", ref)
    assert np.array_equal(read_image(tmp_path / "pred.exr"), pred)
    mask = np.zeros((16, 20, 3), np.uint8)
    mask[4:12, 5:15] = 255
    write_png(tmp_path / "mask.png", mask)
    out = tmp_path / "out"
    assert main(["compare", str(tmp_path / "pred.exr"), str(tmp_path / "ref.exr"),
                 "--mask", str(tmp_path / "mask.png"), "--out", str(out)]) == 0
    result = json.loads((out / "compare.json").read_text())
    assert set(result) >= {"delta_e_log_mean", "delta_e_log_median", "rel_rmse", "pixels"}
    assert result["pixels"] == 80
    assert result["rel_rmse"] == pytest.approx(0.1, rel=1e-5)
    expected, _ = compare_images(pred, ref, mask[..., 0] > 0)
    assert result["delta_e_log_mean"] == pytest.approx(expected["delta_e_log_mean"])
    assert (out / "delta_e.png").stat().st_size > 1000
    # bad input: exit 2, one line naming the file, nothing written
    bad = tmp_path / "bad"
    write_exr(tmp_path / "small.exr", ref[:8])
    assert main(["compare", str(tmp_path / "pred.exr"), str(tmp_path / "small.exr"),
                 "--out", str(bad)]) == 2
    assert main(["compare", str(tmp_path / "nope.exr"), str(tmp_path / "ref.exr"),
                 "--out", str(bad)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and "small.exr" in err[0] and "nope.exr" in err[1]
    assert not bad.exists() or not any(bad.iterdir())


def test_compare_a_black_prediction_has_null_metrics(tmp_path):
    """Without a mask the contract compares the pixels finite and nonzero in both images: a
    black prediction leaves none, a valid (bad) prediction, so the metrics are null over 0
    pixels and the exit is 0, as render and run write them; a black reference is bad input."""
    ref = np.full((8, 10, 3), 0.3, np.float32)
    write_exr(tmp_path / "black.exr", np.zeros_like(ref))
    write_exr(tmp_path / "ref.exr", ref)
    out = tmp_path / "out"
    assert main(["compare", str(tmp_path / "black.exr"), str(tmp_path / "ref.exr"),
                 "--out", str(out)]) == 0
    result = json.loads((out / "compare.json").read_text())
    assert result == {"delta_e_log_mean": None, "delta_e_log_median": None, "rel_rmse": None,
                      "pixels": 0}
    assert main(["compare", str(tmp_path / "ref.exr"), str(tmp_path / "black.exr"),
                 "--out", str(tmp_path / "out2")]) == 2
    assert not (tmp_path / "out2").exists()


def test_level_ratio_is_the_ratio_of_sums_over_the_compared_pixels():
    """sum(ref) / sum(pred) per channel over mask & finite, computed by hand on a photo whose
    per-pixel ratio spreads (lognormal, sigma 0.3) around 1.1 / 1.0 / 0.9: a median of per-pixel
    ratios differs from it by several percent, and reading the 3/4 of the image
    outside the mask (photo 100x brighter there) or a NaN pixel would change it by far more."""
    from flashbrdf.render.compare import level_ratio
    rng = np.random.default_rng(3)
    pred = rng.uniform(0.1, 2.0, (20, 30, 3))
    ref = pred * np.array([1.1, 1.0, 0.9]) * rng.lognormal(0.0, 0.3, pred.shape)
    mask = np.zeros((20, 30), bool)
    mask[15:] = True                      # 150 of 600 pixels compared
    ref[:15] *= 100.0
    ref[19, 0] = np.nan                   # not finite: not compared
    used = mask.copy()
    used[19, 0] = False
    expected = ref[used].sum(axis=0) / pred[used].sum(axis=0)
    level = level_ratio(pred, ref, mask.astype(np.uint8))       # a 0/1 mask reads as bool
    assert np.allclose(level, expected, rtol=1e-12)
    per_pixel_median = np.median(ref[used] / pred[used], axis=0)
    assert np.all(np.abs(per_pixel_median / expected - 1) > 0.01)   # the test tells them apart
    pred[..., 2] = 0.0                    # a black render in B: no level there
    level = level_ratio(pred, ref, mask)
    assert np.isnan(level[2]) and np.allclose(level[:2], expected[:2], rtol=1e-12)


def test_a_preview_is_tone_mapped_in_float32_blocks_within_one_code_of_float64():
    """A 24 MP preview took 3.6 GB of float64 copies; now float32, 256 rows at a time: within
    one 8-bit code of the float64 formula (x / (1 + x/4) * 1.25, sRGB; exposure from the 99th
    percentile of the finite positive luminances), and the memory peak under 3 times the float32
    input (luminance, its positive part and the percentile's copy of it, a third each; the uint8
    out; a block's temporaries), where float64 copies of the whole image took 13."""
    import tracemalloc
    from flashbrdf.brdf.colour import srgb_encode
    from flashbrdf.render.images import tonemap
    rng = np.random.default_rng(0)
    image = (rng.random((900, 1200, 3)) ** 4 * 5).astype(np.float32)
    image[0, 0], image[1, 1], image[2, 2] = np.nan, np.inf, -1.0
    tracemalloc.start()
    try:
        got = tonemap(image)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    x = np.maximum(np.nan_to_num(image.astype(np.float64), nan=0, posinf=0, neginf=0), 0)
    lum = x @ np.array([0.2126, 0.7152, 0.0722])
    x = x / np.percentile(lum[lum > 0], 99)
    x = np.clip(x / (1 + x / 4) * 1.25, 0, 1)
    want = (np.clip(srgb_encode(x), 0, 1) * 255 + 0.5).astype(np.uint8)
    assert np.abs(got.astype(int) - want).max() <= 1 and got[1, 1].tolist() == [0, 0, 0]
    assert peak < 3 * image.nbytes, peak / image.nbytes


def test_a_comparison_lets_its_images_go(tmp_path):
    """At 24 MP `run` peaked at 6.3 GB in its compares: whole-image float64 copies of the render
    and the photo (1.15 GB) where only the object's pixels are compared, and the ΔE figure's
    mathtext left a reference cycle holding every earlier photo's render, map and masks until a
    full garbage collection. A 1000 x 1500 compare over a tenth of the image now peaks under three
    of its float32 images (six before), and its ΔE map is freed on return, the collector off."""
    import gc
    import tracemalloc
    import weakref
    from flashbrdf.render.compare import write_comparison
    rng = np.random.default_rng(0)
    ref = rng.random((1000, 1500, 3), dtype=np.float32) + np.float32(0.1)
    pred = ref * np.float32(1.1)
    mask = np.zeros((1000, 1500), bool)
    mask[:100] = True
    tracemalloc.start()
    metrics, delta_e = compare_images(pred, ref, mask)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert metrics["pixels"] == mask.sum() and peak < 3 * ref.nbytes, peak / ref.nbytes
    gc.disable()
    try:
        def compare_once():
            _, kept = write_comparison(tmp_path, pred, ref, mask, return_map=True)
            return weakref.ref(kept)
        # every call: the first collects matplotlib's one-off font-parsing cycle, later ones
        # must make none (a mathtext label made one at every figure)
        assert [compare_once()() is None for _ in range(3)] == [True] * 3
    finally:
        gc.enable()
