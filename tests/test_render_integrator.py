"""The integrator against answers known analytically: white furnace, energy (directional albedo),
mirror orientation, directional lights and shadows, determinism, HDR maps without fireflies;
several models in one render, each as rendered alone."""

import numpy as np
import pytest

from flashbrdf.brdf.angles import half_diff_from_local
from flashbrdf.brdf.lookup import evaluate_table
from flashbrdf.brdf.merl import read_merl
from flashbrdf.brdf.models import GGX, Lambert, TabulatedBRDF
from flashbrdf.render.envmap import EnvMap, envmap_direction
from flashbrdf.render.integrator import (render_directional_light, render_envmap,
                                        render_point_light)
from flashbrdf.render.scene_render import render_sphere, sphere_view


def test_white_furnace_exact_with_compensation():
    # Constant map: nothing is above the mean, so only cosine sampling runs, and for Lambert
    # f cos / pdf = a exactly: every pixel is a L to rounding.
    mask, normals, view = sphere_view(64)
    env = EnvMap(np.full((16, 32, 3), 2.0))
    albedo = np.array([0.2, 0.5, 0.9])
    image = render_envmap(normals, normals, view, Lambert(albedo), env, spp=16, seed=1)
    assert np.allclose(image, albedo * 2.0, rtol=1e-9, atol=0)


def test_white_furnace_within_half_percent_with_full_mis():
    # Uncompensated MIS (uniform envmap samples + cosine samples, balance heuristic): the
    # per-sample estimate a L cos / (cos + 1/4) varies in [0, 0.8 a L], sd ~0.25 a L. Sobol
    # points with a per-pixel random shift converge ~1/N here: at 1024 samples per pixel (1024
    # envmap + 1024 cosine directions) the measured sd over pixels is 3e-4 and the worst of 800
    # pixels <= 2.3e-3 (3 seeds), so 0.5 % on every pixel holds with margin and would fail for
    # plain random sampling (sd ~0.5 %).
    mask, normals, view = sphere_view(32)
    env = EnvMap(np.full((16, 32, 3), 2.0), compensate=False)
    image = render_envmap(normals, normals, view, Lambert([0.5, 0.5, 0.5]), env, spp=1024, seed=1)
    assert np.all(np.abs(image / 1.0 - 1.0) < 5e-3)


def _albedo_by_quadrature(table, wo, per_bin=4, n_phi=360):
    """Directional albedo, integral of rho cos(theta_i) over wi, by midpoint quadrature over half
    vectors (d w_i = 4 (wo.h) d w_h), `per_bin` cos-uniform cells per MERL theta_h bin so the
    narrow bins near theta_h = 0 are resolved; lookup via brdf.lookup (not the render path)."""
    edges = np.cos((np.pi / 2) * (np.arange(90 * per_bin + 1) / (90 * per_bin)) ** 2)
    cos_h, phi = np.meshgrid(0.5 * (edges[:-1] + edges[1:]), (np.arange(n_phi) + 0.5) / n_phi
                             * 2 * np.pi, indexing="ij")
    d_omega = ((edges[:-1] - edges[1:])[:, None] * (2 * np.pi / n_phi) * np.ones(n_phi)).ravel()
    sin_h = np.sqrt(1 - cos_h ** 2)
    h = np.stack([sin_h * np.cos(phi), sin_h * np.sin(phi), cos_h], -1).reshape(-1, 3)
    wo_h = h @ wo
    wi = 2 * wo_h[:, None] * h - wo
    ok = (wo_h > 0) & (wi[:, 2] > 0)
    f = evaluate_table(table, *half_diff_from_local(wi[ok], np.broadcast_to(wo, wi[ok].shape)))
    return np.sum(f * (wi[ok, 2] * 4 * wo_h[ok] * d_omega[ok])[:, None], axis=0)


@pytest.mark.parametrize("material", ["blue-acrylic", "gold-metallic-paint"])
def test_energy_equals_directional_albedo(merl_proxy, material):
    table = read_merl(merl_proxy(material))
    # 20..70 degrees: at exact normal incidence phi_d is 0 = pi, a MERL bin-fold tie that the two
    # lookups may break differently (proxy tables are not symmetric there)
    angles = np.radians([20.0, 45.0, 70.0])
    wo = np.stack([np.sin(angles), 0 * angles, np.cos(angles)], -1)
    expected = np.array([_albedo_by_quadrature(table, w) for w in wo])
    normals = np.tile([0.0, 0.0, 1.0], (len(wo), 1))
    env = EnvMap(np.ones((16, 32, 3)))        # L = 1: the pixel is the directional albedo
    image = render_envmap(normals, normals, wo, TabulatedBRDF(table), env, spp=4096, seed=2)
    # quadrature converged to ~1e-4 (doubling both resolutions); the render measured <= 0.1 %
    assert np.allclose(image, expected, rtol=0.01)


def test_mirror_sphere_orientation():
    # One bright 3x3 patch in a black map; by the contract, map pixel (row i, col j) is light
    # arriving from d = (sin phi sin theta, cos theta, -cos phi sin theta). A near-mirror sphere
    # seen by an orthographic camera looking along -z (image right +x, up +y) shows it where the
    # normal bisects d and the view direction +z.
    h, w, i0, j0 = 64, 128, 21, 100
    pixels = np.zeros((h, w, 3))
    pixels[i0 - 1:i0 + 2, j0 - 1:j0 + 2] = 100.0
    theta, phi = np.pi * (i0 + 0.5) / h, 2 * np.pi * (j0 + 0.5) / w - np.pi
    d = np.array([np.sin(phi) * np.sin(theta), np.cos(theta), -np.cos(phi) * np.sin(theta)])
    assert d[0] > 0.5 and d[1] > 0.3 and d[2] > 0   # up and to the right, in front of the sphere
    n = (d + [0, 0, 1]) / np.linalg.norm(d + [0, 0, 1])
    size = 64
    expected_col = n[0] * size / 2 + (size - 1) / 2
    expected_row = -n[1] * size / 2 + (size - 1) / 2
    image = render_sphere(GGX(0.01), EnvMap(pixels), size=size, spp=32, seed=0)
    lum = image.sum(-1)
    rows, cols = np.nonzero(lum > 0.05 * lum.max())
    weight = lum[rows, cols]
    row, col = np.average(rows, weights=weight), np.average(cols, weights=weight)
    # the patch spans 8.4 degrees, its reflection ~3 pixels: its centroid within 1.5 pixels
    assert abs(row - expected_row) < 1.5 and abs(col - expected_col) < 1.5
    # and nothing anywhere else on the sphere
    far = np.hypot(rows - expected_row, cols - expected_col) > 6
    assert not np.any(far)


def test_directional_light_lambert_and_shadow():
    mask, normals, view = sphere_view(32)
    points = normals.copy()                                 # unit sphere at the origin
    light = np.array([1.0, 1.0, 1.0]) / np.sqrt(3)
    e = np.array([2.0, 3.0, 4.0])
    value = render_directional_light(points, normals, view, Lambert([0.5, 0.5, 0.5]), light, e)
    cos_i = np.maximum(normals @ light, 0)
    assert np.allclose(value, 0.5 / np.pi * e * cos_i[:, None], rtol=1e-12)

    def blocker(p, d, max_dist):                             # everything left of x = 0 is shadowed
        assert max_dist is None
        return p[:, 0] < 0
    shadowed = render_directional_light(points, normals, view, Lambert([0.5] * 3), light, e,
                                        occluded=blocker)
    left = points[:, 0] < 0
    assert np.all(shadowed[left] == 0) and np.allclose(shadowed[~left], value[~left])
    # lists, and one (3,) point, as render_point_light takes them (an AttributeError before)
    listed = render_directional_light(points[:5].tolist(), normals[:5].tolist(),
                                      view[:5].tolist(), Lambert([0.5] * 3), list(light), list(e))
    assert np.array_equal(listed, value[:5])
    one = render_directional_light(points[0], normals[0], view[0], Lambert([0.5] * 3), light, e)
    assert one.shape == (1, 3) and np.array_equal(one[0], value[0])


def test_envmap_shadow_rays_and_determinism():
    mask, normals, view = sphere_view(16)
    rng = np.random.default_rng(0)
    env = EnvMap(rng.random((16, 32, 3)) * 5)
    brdf = GGX(0.2, specular=[0.5] * 3, diffuse=[0.3] * 3)
    a = render_envmap(normals, normals, view, brdf, env, spp=16, seed=7, threads=1)
    b = render_envmap(normals, normals, view, brdf, env, spp=16, seed=7, threads=2)
    c = render_envmap(normals, normals, view, brdf, env, spp=16, seed=8, threads=2)
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    # A blocker taking every direction with y > 0 leaves exactly the lower hemisphere's light:
    # the same as a map whose upper half is black (same samples, same seed).
    lower = env.pixels.copy()
    i = np.arange(16) + 0.5
    upper_rows = envmap_direction(i, np.full(16, 0.5), 16, 32)[:, 1] > 0
    lower[upper_rows] = 0
    blocked = render_envmap(normals, normals, view, brdf, EnvMap(lower, compensate=False),
                            spp=1024, seed=1, occluded=lambda p, d, m: d[:, 1] > 0,
                            strategies=("brdf",))
    reference = render_envmap(normals, normals, view, brdf, EnvMap(lower, compensate=False),
                              spp=1024, seed=1, strategies=("brdf",))
    # they differ only through bilinear blending across the horizon row boundary (rows 7|8),
    # which the blocker cuts exactly at y = 0 and the black map at the row centres
    assert np.sqrt(np.mean((blocked - reference) ** 2)) < 0.1 * np.sqrt(np.mean(reference ** 2))


def test_hdr_sun_without_fireflies():
    # sky plus a one-pixel sun 5e4 times brighter (royal_esplanade-like); the rel. RMSE between
    # two independent renders is sqrt(2) x each one's error. MIS keeps it small and halves it
    # (or better) from 64 to 256 samples per pixel; BRDF sampling alone is dominated by
    # fireflies (measured rel. RMSE > 1 against a converged render).
    mask, normals, view = sphere_view(32)
    h, w = 32, 64
    i, j = np.meshgrid(np.arange(h) + 0.5, np.arange(w) + 0.5, indexing="ij")
    sky = 0.2 + 0.8 * np.clip(envmap_direction(i, j, h, w)[..., 1:2], 0, 1)
    pixels = sky * np.array([0.6, 0.8, 1.0])
    pixels[8, 40] = [5e4, 4e4, 3e4]
    env = EnvMap(pixels)
    brdf = Lambert([0.5] * 3)

    def spread(spp, **kw):
        a = render_envmap(normals, normals, view, brdf, env, spp=spp, seed=1, **kw)
        b = render_envmap(normals, normals, view, brdf, env, spp=spp, seed=2, **kw)
        return np.sqrt(np.sum((a - b) ** 2) / np.sum(b ** 2))

    mis64, mis256 = spread(64), spread(256)
    assert mis64 < 0.15 and mis256 < 0.5 * mis64
    assert spread(64, strategies=("brdf",)) > 5 * mis64


def _several_models():
    """Models whose envmap-strategy directions differ in what they light: a 2D table that is
    0 past theta_h 20 deg keeps only some of the directions the others keep."""
    table = np.zeros((90, 90, 3))
    table[:20] = [0.9, 0.5, 0.2]
    return [GGX(0.2, specular=[0.5] * 3, diffuse=[0.3] * 3), Lambert([0.5, 0.2, 0.1]),
            TabulatedBRDF(table), GGX(0.05, specular=[0.8, 0.6, 0.4], diffuse=[0.0] * 3)]


@pytest.mark.parametrize("strategies", [("envmap", "brdf"), ("envmap",), ("brdf",)])
def test_several_models_render_each_as_alone(monkeypatch, strategies):
    """One render with several models gives each model its render alone, to the bit: the same
    seed gives every model the same pattern and per-pixel shifts (chunks start at the same
    points), and the envmap strategy's directions, pdfs, radiance and shadow rays, computed once
    for the directions any model lights, are element by element the numbers each model's own
    call computes; each model's sums run over the same terms in the same order. So the
    tolerance is 0. The shared shadow rays are fewer than the separate calls cast."""
    import flashbrdf.render.integrator as integrator
    monkeypatch.setattr(integrator, "SAMPLES_PER_CHUNK", 1 << 10)  # many chunks, two threads
    mask, normals, view = sphere_view(20)
    rng = np.random.default_rng(3)
    c, s = np.cos(0.7), np.sin(0.7)
    env = EnvMap(rng.random((16, 32, 3)) * 5, [[c, 0, s], [0, 1, 0], [-s, 0, c]], 1.5)
    rays = []

    def occluded(points, dirs, far):   # a blocker over x > 0.4, counting the rays cast
        rays.append(len(dirs))
        return dirs[:, 0] > 0.4
    models = _several_models()
    kw = dict(spp=8, seed=5, occluded=occluded, strategies=strategies, threads=2)
    alone = [render_envmap(normals, normals, view, model, env, **kw) for model in models]
    separate_rays, rays[:] = sum(rays), []
    together = render_envmap(normals, normals, view, models, env, **kw)
    assert len(together) == len(models)
    for one, shared in zip(alone, together):
        assert one.any() and np.array_equal(one, shared)
    if "envmap" in strategies:
        assert sum(rays) < separate_rays
    else:
        assert sum(rays) == separate_rays


def test_several_models_under_direct_lights_render_each_as_alone():
    """Point and directional lights: one shadow ray a point for all models, the same values
    (tolerance 0: each model's value is the same elementwise product, zeroed where its own
    lit points are blocked)."""
    mask, normals, view = sphere_view(16)
    models = _several_models()

    def occluded(points, dirs, far):
        return points[:, 0] > 0.3
    for render, light in ((render_point_light, ([0.5, 0.5, 2.0], [1.0, 2.0, 3.0])),
                          (render_directional_light, ([0.3, 0.5, 0.8], [1.0, 2.0, 3.0]))):
        alone = [render(normals, normals, view, model, *light, occluded=occluded)
                 for model in models]
        together = render(normals, normals, view, models, *light, occluded=occluded)
        for one, shared in zip(alone, together):
            assert one.any() and np.array_equal(one, shared)


def test_an_empty_list_of_models_renders_no_image():
    """A list of models gives one output per model, so an empty list gives an empty list (it
    raised IndexError / ValueError from the shared shadow-ray and radiance code)."""
    mask, normals, view = sphere_view(8)
    env = EnvMap(np.random.default_rng(0).random((8, 16, 3)), np.eye(3), 1.0)

    def occluded(points, dirs, far):
        return dirs[:, 0] > 0.3
    assert render_envmap(normals, normals, view, [], env, spp=2, occluded=occluded) == []
    assert render_point_light(normals, normals, view, [], [0, 0, 3], [1, 1, 1],
                              occluded=occluded) == []
    assert render_directional_light(normals, normals, view, (), [0, 0, 1], [1, 1, 1],
                                    occluded=occluded) == []
