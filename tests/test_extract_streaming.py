"""Extraction of many photos with bounded memory: photos read one at a time, pooled samples
subsampled per theta_h bin past a budget, inner occluding contours left out."""

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from flashbrdf.brdf.angles import merl_bin_index
from flashbrdf.slice_extract import ExtractOptions, collect_samples, extract_slice
from flashbrdf.slice_extract.extract import bin_samples
from flashbrdf.slice_extract.sample_store import SampleStore
from flashbrdf.slice_extract.visibility import depth_edge_mask
from synthetic import ggx_lambert, pinhole_camera, point_light, sphere_mesh, write_synthetic_scene


def _part(theta_h, k):
    n = len(theta_h)
    return {"theta_h": theta_h, "theta_d": np.zeros(n), "rho": np.full((n, 3), float(k)),
            "censored": np.zeros(n, bool), "pixels": np.arange(n), "photo": np.full(n, k)}


def test_store_keeps_everything_below_the_budget_in_order():
    options = replace(ExtractOptions(), sample_budget=1000, max_samples_per_bin=10)
    store = SampleStore(options)
    for k in range(3):
        store.add(_part(np.linspace(0.01, 1.4, 300), k))
    pooled = store.pooled()
    assert not store.subsampled and len(pooled["theta_h"]) == 900
    assert np.array_equal(pooled["photo"], np.repeat([0, 1, 2], 300))


def test_store_past_the_budget_caps_each_bin_uniformly_over_photos():
    """60 photos of 2,000 samples, all in one theta_h bin, budget 5,000, cap 1,200: the bin
    holds 1,200, and each photo's share is binomial around 1,200 / 60 = 20 (sd 4.4; every photo
    within 5 sd: 20 +- 22), whatever the order the photos came in. A sparse bin keeps all."""
    options = replace(ExtractOptions(), sample_budget=5000, max_samples_per_bin=1200)
    store = SampleStore(options)
    dense = np.full(2000, 0.3)
    for k in range(60):
        part = _part(np.concatenate([dense, [1.2]]), k)  # + one sample in another bin
        store.add(part)
    pooled = store.pooled()
    bins = merl_bin_index(pooled["theta_h"], 0.0, 0.0)[0]
    counts = np.bincount(bins, minlength=90)
    dense_bin = merl_bin_index(np.array([0.3]), 0.0, 0.0)[0][0]
    sparse_bin = merl_bin_index(np.array([1.2]), 0.0, 0.0)[0][0]
    assert store.subsampled and counts[dense_bin] == 1200 and counts[sparse_bin] == 60
    per_photo = np.bincount(pooled["photo"][bins == dense_bin], minlength=60)
    assert np.all(np.abs(per_photo - 20) <= 22), per_photo


def test_store_keeps_exactly_each_bins_smallest_keys_over_all_photos():
    """After every photo, the subset is the one a single sort over every sample added so far
    would keep: per bin, the `cap` smallest random keys. Samples dropped on arrival (a key at or
    above the bin's limit) would have been cut by that sort too; none that it keeps is lost
    (a sample just under the limit is kept only until smaller keys arrive, so the check is made
    photo by photo, not only at the end)."""
    options = replace(ExtractOptions(), sample_budget=3000, max_samples_per_bin=400)
    store = SampleStore(options, seed=3)
    rng = np.random.default_rng(1)
    # ~19 theta_h bins of ~2,000 samples each: every bin fills early and is filtered on arrival
    parts = [_part(rng.uniform(0.2, 0.5, 1500), k) for k in range(25)]
    # the keys the store draws, in order: once it subsamples (at the part that takes it past the
    # budget, 3 x 1500 > 3000), one per sample added, the earlier parts' first
    keys = np.random.default_rng(3).random(1500 * 25, np.float32)
    theta_h = np.concatenate([p["theta_h"] for p in parts]).astype(np.float32)
    bins = merl_bin_index(theta_h, 0.0, 0.0)[0]
    for k, part in enumerate(parts):
        part["pixels"] = np.arange(1500) + 1500 * k  # a unique id per sample
        store.add(part)
        if not store.subsampled:
            continue
        seen = np.arange(1500 * (k + 1))
        expected = set()
        for b in np.unique(bins[seen]):
            mine = seen[bins[seen] == b]
            expected.update(mine[np.argsort(keys[mine], kind="stable")[:400]].tolist())
        assert set(store.pooled()["pixels"].tolist()) == expected, k
    assert np.isfinite(store.key_limit).sum() > 0  # the filter on arrival was in use


@pytest.mark.parametrize("distinct_keys", [40, 1 << 30])
def test_store_cut_matches_one_stable_sort_with_tied_keys(distinct_keys):
    """The cut finds each bin's boundary through a key histogram: it keeps what one stable
    sort by (bin, key, arrival) keeps, also when keys tie (40 distinct values: every bin's
    boundary level is all ties) and when bins hold fewer samples than the cap."""
    options = replace(ExtractOptions(), sample_budget=1000, max_samples_per_bin=300)
    store = SampleStore(options)
    rng = np.random.default_rng(7)
    theta_h = np.concatenate([rng.uniform(0.3, 0.32, 2000), rng.uniform(1.2, 1.5, 200)])
    keys = (rng.integers(0, distinct_keys, len(theta_h)) / distinct_keys).astype(np.float32)
    for k, chunk in enumerate(np.array_split(np.arange(len(theta_h)), 4)):
        part = _part(theta_h[chunk], k)
        part["pixels"], part["key"] = chunk, keys[chunk]
        store.add(part)
    bins = merl_bin_index(theta_h.astype(np.float32), 0.0, 0.0)[0]
    order = np.lexsort((np.arange(len(keys)), keys, bins))
    rank = np.arange(len(order)) - np.searchsorted(bins[order], bins[order])
    expected = np.sort(order[rank < 300])
    assert store.subsampled
    assert np.array_equal(np.sort(store.pooled()["pixels"]), expected)


def test_sieved_photos_keep_each_bins_smallest_keys_among_the_unshadowed():
    """The sieve draws each later photo's keys before its shadow rays and drops what a full bin
    could never keep; shadowed samples then leave with their keys. After every photo the store
    holds exactly what a single sort over every unshadowed sample would keep (per bin, the
    `cap` smallest keys), so the subset stays uniform over what could be kept."""
    options = replace(ExtractOptions(), sample_budget=3000, max_samples_per_bin=400)
    store = SampleStore(options, seed=5)
    rng = np.random.default_rng(2)
    parts = [_part(rng.uniform(0.2, 0.5, 1500), k) for k in range(25)]
    keys = np.random.default_rng(5).random(1500 * 25, np.float32)  # the store's draws, in order
    theta_h = np.concatenate([p["theta_h"] for p in parts]).astype(np.float32)
    bins = merl_bin_index(theta_h, 0.0, 0.0)[0]
    lit = np.ones(1500 * 25, bool)
    sieved_away = 0
    for k, part in enumerate(parts):
        ids = np.arange(1500) + 1500 * k
        part["pixels"] = ids
        sieved = store.sieve(part["theta_h"])
        if sieved is not None:
            wanted, part_keys = sieved
            assert np.array_equal(part_keys, keys[ids][wanted])
            sieved_away += int((~wanted).sum())
            lit[ids[ids % 3 == 0]] = False  # a third of this photo is in shadow
            survive = wanted & lit[ids]
            part = {name: values[survive] for name, values in part.items()}
            part["key"] = part_keys[lit[ids][wanted]]
        store.add(part)
        if not store.subsampled:
            continue
        seen = np.flatnonzero(lit[:1500 * (k + 1)])
        expected = set()
        for b in np.unique(bins[seen]):
            mine = seen[bins[seen] == b]
            expected.update(mine[np.argsort(keys[mine], kind="stable")[:400]].tolist())
        assert set(store.pooled()["pixels"].tolist()) == expected, k
    # ~1,400 unshadowed samples per bin for a cap of 400: a key passes the sieve about
    # (400 + 400 ln(1400 / 400)) / 1400 ~ 64% of the time, so ~36% of the 22 sieved photos'
    # 33,000 samples never reach the shadow rays; 30% leaves room for the bins' spread
    assert sieved_away > 0.30 * 22 * 1500


def test_depth_edges_mark_both_sides_of_a_jump_only():
    camera = SimpleNamespace(shape=(6, 8), model="pinhole", fx=1000.0, fy=1000.0)
    depth = np.full((6, 8), np.inf, np.float32)
    depth[1:5, 1:7] = 1.0
    depth[2:4, 3:5] = 0.8            # a nearer block: a 0.2 jump, 200 pixel footprints
    depth[1, 1] = 1.0 + 0.015        # a slope of 15 footprints: a steep surface, no edge
    edge = depth_edge_mask(depth, camera, 20.0, 1)
    want = np.zeros((6, 8), bool)
    want[2:4, 2:6] = True            # the block and the far pixels beside it, in rows
    want[1:5, 3:5] = True            # ... and in columns
    want[2:4, 3:5] = True
    assert np.array_equal(edge, want)
    assert not depth_edge_mask(depth, camera, 0.0, 1).any()


def test_many_photos_subsampled_give_the_slice_all_of_them_give(tmp_path):
    """Three flash photos of a sphere; extracted whole and with a budget that forces the
    per-bin subsample to ~1/4 of the samples: every bin within 1% (the subsample's noise on
    noise-free pixels is the spread of rho within a bin)."""
    folder = write_synthetic_scene(tmp_path, sphere_mesh(), ggx_lambert(), pinhole_camera(160, 160),
                                   [point_light([x, 0, 0]) for x in (0.0, 0.01, 0.02)])
    whole = extract_slice(folder)
    total = int(whole.n.sum())
    options = replace(ExtractOptions(), sample_budget=total // 8,
                      max_samples_per_bin=max(1, int(whole.n.max()) // 4))
    samples = collect_samples(folder, options)
    capped = bin_samples(samples)
    assert samples.first_photo_samples is not None  # segmentation still sees photo 0 whole
    # the later photos were sieved: what full bins could never keep skipped the shadow rays
    assert samples.per_photo[0]["not_needed"] == 0 < samples.per_photo[2]["not_needed"]
    assert capped.n.max() <= options.max_samples_per_bin
    both = np.isfinite(whole.rho).all(axis=1) & np.isfinite(capped.rho).all(axis=1)
    assert both.sum() >= 0.9 * np.isfinite(whole.rho).all(axis=1).sum()
    assert np.max(np.abs(capped.rho[both] / whole.rho[both] - 1)) < 0.01


def test_prefetched_photos_are_the_photos_read_in_turn(tmp_path):
    """The next photo is decoded in a thread while this one is worked on: the same images,
    in the same order, and a bad later photo is raised when it is asked for, not before."""
    from flashbrdf.capture import iter_flash_images, load_scene
    from flashbrdf.files.errors import InputError
    folder = write_synthetic_scene(tmp_path, sphere_mesh(), ggx_lambert(), pinhole_camera(40, 40),
                                   [point_light([x, 0, 0]) for x in (0.0, 0.01, 0.02)])
    scene = load_scene(folder)
    plain = list(iter_flash_images(scene, prefetch=False))
    ahead = list(iter_flash_images(scene))
    assert [a.photo.file for a in ahead] == [p.photo.file for p in plain]
    assert all(np.array_equal(a.radiance, p.radiance) and np.array_equal(a.usable, p.usable)
               for a, p in zip(ahead, plain))
    plain[2].photo.file.write_bytes(b"not an image")
    images = iter_flash_images(scene)
    assert next(images).photo.file == plain[0].photo.file
    next(images)
    with pytest.raises(InputError, match=plain[2].photo.file.name):
        next(images)


def test_a_multiview_flash_photo_without_its_views_ambient_is_refused(tmp_path):
    """Ambient photos are subtracted view by view. A second view with no ambient photo of its
    own is refused, naming it: the first view's ambient light lies on other pixels. With every
    flash photo of one view, the ambient photo applies (its camera may be given apart)."""
    import json
    import shutil

    from flashbrdf import capture
    from flashbrdf.files.errors import InputError
    scene = write_synthetic_scene(tmp_path / "s", sphere_mesh(subdivisions=2), ggx_lambert(),
                                  pinhole_camera(24, 24, 40.0), [point_light([0.02, 0, 0])])
    shutil.copy(scene / "flash0.exr", scene / "ambient0.exr")
    shutil.copy(scene / "flash0.exr", scene / "flash1.exr")
    doc = json.loads((scene / "scene.json").read_text())
    turned = json.loads(json.dumps(doc["camera"]))
    turned["world_from_camera"][0][3] = 0.01  # a second view, 1 cm aside
    doc["photos"].append({"file": "ambient0.exr", "role": "ambient"})
    (scene / "scene.json").write_text(json.dumps(doc))
    one_view = list(capture.iter_flash_images(capture.load_scene(scene)))
    assert len(one_view) == 1 and float(np.abs(one_view[0].radiance).max()) == 0.0  # a - a
    doc["photos"].append({**doc["photos"][0], "file": "flash1.exr", "camera": turned})
    (scene / "scene.json").write_text(json.dumps(doc))
    images = capture.iter_flash_images(capture.load_scene(scene))
    next(images)  # the first view has its ambient photo
    with pytest.raises(InputError, match=r"photos\[2\].*no ambient photo"):
        next(images)


@pytest.mark.parametrize("photo_format", ["exr", "png16"])
def test_a_dark_rooms_ambient_photo_of_zeros_costs_no_flash_pixel(tmp_path, photo_format):
    """An ambient photo at 0 (a dark room; below one code in 8/16 bits) measures no ambient light:
    subtracting it must leave the flash photo's usable pixels as they are. Zeros made the flash
    pixels under them unusable: half a black ambient photo dropped half the samples, a wholly
    black one exited 2 ("no usable pixel", naming the flash photo). A clipped ambient pixel
    still makes its flash pixel unusable."""
    import json

    from flashbrdf import capture
    from synthetic import write_exr, write_png16
    scene = write_synthetic_scene(tmp_path / "s", sphere_mesh(subdivisions=3), ggx_lambert(),
                                  pinhole_camera(48, 48, 160.0), [point_light([0.02, 0, 0])],
                                  photo_format=photo_format)
    (plain,) = capture.iter_flash_images(capture.load_scene(scene))
    n_usable = int(plain.usable.sum())
    assert n_usable > 500
    ambient = np.zeros((48, 48, 3))
    ambient[:24] = 1.0        # the top half clipped (the 16-bit code's ceiling, or past 0.9)
    name = f"ambient.{'exr' if photo_format == 'exr' else 'png'}"
    if photo_format == "exr":
        write_exr(scene / name, ambient)
        entry = {"file": name, "role": "ambient", "saturation": 0.9}
    else:
        write_png16(scene / name, ambient, 1.0)
        entry = {"file": name, "role": "ambient", "encoding": "linear"}
    doc = json.loads((scene / "scene.json").read_text())
    doc["photos"].append(entry)
    (scene / "scene.json").write_text(json.dumps(doc))
    (dark,) = capture.iter_flash_images(capture.load_scene(scene))
    bottom = np.zeros((48, 48), bool)
    bottom[24:] = True
    # every usable flash pixel under the ambient's zeros stays usable, none under its clipped half
    assert int(dark.usable.sum()) == int((plain.usable & bottom).sum()) > 200
    np.testing.assert_array_equal(dark.radiance[bottom], plain.radiance[bottom])
