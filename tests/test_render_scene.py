"""The render command on synthetic capture folders: point, directional and envmap references,
mesh and normal-map geometry, outputs and bad input; several BRDFs rendered at once."""

import json

import numpy as np
import pytest

from flashbrdf.brdf.angles import half_diff_from_world
from flashbrdf.brdf.lookup import evaluate_table
from flashbrdf.brdf.merl import read_merl, write_merl
from flashbrdf.brdf.views import table_2d, table_3d_from_2d
from flashbrdf.cli.main import main
from flashbrdf.render.images import read_image, write_exr, write_png
from synthetic import (directional_light, orthographic_camera, pinhole_camera, point_light,
                       render, sphere_mesh, table_brdf, torus_mesh, write_png16,
                       write_synthetic_scene)


def _as_references(folder):
    scene = json.loads((folder / "scene.json").read_text())
    for photo in scene["photos"]:
        photo["role"] = "reference"
    (folder / "scene.json").write_text(json.dumps(scene))


@pytest.fixture(scope="module")
def gold(merl_proxy):
    path = merl_proxy("gold-metallic-paint")
    return path, read_merl(path)


def test_point_light_reproduces_synthetic_flash_photos(tmp_path, gold):
    # Same pixel model, same table lookup (interpolated: no bin-edge ties), same geometry:
    # equal to float32 rounding. Offset flash, photo scale 2.5 (renders are in photo units).
    path, table = gold
    folder = write_synthetic_scene(tmp_path / "scene", sphere_mesh(subdivisions=4),
                                   table_brdf(table, interpolate=True), pinhole_camera(64, 64, 700.0),
                                   [point_light([0.03, 0.01, 0.0]), point_light([-0.02, 0.0, 0.01],
                                                                                [2, 1, 1])],
                                   scale=2.5)
    _as_references(folder)
    out = tmp_path / "out"
    assert main(["render", str(folder), "--brdf", str(path), "--out", str(out),
                 "--interpolate"]) == 0
    for k in (0, 1):
        ours, photo = read_image(out / f"flash{k}.exr"), read_image(folder / f"flash{k}.exr")
        assert np.array_equal(ours > 0, photo > 0)
        assert np.allclose(ours, photo, rtol=2e-5, atol=1e-6 * photo.max())
        metrics = json.loads((out / f"flash{k}_compare.json").read_text())
        assert metrics["pixels"] == int(np.count_nonzero(photo.any(axis=-1)))
        assert metrics["rel_rmse"] < 1e-5
        assert (out / f"flash{k}.png").is_file() and (out / f"flash{k}_delta_e.png").is_file()


def test_colocated_flash_and_shadows_on_a_torus(tmp_path, gold):
    # Co-located flash: theta_d = 0 where phi_d is numerically arbitrary, so use a 2D-derived
    # table (constant over phi_d) to make the lookup tie-free; the torus shadows itself under
    # an offset light, which the non-convex shadow rays must reproduce.
    _, table = gold
    flat = table_3d_from_2d(table_2d(table))
    path = tmp_path / "flat.binary"
    write_merl(path, flat)
    folder = write_synthetic_scene(tmp_path / "scene", torus_mesh(), table_brdf(flat),
                                   pinhole_camera(64, 64, 300.0),
                                   [point_light([0, 0, 0]), point_light([0.0, -0.3, 0.8])])
    _as_references(folder)
    out = tmp_path / "out"
    assert main(["render", str(folder), "--brdf", str(path), "--out", str(out)]) == 0
    for k in (0, 1):
        ours, photo = read_image(out / f"flash{k}.exr"), read_image(folder / f"flash{k}.exr")
        close = np.isclose(ours, photo, rtol=2e-5, atol=1e-6 * photo.max()).all(axis=-1)
        # nearest-bin lookups may round to the neighbouring bin on a handful of pixels, and
        # shadow-ray offsets differ slightly at the terminator: allow 0.5 % of the pixels
        assert close.mean() > 0.995
    # and those shadows are real: without shadow rays these pixels would be lit
    unshadowed = render(torus_mesh(), table_brdf(flat), pinhole_camera(64, 64, 300.0),
                        point_light([0.0, -0.3, 0.8]), shadows=False)
    shadowed = unshadowed.any(axis=-1) & ~read_image(out / "flash1.exr").any(axis=-1)
    assert shadowed.sum() > 200                # 524 pixels measured


def test_normal_map_directional_and_envmap(tmp_path, gold):
    # Normal-map geometry (no ray casting), orthographic camera looking along world -z.
    path, table = gold
    folder = tmp_path / "scene"
    folder.mkdir()
    size = 32
    c = (np.arange(size) - (size - 1) / 2) / (size / 2)
    x, y = np.meshgrid(c, c)                   # camera frame: x right, y down
    r2 = x ** 2 + y ** 2
    inside = r2 < 0.95
    normals_cam = np.stack([x, y, -np.sqrt(np.maximum(0, 1 - r2))], -1) * inside[..., None]
    np.save(folder / "normals.npy", normals_cam)
    write_png(folder / "mask.png", np.repeat((inside * 255).astype(np.uint8)[..., None], 3, -1))
    write_exr(folder / "const.exr", np.full((8, 16, 3), 0.5, np.float32))
    pose = np.diag([1.0, -1.0, -1.0, 1.0])                 # camera z = world -z
    light_dir = np.array([0.3, 0.5, 0.8]) / np.linalg.norm([0.3, 0.5, 0.8])
    scene = {"camera": orthographic_camera(size, size, 0.01, pose),
             "geometry": {"normal_map": "normals.npy", "mask": "mask.png"},
             "photos": [{"file": "dir.exr", "role": "reference", "scale": 3.0,
                         "light": directional_light(light_dir, [1.0, 2.0, 3.0])},
                        {"file": "env.exr", "role": "reference",
                         "light": {"type": "envmap", "file": "const.exr", "scale": 2.0}}]}
    (folder / "scene.json").write_text(json.dumps(scene))
    write_exr(folder / "dir.exr", np.ones((size, size, 3), np.float32))   # env.exr is absent
    out = tmp_path / "out"
    assert main(["render", str(folder), "--brdf", str(path), "--out", str(out),
                 "--spp", "256"]) == 0
    image = read_image(out / "dir.exr")
    n_world = normals_cam[inside] @ pose[:3, :3].T
    wo = np.broadcast_to([0.0, 0.0, 1.0], n_world.shape)
    wi = np.broadcast_to(light_dir, n_world.shape)
    rho = evaluate_table(table, *half_diff_from_world(wi, wo, n_world))
    cos_i = np.maximum(n_world @ light_dir, 0)
    expected = 3.0 * rho * [1.0, 2.0, 3.0] * cos_i[:, None]
    assert np.all(image[~inside] == 0)
    close = np.isclose(image[inside], expected, rtol=1e-5, atol=1e-7).all(axis=-1)
    assert close.mean() > 0.99                 # nearest-bin ties aside
    assert (out / "dir_compare.json").is_file() and not (out / "env_compare.json").exists()
    # constant map L = 0.5 x scale 2: pixel = directional albedo; bounded by energy conservation
    env = read_image(out / "env.exr")
    assert np.all(env[~inside] == 0) and np.all(env[inside] > 0)
    assert np.all(env[inside] < 1.0 * 1.05)


def test_bad_input(tmp_path, capsys, gold):
    path, _ = gold
    folder = write_synthetic_scene(tmp_path / "scene", sphere_mesh(subdivisions=2),
                                   table_brdf(read_merl(path)), pinhole_camera(16, 16, 200.0),
                                   [point_light()])
    out = tmp_path / "out"
    # only flash photos: nothing to render
    assert main(["render", str(folder), "--brdf", str(path), "--out", str(out)]) == 2
    _as_references(folder)
    assert main(["render", str(folder), "--brdf", str(tmp_path / "missing.binary"),
                 "--out", str(out)]) == 2
    assert main(["render", str(folder), "--brdf", str(path), "--out", str(out),
                 "--spp", "0"]) == 2
    # a second reference whose envmap is missing: found before anything is written
    scene = json.loads((folder / "scene.json").read_text())
    scene["photos"].append({"file": "env.exr", "role": "reference",
                            "light": {"type": "envmap", "file": "nowhere.hdr"}})
    (folder / "scene.json").write_text(json.dumps(scene))
    assert main(["render", str(folder), "--brdf", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 4 and "reference" in err[0] and "missing.binary" in err[1]
    assert "--spp" in err[2] and "nowhere.hdr" in err[3]
    assert not out.exists() or not any(out.iterdir())


def test_analytic_brdf_reproduces_flash_photos_through_render_scene(tmp_path):
    # The slice-extraction tests' synthetic flash photos (Lambert + GGX, co-located and offset
    # flashes, photo scale 2) through render.render_scene with the same analytic BRDF: equal
    # to float32 rounding, since both implement the contract's pixel model.
    from flashbrdf import capture
    from flashbrdf.brdf.models import GGX
    from flashbrdf.render import render_scene
    from synthetic import ggx_lambert
    kd, ks, alpha = (0.5, 0.3, 0.2), (0.8, 0.7, 0.6), 0.2
    folder = write_synthetic_scene(tmp_path / "scene", sphere_mesh(subdivisions=4),
                                   ggx_lambert(kd, ks, alpha), pinhole_camera(48, 48, 500.0),
                                   [point_light([0, 0, 0]), point_light([0.04, -0.02, 0.0])],
                                   scale=2.0)
    scene = capture.load_scene(folder)
    photos = scene.photos_with_role("flash")
    brdf = GGX(alpha, specular=ks, diffuse=kd, fresnel=False)
    for photo, image, mask in render_scene(scene, brdf, photos=photos, progress=False):
        reference = read_image(folder / photo.file.name)
        assert np.array_equal(mask, reference.any(axis=-1))
        assert np.allclose(image, reference, rtol=1e-5, atol=1e-7 * reference.max())


def test_shadow_rays_cause_no_acne_on_a_convex_mesh(tmp_path):
    # Forcing Embree shadow rays on a sphere (convex: nothing can shadow) must leave the envmap
    # render unchanged up to the facets: directions just above the smooth shading horizon but
    # below a flat triangle are blocked (measured <= 0.4 % on 4 % of the pixels).
    from flashbrdf import capture
    from flashbrdf.brdf.models import GGX
    from flashbrdf.render import EnvMap, render_envmap
    from synthetic import ggx_lambert
    folder = write_synthetic_scene(tmp_path / "scene", sphere_mesh(subdivisions=5), ggx_lambert(),
                                   pinhole_camera(32, 32, 300.0), [point_light()])
    scene = capture.load_scene(folder)
    mesh = capture.scene_intersector(scene)
    surface = capture.surface_from_mesh(mesh, scene.camera)
    env = EnvMap(np.random.default_rng(0).random((16, 32, 3)) * 3)
    brdf = GGX(0.2, specular=[0.5] * 3, diffuse=[0.4] * 3)
    args = (surface.points, surface.normals, surface.view_dirs, brdf, env)
    free = render_envmap(*args, spp=64, seed=0)
    shadowed = render_envmap(*args, spp=64, seed=0,
                             occluded=lambda p, d, m: capture.occluded(mesh, p, d, m))
    change = np.abs(shadowed - free).max(axis=-1) / free.max(axis=-1)
    assert np.all(shadowed <= free + 1e-12) and change.max() < 0.01


def test_compare_counts_a_float_photos_shadow_and_not_an_integer_code_0(tmp_path, gold):
    """Table 2's error is over the object's pixels: where a float reference photo holds 0 (the
    side the light does not reach) that 0 is measured and compared; NaN and clipped pixels are
    not. In an integer photo a code 0 is censored (the true value is anywhere below one step)
    and a saturated code too, so those pixels are left out."""
    path, table = gold
    folder = tmp_path / "scene"
    folder.mkdir()
    size = 32
    c = (np.arange(size) - (size - 1) / 2) / (size / 2)
    x, y = np.meshgrid(c, c)
    inside = x ** 2 + y ** 2 < 0.95
    normals_cam = np.stack([x, y, -np.sqrt(np.maximum(0, 1 - x ** 2 - y ** 2))], -1) \
        * inside[..., None]
    np.save(folder / "normals.npy", normals_cam)
    write_png(folder / "mask.png", np.repeat((inside * 255).astype(np.uint8)[..., None], 3, -1))
    pose = np.diag([1.0, -1.0, -1.0, 1.0])
    light_dir = np.array([0.9, 0.0, 0.3]) / np.linalg.norm([0.9, 0.0, 0.3])  # grazing: half dark
    light = directional_light(light_dir, [1.0, 1.0, 1.0])
    scene = {"camera": orthographic_camera(size, size, 0.01, pose),
             "geometry": {"normal_map": "normals.npy", "mask": "mask.png"},
             "photos": [{"file": "float.exr", "role": "reference", "light": light},
                        {"file": "int16.png", "role": "reference", "encoding": "linear",
                         "light": light}]}
    (folder / "scene.json").write_text(json.dumps(scene))
    n_world = normals_cam[inside] @ pose[:3, :3].T
    rho = evaluate_table(table, *half_diff_from_world(
        np.broadcast_to(light_dir, n_world.shape), np.broadcast_to([0.0, 0.0, 1.0], n_world.shape),
        n_world))
    truth = np.zeros((size, size, 3), np.float32)
    truth[inside] = rho * np.maximum(n_world @ light_dir, 0)[:, None]
    dark = inside & ~truth.any(axis=-1)
    assert 100 < dark.sum() < inside.sum() - 100        # both sides hold many pixels
    reference = truth.copy()
    lit = np.argwhere(inside & ~dark)
    reference[tuple(lit[:3].T)] = np.nan                 # 3 unknown pixels
    write_exr(folder / "float.exr", reference)
    white = float(np.percentile(truth[inside & ~dark], 90))
    write_png16(folder / "int16.png", truth, white=white)  # the top 10% saturate
    out = tmp_path / "out"
    assert main(["render", str(folder), "--brdf", str(path), "--out", str(out)]) == 0
    float_cmp = json.loads((out / "float_compare.json").read_text())
    assert float_cmp["pixels"] == inside.sum() - 3        # the dark side included
    codes = np.round(np.clip(truth / white, 0, 1) * 65535)
    measured = inside & (codes > 0).all(axis=-1) & (codes < 0.98 * 65535).all(axis=-1)
    int_cmp = json.loads((out / "int16_compare.json").read_text())
    assert int_cmp["pixels"] == measured.sum() < inside.sum() - dark.sum()


def test_cameras_beyond_the_hit_cache_are_each_traced_once_per_render(tmp_path, monkeypatch):
    """Three views of a sphere and a cache that holds one camera's hits: the up-front check
    traced and cached every camera, so the render loop found the first two evicted and traced
    them again (every camera twice). The check now traces a sample of a camera's rays, uncached:
    each camera is traced whole once, and renders as before."""
    from flashbrdf import capture
    from flashbrdf.brdf.models import GGX
    from flashbrdf.render import render_scene
    from flashbrdf.render.scene_render import SceneGeometry
    from synthetic import ggx_lambert
    folder = write_synthetic_scene(tmp_path / "scene", sphere_mesh(subdivisions=3),
                                   ggx_lambert(), pinhole_camera(40, 40, 400.0),
                                   [point_light([0, 0, 0]), point_light([0.03, 0, 0]),
                                    point_light([0, 0.03, 0])])
    doc = json.loads((folder / "scene.json").read_text())
    for k, photo in enumerate(doc["photos"]):  # three cameras, each 1 cm apart
        pose = np.eye(4)
        pose[0, 3] = 0.01 * k
        photo["camera"] = pinhole_camera(40, 40, 400.0, world_from_camera=pose)
    (folder / "scene.json").write_text(json.dumps(doc))
    scene = capture.load_scene(folder)
    geometry = SceneGeometry(scene)
    geometry.CACHED_HITS = len(geometry.surface(scene.photos_with_role("flash")[0].camera).rows)
    geometry._surfaces.clear()
    traced, real = [], capture.surface_from_mesh
    monkeypatch.setattr(capture, "surface_from_mesh",
                        lambda *a, **k: traced.append(1) or real(*a, **k))
    renders = list(render_scene(scene, GGX(0.2), photos=scene.photos_with_role("flash"),
                                geometry=geometry, progress=False))
    assert len(renders) == 3 and len(traced) == 3
    assert all(mask.sum() > 100 for _, _, mask in renders)


def test_point_and_directional_lights_shade_in_chunks_as_at_once(tmp_path, monkeypatch):
    """A view's points are shaded a million at a time (all at once, a 24 MP view made a dozen
    0.6 GB temporaries): chunks of 97 points give the same image, to the bit."""
    from flashbrdf import capture
    from flashbrdf.brdf.models import GGX
    from flashbrdf.render import render_scene
    import flashbrdf.render.scene_render as scene_render
    from synthetic import ggx_lambert
    folder = write_synthetic_scene(tmp_path / "scene", sphere_mesh(subdivisions=3),
                                   ggx_lambert(), pinhole_camera(40, 40, 400.0),
                                   [point_light([0.02, 0, 0]), directional_light()])
    scene = capture.load_scene(folder)
    photos = scene.photos_with_role("flash")

    def images():
        return [image for _, image, _ in render_scene(scene, GGX(0.2), photos=photos,
                                                      progress=False)]
    whole = images()
    monkeypatch.setattr(scene_render, "DIRECT_CHUNK", 97)
    chunked = images()
    assert all(w.any() and np.array_equal(w, c) for w, c in zip(whole, chunked))


def _several_brdfs_scene(tmp_path, size):
    """A torus (it shadows itself: Embree shadow rays) seen by a size x size pinhole camera,
    with an envmap reference (a rotated random map, scale 2) and a point-light reference."""
    from flashbrdf import capture
    from synthetic import ggx_lambert
    folder = write_synthetic_scene(tmp_path / "scene", torus_mesh(),
                                   ggx_lambert(), pinhole_camera(size, size, 3.2 * size),
                                   [point_light([0.02, 0, 0])])
    write_exr(folder / "sky.exr", np.random.default_rng(4).random((16, 32, 3)) * 4)
    doc = json.loads((folder / "scene.json").read_text())
    c, s = np.cos(0.6), np.sin(0.6)
    doc["photos"] += [
        {"file": "env.exr", "role": "reference", "scale": 1.5,
         "light": {"type": "envmap", "file": "sky.exr", "scale": 2.0,
                   "world_from_envmap": [[c, 0, s], [0, 1, 0], [-s, 0, c]]}},
        {"file": "point.exr", "role": "reference", "light": point_light([0.05, -0.03, 0.1])}]
    (folder / "scene.json").write_text(json.dumps(doc))
    return capture.load_scene(folder)


def test_several_brdfs_render_each_photo_once_each_as_alone(tmp_path):
    """render_scene with a list of BRDFs (models, material maps, albedo maps) yields for every
    photo one image per BRDF, each equal to its render alone to the bit (tolerance 0: the
    integrator gives every model its own samples and sums, tests/test_render_integrator.py,
    and the pixels are the same float64 values times the photo's scale, cast to float32)."""
    from flashbrdf.brdf.models import GGX, Lambert
    from flashbrdf.render import DiffuseAlbedoMap, MaterialMap, render_scene
    scene = _several_brdfs_scene(tmp_path, 40)
    camera = scene.photos_with_role("flash")[0].camera
    labels = np.ones(camera.shape, np.int64)
    labels[:, 20:] = 2
    albedo = np.random.default_rng(5).random(camera.shape + (3,)) * 0.6
    albedo[:, :8] = 0                                     # off the map: the base BRDF alone
    two = [GGX(0.3, specular=[0.3] * 3, diffuse=[0.2, 0.4, 0.1]), Lambert([0.2, 0.3, 0.6])]
    brdfs = [GGX(0.2), Lambert([0.5, 0.4, 0.3]), MaterialMap(two, labels, camera),
             DiffuseAlbedoMap(GGX(0.1), albedo, [[0.05, 0.04, 0.03]], camera),
             DiffuseAlbedoMap(MaterialMap(two[::-1], labels, camera), albedo,
                              [[0.05] * 3, [0.1] * 3], camera),
             MaterialMap([Lambert([0.1] * 3)], np.where(labels == 1, 1, 0), camera)]
    references = scene.photos_with_role("reference")
    alone = [[image for _, image, _ in render_scene(scene, brdf, spp=8, photos=references,
                                                    progress=False)] for brdf in brdfs]
    together = list(render_scene(scene, brdfs, spp=8, photos=references, progress=False))
    assert [photo.stem for photo, _, _ in together] == ["env", "point"]
    for p, (_, images, mask) in enumerate(together):
        assert len(images) == len(brdfs) and mask.sum() > 400
        for b, image in enumerate(images):
            assert image.dtype == np.float32 and image[mask].any(), (p, b)
            assert np.array_equal(image, alone[b][p]), (p, b)


def _traced_render_peak(tmp_path, monkeypatch, brdfs_for, spp):
    """(traced peak bytes, primary hits N) of render_scene over a 300² envmap reference with the
    BRDFs brdfs_for(flash camera) gives, at 1 << 10 samples a chunk."""
    import tracemalloc
    import flashbrdf.render.integrator as integrator
    from flashbrdf.render import SceneGeometry, render_scene
    scene = _several_brdfs_scene(tmp_path, 300)
    photo = [p for p in scene.photos_with_role("reference") if p.light.type == "envmap"]
    brdfs = brdfs_for(scene.photos_with_role("flash")[0].camera)
    geometry = SceneGeometry(scene)
    n = len(geometry.surface(photo[0].camera).rows)     # primary hits cast before tracing
    monkeypatch.setattr(integrator, "SAMPLES_PER_CHUNK", 1 << 10)
    tracemalloc.start()
    try:
        for _, images, mask in render_scene(scene, brdfs, spp=spp, photos=photo,
                                            geometry=geometry, progress=False):
            assert len(images) == len(brdfs) and all(image.any() for image in images)
            del images, mask
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert n > 20_000
    return peak, n


def test_several_brdfs_hold_their_images_not_float64_values(tmp_path, monkeypatch):
    """A photo rendered for M BRDFs at once holds the M float32 images (12 bytes a pixel each)
    and per-chunk buffers, not an (N, 3) float64 array (24 bytes a point) per BRDF. The traced
    peak stays under the images + the mask + 1.5 MB: at 1 << 10 samples a chunk and spp 2, a
    chunk is 256 points x 2 strategies x 2 samples, and its ~40 temporaries of at most 512 x 3
    float64 (12 kB) make < 0.5 MB a thread, 1 MB for two; the rest is slack. M float64 arrays
    would add M x 24 N bytes (2.9 MB here)."""
    from flashbrdf.brdf.models import GGX, Lambert
    brdfs = [GGX(0.2), Lambert([0.5] * 3), GGX(0.05), Lambert([0.2] * 3)]
    peak, n = _traced_render_peak(tmp_path, monkeypatch, lambda camera: brdfs, spp=2)
    pixels = 300 * 300
    assert peak < len(brdfs) * 12 * pixels + pixels + 1.5e6, (peak, n)


def test_albedo_maps_hold_the_unit_render_and_chunks(tmp_path, monkeypatch):
    """Several DiffuseAlbedoMaps hold the render of the 1/sr BRDF (one N x 3 float64 array, 24 N
    bytes) and per-chunk buffers, not a map's (N, 3) float64 values or delta. The traced peak
    stays under the images + the mask + 2 x 24 N + 1.5 MB: the unit (24 N) and, while the bases
    render together, the chunk buffers within the test above's 1.5 MB allowance (~1.0 MB
    measured with these 6 models in two threads; the sink's delta, unit rows and sum of a
    512-point chunk are 12 kB each); before it, the delta check holds ~4 arrays of DELTA_CHUNK x
    3 float64 (1.6 MB). The second 24 N is headroom for more render threads. Rendering the maps
    one at a time held a map's base values, delta and sum beside the unit (6.5 x 24 N over the
    images measured here, 2.4 x 24 N now)."""
    from flashbrdf.brdf.models import GGX
    from flashbrdf.render import DiffuseAlbedoMap

    def maps(camera):
        albedo = np.full(camera.shape + (3,), 0.5, np.float32)
        return [DiffuseAlbedoMap(GGX(0.05 * (k + 1)), albedo, [[0.02] * 3], camera)
                for k in range(6)]
    peak, n = _traced_render_peak(tmp_path, monkeypatch, maps, spp=1)
    pixels = 300 * 300
    assert peak < 6 * 12 * pixels + pixels + 2 * 24 * n + 1.5e6, (peak, n)


def test_albedo_maps_share_the_envmap_work_and_add_the_unit_render(tmp_path, monkeypatch):
    """DiffuseAlbedoMaps under an envmap draw the envmap's samples (BRDF-independent work) in
    two renders, whatever their number: the 1/sr BRDF's, then all bases together as a list of
    BRDFs is rendered (one map at a time drew them for each base alone). Each map's values are,
    to the bit, max(base + unit x delta, 0) of its base's and the 1/sr BRDF's renders alone
    (tolerance 0: the same float64 operations per point), or its base's alone where its delta
    is 0 everywhere (no albedo)."""
    from flashbrdf.brdf.models import GGX, Lambert
    import flashbrdf.render.integrator as integrator
    from flashbrdf.render import DiffuseAlbedoMap, MaterialMap, SceneGeometry
    from flashbrdf.render.envmap import EnvMap
    from flashbrdf.render.scene_render import render_surface
    scene = _several_brdfs_scene(tmp_path, 40)
    photo = next(p for p in scene.photos_with_role("reference") if p.light.type == "envmap")
    camera = photo.camera
    geometry = SceneGeometry(scene)
    surface = geometry.surface(camera)
    n = len(surface.rows)
    labels = np.ones(camera.shape, np.int64)
    labels[:, 20:] = 2
    albedo = np.random.default_rng(6).random(camera.shape + (3,)) * 0.6
    albedo[:, :8] = 0
    two = [GGX(0.3, specular=[0.3] * 3, diffuse=[0.2, 0.4, 0.1]), Lambert([0.2, 0.3, 0.6])]
    maps = [DiffuseAlbedoMap(GGX(0.1), albedo, [[0.05, 0.04, 0.03]], camera),
            DiffuseAlbedoMap(MaterialMap(two, labels, camera), albedo, [[0.05] * 3, [0.3] * 3],
                             camera),
            DiffuseAlbedoMap(Lambert([0.1] * 3), albedo * 0.01, [[0.3] * 3], camera),  # < 0
            DiffuseAlbedoMap(GGX(0.2), np.zeros_like(albedo), [[0.05] * 3], camera)]
    monkeypatch.setattr(integrator, "SAMPLES_PER_CHUNK", 1 << 10)  # several chunks a render
    draws = []
    sample = EnvMap.sample
    monkeypatch.setattr(EnvMap, "sample", lambda self, u: draws.append(len(u)) or sample(self, u))

    def rendered(brdfs):
        out = [np.full((n, 3), np.nan) for _ in brdfs]
        draws.clear()

        def keep(rows, m, values):
            out[m][rows] = values
        render_surface(surface, camera, photo.light, brdfs, keep, spp=4,
                       occluded=geometry.occluder(), progress=None)
        return out, len(draws)
    together, drawn = rendered(maps)
    (unit,), once = rendered([Lambert(np.pi)])
    bases, bases_drawn = rendered([albedo_map.base for albedo_map in maps])
    alone = sum(rendered([albedo_map.base])[1] for albedo_map in maps)
    # the 3 models' bases draw once a chunk, the MaterialMap's once a chunk of each material's
    # part: 5 + 6 draws together, against 5 + 6 + 5 + 5 one base at a time
    assert once >= 3 and bases_drawn < alone, (once, bases_drawn, alone)
    assert drawn == once + bases_drawn, (drawn, once, bases_drawn, alone)
    for i, albedo_map in enumerate(maps):
        delta = albedo_map.point_delta(surface, camera)
        expected = np.maximum(bases[i] + unit * delta, 0.0) if delta.any() else bases[i]
        assert np.array_equal(together[i], expected), i
    assert (bases[2] + unit * maps[2].point_delta(surface, camera) < 0).any()  # a clip at 0
