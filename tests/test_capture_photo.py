"""capture: photo formats, usable/clipped masks, brackets, RAW, ambient removal, real files."""

import json
import subprocess
import sys
import warnings
from pathlib import Path

import cv2
import numpy as np
import pytest

from flashbrdf import capture
from flashbrdf.files.errors import InputError
from conftest import shared_path
from synthetic import write_exr


def test_exr_roundtrip_and_masks(tmp_path):
    img = np.full((4, 5, 3), 0.5, np.float32)
    img[0, 0] = [np.nan, 1, 1]
    img[0, 1] = [np.inf, 1, 1]
    img[0, 2] = [-0.1, 1, 1]   # negative noise about a dim level is data (a flash − ambient EXR)
    img[0, 3] = 0.0
    img[0, 4] = [0.0, 0.2, 0.0]  # one dark channel is still data in a float image
    img[1, 0] = [7.0, 1, 1]
    write_exr(tmp_path / "a.exr", img)
    rgb, usable, clipped = capture.load_photo(tmp_path / "a.exr", saturation=5.0,
                                              return_clipped=True)
    assert rgb.dtype == np.float32 and rgb.shape == (4, 5, 3)
    assert np.array_equal(rgb[1:], img[1:]) and rgb[1, 0, 0] == 7.0  # never clamped
    assert usable.tolist()[0] == [False, False, True, False, True]
    assert not usable[1, 0] and clipped[1, 0] and clipped[0, 1] and not clipped[0, 0]
    assert usable[1:].sum() == 14


@pytest.mark.parametrize("saturation, largest_usable", [(np.finfo(np.float32).max, False),
                                                        (1e39, True), (1e300, True)])
def test_saturation_up_to_and_past_float32(tmp_path, saturation, largest_usable):
    """A ceiling at FLT_MAX clips a FLT_MAX pixel (">= saturation"); one past float32 means "no
    ceiling": only +Inf is clipped, and casting it to float32 raises no overflow warning."""
    img = np.full((1, 3, 3), 0.5, np.float32)
    img[0, 1] = np.finfo(np.float32).max
    img[0, 2] = [np.inf, 1, 1]
    write_exr(tmp_path / "a.exr", img)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        _, usable, clipped = capture.load_photo(tmp_path / "a.exr", saturation=float(saturation),
                                                return_clipped=True)
    assert usable[0].tolist() == [True, largest_usable, False]
    assert clipped[0].tolist() == [False, not largest_usable, True]


def test_pfm_rows_are_top_first(tmp_path):
    img = np.zeros((4, 5, 3), np.float32)
    img[0, :, 0] = 1.0
    with open(tmp_path / "a.pfm", "wb") as f:  # PFM stores rows bottom to top
        f.write(b"PF\n5 4\n-1.0\n" + img[::-1].astype("<f4").tobytes())
    rgb, _ = capture.load_photo(tmp_path / "a.pfm")
    assert np.array_equal(rgb, img)


def test_png16_is_linear_16_bit(tmp_path):
    codes = np.array([[[0, 100, 200], [1000, 30000, 65535], [12345, 54321, 60000]]], np.uint16)
    cv2.imwrite(str(tmp_path / "a.png"), codes[..., ::-1])
    rgb, usable, clipped = capture.load_photo(tmp_path / "a.png", return_clipped=True)
    assert np.allclose(rgb * 65535, codes, atol=1e-2)  # linear, all 16 bits kept
    # code 0 is at the black level; >= 98% of 65535 (64224) is clipped
    assert usable.tolist() == [[False, False, True]] and clipped.tolist() == [[False, True, False]]


def test_png8_srgb_decoding(tmp_path):
    codes = np.array([[[10, 128, 255], [200, 1, 64]]], np.uint8)
    cv2.imwrite(str(tmp_path / "a.png"), codes[..., ::-1])
    rgb, usable = capture.load_photo(tmp_path / "a.png", encoding="srgb")
    c = codes / 255.0
    expected = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    assert np.allclose(rgb, expected, atol=1e-6)
    assert usable.tolist() == [[False, True]]  # 255 is clipped
    linear, _ = capture.load_photo(tmp_path / "a.png", encoding="linear")
    assert np.allclose(linear, c, atol=1e-6)


def test_linear_brackets_recover_radiance(tmp_path):
    """16-bit brackets 1/16 s and 1 s of radiance up to 12 per second: the long one clips the
    bright half, the short one is coarse in the dark; the merge keeps each where it is usable."""
    radiance = np.geomspace(0.01, 12, 300).reshape(20, 15, 1).repeat(3, -1)
    entries = []
    for k, t in enumerate((1 / 16, 1.0)):
        codes = np.clip(np.round(radiance * t * 65535 / 1.0), 0, 65535).astype(np.uint16)
        cv2.imwrite(str(tmp_path / f"b{k}.png"), codes[..., ::-1])
        entries.append((tmp_path / f"b{k}.png", t))
    rgb, usable = capture.load_brackets(entries)
    assert usable.all()
    # worst case: a pixel seen only at 1/16 s with code ~ 0.01 / 16 * 65535 = 41 -> 1.2% rounding
    assert np.abs(rgb / radiance - 1).max() < 0.013


def test_8bit_brackets_without_an_encoding_are_read_as_srgb_like_one_8bit_photo(tmp_path):
    """An 8-bit photo without `encoding` is sRGB; its brackets were merged through a Debevec
    response of arbitrary scale instead (4.6 times the truth, and another scale for each photo),
    while the slice's level was reported absolute. Read as sRGB they give radiance per second of
    exposure over 3 decades."""
    rng = np.random.default_rng(1)
    radiance = np.exp(rng.uniform(np.log(0.01), np.log(10), (64, 64, 3)))
    c = np.clip(radiance[None] * np.array([1 / 64, 1 / 16, 1 / 4, 1])[:, None, None, None], 0, 1)
    srgb = np.where(c <= 0.0031308, 12.92 * c, 1.055 * c ** (1 / 2.4) - 0.055)
    entries = []
    for k, t in enumerate((1 / 64, 1 / 16, 1 / 4, 1.0)):
        cv2.imwrite(str(tmp_path / f"b{k}.jpg.png"), np.round(srgb[k] * 255).astype(np.uint8)
                    [..., ::-1])
        entries.append((tmp_path / f"b{k}.jpg.png", t))
    rgb, usable = capture.load_brackets(entries)
    ratio = rgb[usable] / radiance[usable]
    assert usable.mean() > 0.99
    assert abs(np.median(ratio) - 1) < 0.01
    # as test_8bit_brackets_with_encoding_keep_absolute_radiance's sRGB case
    assert np.percentile(np.abs(ratio - 1), 95) < 0.05


def test_8bit_brackets_with_encoding_keep_absolute_radiance(tmp_path):
    """8-bit brackets whose `encoding` is given are linearised by it (the contract's photo
    formats): radiance per second of exposure comes back in absolute units."""
    rng = np.random.default_rng(2)
    radiance = np.exp(rng.uniform(np.log(0.01), np.log(2), (32, 32, 3)))
    times = (0.25, 1.0, 4.0)
    for encoding in ("srgb", "linear"):
        entries = []
        for k, t in enumerate(times):
            c = np.clip(radiance * t, 0, 1)
            if encoding == "srgb":
                c = np.where(c <= 0.0031308, 12.92 * c, 1.055 * c ** (1 / 2.4) - 0.055)
            path = tmp_path / f"{encoding}{k}.png"
            cv2.imwrite(str(path), np.round(c * 255).astype(np.uint8)[..., ::-1])
            entries.append((path, t))
        rgb, usable = capture.load_brackets(entries, encoding=encoding)
        ratio = rgb[usable] / radiance[usable]
        assert usable.mean() > 0.99
        assert abs(np.median(ratio) - 1) < 0.01, encoding
        # 8-bit linear codes are coarse in the dark (a code of 1 or 2 at 1/4 s): a wider spread
        assert np.percentile(np.abs(ratio - 1), 95) < (0.05 if encoding == "srgb" else 0.2)


def test_brackets_with_an_encoding_are_decoded_once(tmp_path, monkeypatch):
    """8-bit brackets with an `encoding` were decoded twice (once to choose the merge, again by
    load_photo): each file is now decoded once, and the merge is the one of the photos as
    load_photo reads them, to float32's rounding of a sum of three (clipped and dark pixels
    included): the merge sums one bracket at a time in float32."""
    import flashbrdf.capture.photo as photo
    rng = np.random.default_rng(3)
    radiance = np.exp(rng.uniform(np.log(0.001), np.log(8), (12, 10, 3)))
    radiance[0, :3] = 20.0  # clipped even at 1/8 s
    entries = []
    for k, t in enumerate((0.125, 1.0, 4.0)):  # exact in float32 too
        c = np.clip(radiance * t, 0, 1)
        srgb = np.where(c <= 0.0031308, 12.92 * c, 1.055 * c ** (1 / 2.4) - 0.055)
        cv2.imwrite(str(tmp_path / f"b{k}.png"), np.round(srgb * 255).astype(np.uint8)[..., ::-1])
        entries.append((tmp_path / f"b{k}.png", t))
    decoded = []
    real_imread = photo.cv2.imread
    monkeypatch.setattr(photo.cv2, "imread", lambda *a: decoded.append(a[0]) or real_imread(*a))
    rgb, usable, clipped = capture.load_brackets(entries, encoding="srgb", return_clipped=True)
    assert decoded == [str(path) for path, _ in entries]
    photos = [capture.load_photo(path, "srgb", return_clipped=True) for path, _ in entries]
    total = sum(np.where(u[..., None], x, 0).astype(np.float64) for x, u, _ in photos)
    exposure = sum(u * t for (_, u, _), (_, t) in zip(photos, entries))
    seen = exposure > 0  # elsewhere the shortest exposure's value, flagged unusable
    expected = np.where(seen[..., None], total / np.where(seen, exposure, 1)[..., None],
                        photos[0][0] / 0.125).astype(np.float32)
    assert 0 < usable.mean() < 1 and clipped.any()  # dark, clipped and merged pixels all present
    assert np.array_equal(usable, seen)
    assert np.array_equal(clipped, photos[0][2] & photos[1][2] & photos[2][2])
    assert rgb.dtype == np.float32 and np.allclose(rgb, expected, rtol=4 * 2.0 ** -24, atol=0)


def test_size_missing_and_corrupt_files(tmp_path):
    write_exr(tmp_path / "a.exr", np.ones((4, 5, 3)))
    with pytest.raises(InputError, match=r"a.exr: image is 5x4 but the camera is 6x4"):
        capture.load_photo(tmp_path / "a.exr", shape=(4, 6))
    with pytest.raises(InputError, match="none.exr: file not found"):
        capture.load_photo(tmp_path / "none.exr")
    (tmp_path / "dir.exr").mkdir()
    with pytest.raises(InputError, match="dir.exr: is a folder, not a file"):
        capture.load_photo(tmp_path / "dir.exr")
    (tmp_path / "bad.exr").write_bytes(b"not an exr")
    with pytest.raises(InputError, match="bad.exr: cannot read image"):
        capture.load_photo(tmp_path / "bad.exr")
    (tmp_path / "bad.png").write_bytes(b"\x89PNG broken")
    with pytest.raises(InputError, match="bad.png: cannot read image"):
        capture.load_photo(tmp_path / "bad.png")
    (tmp_path / "bad.dng").write_bytes(b"II*\x00 broken")
    with pytest.raises(InputError, match="bad.dng: cannot read RAW"):
        capture.load_photo(tmp_path / "bad.dng")


def test_damaged_exr_whose_error_message_is_not_utf8(tmp_path):
    """OpenImageIO quotes a damaged header's bytes in its message (here a channel-list type
    name running into byte 0xd5), and its binding then raises UnicodeDecodeError: the reader
    still gives one InputError naming the file (found by fuzzing compare)."""
    from flashbrdf.render.images import image_channel_names, read_mask
    write_exr(tmp_path / "a.exr", np.ones((4, 5, 3)))
    data = bytearray((tmp_path / "a.exr").read_bytes())
    data[data.index(b"chlist\x00") + 6] = 0xD5
    (tmp_path / "a.exr").write_bytes(bytes(data))
    with pytest.raises(InputError, match=r"a.exr: cannot read image: \(the library's message is "
                                         r"not UTF-8 text\)"):
        capture.load_photo(tmp_path / "a.exr")
    assert image_channel_names(tmp_path / "a.exr") == []
    with pytest.raises(InputError, match=r"a.exr: cannot read mask"):
        read_mask(tmp_path / "a.exr")


def test_image_over_opencvs_size_limit_is_named_with_the_limit(tmp_path):
    """cv2.imread raises (not None) past its limits: the one line names the file and the limit it
    exceeds, not "cannot read image (corrupt or unsupported)"."""
    from corpus_inputs import png_bomb
    big = tmp_path / "big.png"
    big.write_bytes(png_bomb(40000))
    with pytest.raises(InputError) as err:
        capture.load_photo(big, encoding="linear")
    assert str(err.value) == (f"{big}: image is over OpenCV's limit of 1073741824 pixels "
                              "(OPENCV_IO_MAX_IMAGE_PIXELS)")
    # the limit as OpenCV read it from its variable (a PNG too wide is refused by libpng first,
    # as unreadable, so the width limit is seen only from other formats); other errors are not
    # limits
    from flashbrdf.capture.photo import opencv_size_limit
    assert opencv_size_limit("pixels <= CV_IO_MAX_IMAGE_PIXELS",
                             {"OPENCV_IO_MAX_IMAGE_PIXELS": "4096"}) == \
        "4096 pixels (OPENCV_IO_MAX_IMAGE_PIXELS)"
    assert opencv_size_limit("static_cast<size_t>(size.width) <= CV_IO_MAX_IMAGE_WIDTH", {}) == \
        "1048576 pixels wide (OPENCV_IO_MAX_IMAGE_WIDTH)"
    assert opencv_size_limit("(-215:Assertion failed) size.width > 0") is None


def test_exr_loading_never_imports_rawpy(tmp_path):
    write_exr(tmp_path / "a.exr", np.ones((2, 2, 3)))
    code = ("import sys, capture; capture.load_photo(sys.argv[1]); "
            "print('rawpy' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code, str(tmp_path / "a.exr")],
                         capture_output=True, text=True, check=True,
                         cwd=Path(__file__).resolve().parents[1])
    assert out.stdout.strip() == "False"


def test_ambient_subtraction_and_scale(tmp_path):
    flash = np.full((3, 4, 3), 0.9, np.float32)
    flash[0, 0] = np.nan
    ambient = np.full((3, 4, 3), 0.1, np.float32)
    ambient[1, 1] = np.inf
    write_exr(tmp_path / "f.exr", flash)
    write_exr(tmp_path / "a.exr", ambient)
    doc = {"camera": {"model": "orthographic", "width": 4, "height": 3, "pixel_size": 1,
                      "world_from_camera": np.eye(4).tolist()},
           "geometry": {"mesh": "m.ply"},
           "photos": [{"file": "f.exr", "role": "flash", "scale": 4.0,
                       "light": {"type": "directional", "direction": [0, 0, -1],
                                 "irradiance_rgb": [1, 1, 1]}},
                      {"file": "a.exr", "role": "ambient"}]}
    (tmp_path / "scene.json").write_text(json.dumps(doc))
    (img,) = capture.load_flash_images(capture.load_scene(tmp_path))
    assert np.allclose(img.radiance[2, 2], 0.2)  # (0.9 - 0.1) / 4
    assert not img.usable[0, 0] and not img.usable[1, 1] and img.usable.sum() == 10
    # an ambient photo with its own scale is in its own units: flash/4 - ambient/0.5
    doc["photos"][1]["scale"] = 0.5
    (tmp_path / "scene.json").write_text(json.dumps(doc))
    (img,) = capture.load_flash_images(capture.load_scene(tmp_path))
    assert np.allclose(img.radiance[2, 2], 0.9 / 4 - 0.1 / 0.5)


GREY_PATCHES = {"white": 704, "n8": 814, "n6.5": 924}  # columns on row 930 (found by eye)


def test_colorchart_dng_grey_patches_neutral():
    """The real Canon DNG decodes linearly: after white balancing on the N8 grey patch, the
    white and N6.5 patches are neutral within 5% (a gamma, a wrong black level or clipping would
    tint them). The camera's as-shot balance itself does not neutralise this scene, which is lit
    by warm light (its grey patches come out with R/G ~ 2.2)."""
    path = shared_path("data", "real", "raw", "colorchart.dng")
    rgb, usable = capture.load_photo(path)
    assert rgb.shape == (1156, 1734, 3) and rgb.dtype == np.float32
    means = {name: rgb[915:945, x - 15:x + 15].reshape(-1, 3).mean(0)
             for name, x in GREY_PATCHES.items()}
    assert all(usable[915:945, x - 15:x + 15].all() for x in GREY_PATCHES.values())
    gains = means["n8"].mean() / means["n8"]
    for name in ("white", "n6.5"):
        balanced = means[name] * gains
        assert np.abs(balanced / balanced.mean() - 1).max() < 0.05, name
    # linear: white (~90% reflectance) over N6.5 (~36%) is about 2.5 (a gamma would give ~1.5)
    assert 2.0 < means["white"].mean() / means["n6.5"].mean() < 3.0


def test_colorchart_dng_red_is_not_clipped_before_its_sensels_saturate():
    """The as-shot white balance multiplies red by ~2.48 over green. No sensel of the file
    reaches 78% of the sensor's range, so at SATURATION_FRACTION (98%) no pixel is clipped; a
    16-bit decode that scales green's white level to 65535 clipped red at 1/2.48 = 40% of the
    range instead (0.15% of the pixels flagged, red capped at 1). The level is unchanged: where
    that decode did not clip, the two agree (median ratio within 0.2%: codes over 2000 carry
    16-bit rounding under 0.1%)."""
    import rawpy
    from flashbrdf.capture.photo import SATURATION_FRACTION
    from flashbrdf.capture.raw import load_raw
    path = shared_path("data", "real", "raw", "colorchart.dng")
    rgb, usable, clipped = load_raw(path, SATURATION_FRACTION)
    assert not clipped.any()
    assert rgb[..., 0].max() > 1.2   # above the old cap of 1.0
    with rawpy.imread(str(path)) as raw:
        capped = raw.postprocess(gamma=(1, 1), no_auto_bright=True, use_camera_wb=True,
                                 output_bps=16, output_color=rawpy.ColorSpace.sRGB,
                                 user_flip=None)
    inside = (capped < 65535).all(-1) & (capped > 2000).all(-1)
    ratio = np.median(rgb[inside] / (capped[inside] / 65535.0), axis=0)
    assert np.abs(ratio - 1).max() < 0.002


def _without_as_shot_balance(dng, out):
    """A copy of the DNG whose AsShotNeutral tag (50728) is renamed to an unknown one: a RAW
    file with no camera white balance (LibRaw then reads camera_whitebalance as [0, 1, 0, 0])."""
    import struct
    data = bytearray(Path(dng).read_bytes())
    order = "<" if data[:2] == b"II" else ">"
    offset = struct.unpack(order + "I", data[4:8])[0]
    while offset:
        count = struct.unpack(order + "H", data[offset:offset + 2])[0]
        for entry in range(offset + 2, offset + 2 + 12 * count, 12):
            if struct.unpack(order + "H", data[entry:entry + 2])[0] == 50728:
                struct.pack_into(order + "H", data, entry, 65000)
        after = offset + 2 + 12 * count
        offset = struct.unpack(order + "I", data[after:after + 4])[0]
    Path(out).write_bytes(bytes(data))
    return out


def test_raw_without_as_shot_balance_is_daylight_balanced_at_its_level(tmp_path):
    """A RAW with no as-shot white balance: LibRaw (>= 0.20) would balance it grey-world, whose
    multipliers the headroom did not know (colorchart.dng so stripped came out 1.222x too
    bright in every channel, and tinted by the scene). It is decoded with the daylight
    multipliers, at the level of a 16-bit decode with them where that one does not clip
    (median ratio within 0.2%, as in the test above)."""
    import rawpy
    from flashbrdf.capture.photo import SATURATION_FRACTION
    from flashbrdf.capture.raw import load_raw, white_balance
    path = _without_as_shot_balance(shared_path("data", "real", "raw", "colorchart.dng"),
                                    tmp_path / "no_wb.dng")
    rgb, usable, clipped = load_raw(path, SATURATION_FRACTION)
    with rawpy.imread(str(path)) as raw:
        assert raw.camera_whitebalance[0] == 0  # the file has no camera balance
        daylight = list(raw.daylight_whitebalance[:3]) + [raw.daylight_whitebalance[1]]
        assert np.allclose(white_balance(raw), daylight)
        capped = raw.postprocess(gamma=(1, 1), no_auto_bright=True, use_camera_wb=False,
                                 user_wb=daylight, output_bps=16,
                                 output_color=rawpy.ColorSpace.sRGB, user_flip=None)
    inside = (capped < 65535).all(-1) & (capped > 2000).all(-1)
    ratio = np.median(rgb[inside] / (capped[inside] / 65535.0), axis=0)
    assert np.abs(ratio - 1).max() < 0.002


@pytest.mark.parametrize("camera, daylight, colours, expected", [
    ([2.0, 1.0, 1.5, 1.1], [9, 9, 9, 9], 3, [2.0, 1.0, 1.5, 1.1]),  # 4 distinct: all 4 count
    ([2.0, 1.0, 1.5, 0.0], [9, 9, 9, 9], 3, [2.0, 1.0, 1.5, 1.0]),  # no 2nd green: the green
    ([2.0, 0.0, 1.5, 0.0], [9, 9, 9, 9], 3, [2.0, 1.0, 1.5, 1.0]),  # no green: 1 (LibRaw's)
    ([2.0, 0.5, 1.5, 0.0], [9, 9, 9, 9], 4, [2.0, 0.5, 1.5, 1.0]),  # 4-colour sensor: 1
    ([0.0, 1.0, 0.0, 0.0], [2.4, 0.9, 1.3, 0.0], 3, [2.4, 0.9, 1.3, 0.9]),  # none: daylight
    ([-1.0, 1.0, 1.0, 0.0], [2.4, 0.9, 1.3, 0.0], 3, [2.4, 0.9, 1.3, 0.9]),  # "auto": daylight
    ([0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0], 3, [1.0, 1.0, 1.0, 1.0]),  # neither: 1
])
def test_white_balance_picks_libraw_multipliers(camera, daylight, colours, expected):
    """The multipliers passed to LibRaw (user_wb) and whose max / min is the headroom: LibRaw's
    scale_colors rules for a missing green or fourth channel, daylight without a camera one."""
    from types import SimpleNamespace
    from flashbrdf.capture.raw import white_balance
    raw = SimpleNamespace(camera_whitebalance=camera, daylight_whitebalance=daylight,
                          num_colors=colours)
    assert white_balance(raw).tolist() == expected


def test_diligent_png_loads_as_16_bit():
    path = shared_path("data", "real", "diligent-ball", "001.png")
    rgb, usable = capture.load_photo(path)
    assert rgb.shape == (512, 612, 3)
    codes = np.round(rgb * 65535).astype(np.int64)
    # 8-bit data widened to 16 bits would only hold multiples of 257
    assert np.count_nonzero(codes % 257) > 0.5 * codes.size
    assert codes.max() <= 65535 and not usable[np.any(codes >= 65535, axis=-1)].any()


def test_exr_data_window_is_placed_in_display_window(tmp_path):
    import OpenImageIO as oiio
    spec = oiio.ImageSpec(4, 3, 3, "float")
    spec.x, spec.y, spec.full_x, spec.full_y, spec.full_width, spec.full_height = 2, 1, 0, 0, 8, 5
    out = oiio.ImageOutput.create(str(tmp_path / "w.exr"))
    out.open(str(tmp_path / "w.exr"), spec)
    out.write_image(np.full((3, 4, 3), 2.0, np.float32))
    out.close()
    rgb, usable = capture.load_photo(tmp_path / "w.exr")
    assert rgb.shape == (5, 8, 3) and np.all(rgb[1:4, 2:6] == 2.0)
    assert usable.sum() == 12 and usable[1:4, 2:6].all()


@pytest.mark.parametrize("size", [b"-2 -3", b"-1 4", b"0 5"])
def test_pfm_with_a_size_below_one_is_bad_input(tmp_path, size):
    """A PFM header's width and height must be >= 1: -2 -3 broke numpy's reshape (a traceback),
    -1 4 read a 4x4 image from the wrong bytes, 0 5 gave an empty one."""
    from flashbrdf.files.errors import InputError
    from flashbrdf.capture.photo import read_float_image
    path = tmp_path / "bad.pfm"
    path.write_bytes(b"PF\n" + size + b"\n-1.0\n" + np.zeros(60, "<f4").tobytes())
    with pytest.raises(InputError, match="bad.pfm"):
        read_float_image(path)


def test_brackets_are_merged_one_at_a_time_in_float32(tmp_path):
    """Three 16-bit brackets peaked at 13.8 times one float32 photo (every bracket decoded and
    linearised at once, then a float64 merge; 3.8 GB at 24 MP). One at a time: the decoded
    bracket, its linear copy, the float32 sum and the shortest's values, with load_photo's own
    temporaries (2.2 photos on its own): under 7."""
    import tracemalloc
    rng = np.random.default_rng(0)
    size = (200, 300)
    entries = []
    for k, t in enumerate((0.25, 1.0, 4.0)):
        image = np.clip(rng.random(size + (3,)) * t * 0.5, 0, 1)
        cv2.imwrite(str(tmp_path / f"b{k}.png"), (image * 65535).astype(np.uint16))
        entries.append((tmp_path / f"b{k}.png", t))
    tracemalloc.start()
    try:
        rgb, _ = capture.load_brackets(entries)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert rgb.dtype == np.float32 and peak < 7 * rgb.nbytes, peak / rgb.nbytes


@pytest.mark.parametrize("channels", [2, 4])
def test_a_mask_with_opaque_alpha_marks_only_its_coloured_pixels(tmp_path, channels):
    """Nonzero means object in the mask's colour channels; its alpha is not colour. A black-and-
    white mask saved with alpha 255 everywhere marked every pixel as object in the normal-map
    geometry (and in import-diligent), while `compare --mask` read the same file right."""
    from flashbrdf.capture.normal_map import load_normal_map
    import OpenImageIO as oiio
    from flashbrdf.render.images import read_mask
    inside = np.zeros((4, 6), bool)
    inside[1:3, 2:5] = True
    grey = np.where(inside, 255, 0).astype(np.uint8)
    pixels = (np.dstack([grey, np.full_like(grey, 255)]) if channels == 2 else
              np.dstack([grey, grey, grey, np.full_like(grey, 255)]))
    out = oiio.ImageOutput.create(str(tmp_path / "mask.png"))   # grey + alpha: OpenCV writes none
    out.open(str(tmp_path / "mask.png"), oiio.ImageSpec(6, 4, channels, "uint8"))
    out.write_image(pixels)
    out.close()
    np.save(tmp_path / "normals.npy", np.dstack([np.zeros((4, 6, 2)), np.ones((4, 6))]))
    (tmp_path / "scene.json").write_text(json.dumps({
        "camera": {"model": "orthographic", "width": 6, "height": 4, "pixel_size": 1.0,
                   "world_from_camera": np.eye(4).tolist()},
        "geometry": {"normal_map": "normals.npy", "mask": "mask.png"},
        "photos": [{"file": "flash.exr", "role": "flash", "light": {
            "type": "directional", "direction": [0, 0, -1], "irradiance_rgb": [1, 1, 1]}}]}))
    scene = capture.load_scene(tmp_path)
    _, mask = load_normal_map(scene.geometry, scene.camera)
    np.testing.assert_array_equal(mask, inside)
    np.testing.assert_array_equal(read_mask(tmp_path / "mask.png"), inside)
