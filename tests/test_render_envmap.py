"""Environment maps: the contract's direction convention, bilinear lookup, the luminance sampler."""

import numpy as np
import pytest

from flashbrdf.files.errors import InputError
from flashbrdf.render.envmap import EnvMap, envmap_direction, read_envmap_pixels


def _contract_pixel(d, height, width):
    """Continuous (row, col) of direction d by the contract's u, v formula (pixel centres at .5)."""
    u = 0.5 + np.arctan2(d[..., 0], -d[..., 2]) / (2 * np.pi)
    v = np.arccos(d[..., 1]) / np.pi
    return v * height, u * width


def test_direction_convention_matches_contract():
    h, w = 8, 16
    # centre of the map sees light arriving from -z, top row +y, three quarters across +x
    assert np.allclose(envmap_direction(h / 2, w / 2, h, w), [0, 0, -1], atol=1e-12)
    assert np.allclose(envmap_direction(0.0, 3.0, h, w), [0, 1, 0], atol=1e-12)
    assert np.allclose(envmap_direction(h / 2, 3 * w / 4, h, w), [1, 0, 0], atol=1e-12)
    # pixel centres round-trip through the contract's (u, v) formula
    i, j = np.meshgrid(np.arange(h) + 0.5, np.arange(w) + 0.5, indexing="ij")
    rows, cols = _contract_pixel(envmap_direction(i, j, h, w), h, w)
    assert np.allclose(rows, i, atol=1e-9) and np.allclose(cols, j, atol=1e-9)


def test_radiance_at_pixel_centres_midpoints_and_wrap():
    rng = np.random.default_rng(1)
    pixels = rng.random((8, 16, 3))
    env = EnvMap(pixels)
    i, j = np.meshgrid(np.arange(8) + 0.5, np.arange(16) + 0.5, indexing="ij")
    assert np.allclose(env.radiance(envmap_direction(i, j, 8, 16)), pixels, atol=1e-12)
    # halfway between columns 15 and 0 of row 3 (wraps in u): the mean of the two
    mid = env.radiance(envmap_direction(3.5, 16.0, 8, 16))
    assert np.allclose(mid, 0.5 * (pixels[3, 15] + pixels[3, 0]), atol=1e-12)
    # halfway between rows 2 and 3 in column 5
    mid = env.radiance(envmap_direction(3.0, 5.5, 8, 16))
    assert np.allclose(mid, 0.5 * (pixels[2, 5] + pixels[3, 5]), atol=1e-12)


def test_world_from_envmap_and_scale():
    pixels = np.random.default_rng(2).random((8, 16, 3))
    # rotation by 90 degrees about y: world +x maps to envmap -z (the map centre)
    rot = np.array([[0.0, 0, -1], [0, 1, 0], [1, 0, 0]])   # world_from_envmap, columns = env axes
    env = EnvMap(pixels, world_from_envmap=rot, scale=3.0)
    world = np.array([1.0, 0, 0])
    d = rot.T @ world
    assert np.allclose(d, [0, 0, -1])
    expected = EnvMap(pixels).radiance(d) * 3.0
    assert np.allclose(env.radiance(world), expected)


def test_sampler_pdf_is_consistent_and_unbiased():
    rng = np.random.default_rng(3)
    pixels = rng.random((16, 32, 3)) ** 4 * 50      # peaky, high dynamic range
    pixels[5, 7] = 5e4                              # a sun
    for compensate in (False, True):
        env = EnvMap(pixels, compensate=compensate)
        d, pdf = env.sample(rng.random((200_000, 2)))
        assert np.allclose(np.linalg.norm(d, axis=-1), 1.0)
        assert np.allclose(env.pdf(d), pdf)
        # pdf integrates to 1: sum over pixels of pdf x exact pixel solid angle
        i, j = np.meshgrid(np.arange(16) + 0.5, np.arange(32) + 0.5, indexing="ij")
        edges = np.cos(np.pi * np.arange(17) / 16)
        omega = (edges[:-1] - edges[1:])[:, None] * (2 * np.pi / 32) * np.ones((1, 32))
        assert np.isclose(np.sum(env.pdf(envmap_direction(i, j, 16, 32)) * omega), 1.0)
    # Without compensation every lit direction can be sampled: E[L / pdf] = integral of L.
    # The integral of the bilinear map by fine quadrature (uniform in cos theta and phi).
    env = EnvMap(pixels, compensate=False)
    n = 300_000
    d, pdf = env.sample(rng.random((n, 2)))
    estimate = np.mean(env.radiance(d) / pdf[:, None], axis=0)
    g = 512
    ct, ph = np.meshgrid((np.arange(g) + 0.5) / g * 2 - 1, (np.arange(2 * g) + 0.5) / (2 * g)
                         * 2 * np.pi - np.pi, indexing="ij")
    st = np.sqrt(1 - ct ** 2)
    grid = np.stack([np.sin(ph) * st, ct, -np.cos(ph) * st], -1).reshape(-1, 3)
    exact = env.radiance(grid).mean(axis=0) * 4 * np.pi
    # luminance sampling bounds L / pdf, so 3e5 samples give well under 1 % (measured ~0.2 %)
    assert np.allclose(estimate, exact, rtol=0.01)


def test_constant_map_needs_no_envmap_samples():
    env = EnvMap(np.full((8, 16, 3), 2.0))
    assert not env.can_sample
    assert EnvMap(np.full((8, 16, 3), 2.0), compensate=False).can_sample


def test_read_envmap_file(tmp_path):
    import OpenImageIO as oiio
    pixels = np.random.default_rng(4).random((8, 16, 3)).astype(np.float32)
    path = str(tmp_path / "map.exr")
    out = oiio.ImageOutput.create(path)
    out.open(path, oiio.ImageSpec(16, 8, 3, oiio.FLOAT))
    out.write_image(pixels)
    out.close()
    assert np.allclose(read_envmap_pixels(path), pixels)
    bad = str(tmp_path / "square.exr")
    out = oiio.ImageOutput.create(bad)
    out.open(bad, oiio.ImageSpec(8, 8, 3, oiio.FLOAT))
    out.write_image(np.zeros((8, 8, 3), np.float32))
    out.close()
    with pytest.raises(InputError, match="width = 2 x height"):
        read_envmap_pixels(bad)
    with pytest.raises(InputError):
        read_envmap_pixels(str(tmp_path / "missing.hdr"))


@pytest.mark.parametrize("negative, refused", [(-0.005, False), (-0.02, True)])
def test_envmap_negative_ringing_is_clamped_and_negative_radiance_refused(tmp_path, negative,
                                                                          refused):
    """A negative pixel within 1% of the brightest (a resampling filter's ringing) reads as 0;
    one beyond it is radiance no map holds, refused naming the file."""
    import OpenImageIO as oiio
    pixels = np.full((8, 16, 3), 0.5, np.float32)
    pixels[0, 0] = 1.0
    pixels[4, 4] = negative
    path = str(tmp_path / "map.exr")
    out = oiio.ImageOutput.create(path)
    out.open(path, oiio.ImageSpec(16, 8, 3, oiio.FLOAT))
    out.write_image(pixels)
    out.close()
    if refused:
        with pytest.raises(InputError, match="map.exr.*negative radiance \\(1 pixels"):
            read_envmap_pixels(path)
    else:
        read = read_envmap_pixels(path)
        assert np.all(read[4, 4] == 0.0) and np.allclose(read[0, 0], 1.0)


def test_pfm_envmap_and_compare_images_are_top_row_first(tmp_path):
    """PFM stores rows bottom to top. A .pfm envmap's top row is +y (contract: "The top edge is
    +y"), and `compare` reads .pfm images the way photos are read; OpenImageIO alone gave the rows
    bottom first, so the sky lit the object from below."""
    from flashbrdf.cli.main import main
    sky = np.zeros((8, 16, 3), np.float32)
    sky[0] = [2.0, 3.0, 4.0]                       # top row: light from straight above (+y)

    def write_pfm(path, image):
        with open(path, "wb") as f:
            f.write(f"PF\n{image.shape[1]} {image.shape[0]}\n-1.0\n".encode()
                    + image[::-1].astype("<f4").tobytes())

    write_pfm(tmp_path / "sky.pfm", sky)
    env = EnvMap.from_file(tmp_path / "sky.pfm")
    assert np.allclose(env.radiance(np.array([[0.0, 1.0, 0.0]]))[0], [2.0, 3.0, 4.0])
    assert np.allclose(env.radiance(np.array([[0.0, -1.0, 0.0]]))[0], 0.0)
    # compare over a mask of the top row only: pred equals ref there, differs below
    ref = np.ones((4, 5, 3), np.float32)
    pred = ref.copy()
    pred[1:] = 3.0
    write_pfm(tmp_path / "pred.pfm", pred)
    write_pfm(tmp_path / "ref.pfm", ref)
    import cv2
    mask = np.zeros((4, 5), np.uint8)
    mask[0] = 255
    cv2.imwrite(str(tmp_path / "mask.png"), mask)
    assert main(["compare", str(tmp_path / "pred.pfm"), str(tmp_path / "ref.pfm"), "--mask",
                 str(tmp_path / "mask.png"), "--out", str(tmp_path / "cmp")]) == 0
    import json
    result = json.loads((tmp_path / "cmp" / "compare.json").read_text())
    assert result["pixels"] == 5 and result["delta_e_log_mean"] == pytest.approx(0.0, abs=1e-9)


def test_default_envmaps_are_made_in_code_with_a_sun_the_sampler_finds():
    """Table 2's default maps: finite, non-negative (128, 256, 3). The sky's 3-degree sun holds
    about 60% of the irradiance of a horizontal surface (designed 500 x 0.0086 sr x sin 35 =
    2.5 against the sky's ~1.7: 0.55-0.65 with the pixelated disc), so the importance sampler
    must put most samples there: P(sun pixels) > 0.5."""
    from flashbrdf.render.envmap import DEFAULT_ENVMAPS, default_envmaps, envmap_directions
    maps = default_envmaps()
    assert tuple(maps) == DEFAULT_ENVMAPS
    for pixels in maps.values():
        assert pixels.shape == (128, 256, 3) and np.isfinite(pixels).all() and pixels.min() >= 0
    sky = maps["sky"]
    h = sky.shape[0]
    d = envmap_directions(h)
    solid = (np.cos(np.pi * np.arange(h) / h) - np.cos(np.pi * np.arange(1, h + 1) / h)) \
        * 2 * np.pi / (2 * h)
    lum = sky @ np.array([0.2126, 0.7152, 0.0722])
    irradiance = lum * np.maximum(d[..., 1], 0) * solid[:, None]
    sun = lum > 100
    assert 0.5 < irradiance[sun].sum() / irradiance.sum() < 0.7
    env = EnvMap(sky)
    assert env.can_sample
    dirs = env.sample(np.random.default_rng(0).random((4000, 2)))[0]
    lit = env.radiance(dirs) @ np.array([0.2126, 0.7152, 0.0722]) > 100
    assert lit.mean() > 0.5


@pytest.mark.parametrize("pixels, scale, message", [
    (np.ones((8, 16, 3)), -1.0, "scale must be a finite number >= 0"),
    (np.ones((8, 16, 3)), float("nan"), "scale must be a finite number >= 0"),
    (np.where(np.arange(16)[None, :, None] == 3, np.nan, np.ones((8, 16, 3))), 1.0,
     "non-finite"),
])
def test_an_envmap_of_negative_or_nan_light_is_refused(pixels, scale, message):
    """A scale of -1 rendered a Lambert sphere at -0.51, NaN rendered NaN: both are refused."""
    with pytest.raises(ValueError, match=message):
        EnvMap(pixels, scale=scale)
    assert EnvMap(np.ones((8, 16, 3)), scale=0.0).radiance(np.array([0, 0, 1.0])).max() == 0
