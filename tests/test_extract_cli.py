"""`flashbrdf extract`: outputs, and bad input -> exit 2, one line, no output file."""

import json

import numpy as np
import pytest

from flashbrdf.brdf.views import read_slice_csv
from flashbrdf.cli.main import main
from synthetic import (ggx_lambert, orthographic_camera, pinhole_camera, point_light,
                       sphere_mesh, true_slice, write_exr, write_synthetic_scene)


@pytest.fixture()
def scene(tmp_path):
    return write_synthetic_scene(tmp_path / "scene", sphere_mesh(subdivisions=4), ggx_lambert(),
                                 pinhole_camera(96, 96, 400.0), [point_light()])


def test_extract_writes_slice_and_report(scene, tmp_path, capsys):
    out = tmp_path / "out" / "slice.csv"
    assert main(["extract", str(scene), "--out", str(out)]) == 0
    rho, n = read_slice_csv(out)
    report = json.loads(out.with_suffix(".json").read_text())
    assert np.array_equal(n, report["n"])
    assert np.all(np.isnan(rho[n == 0])) and np.all(np.isfinite(rho[n > 0]))
    assert report["coverage"]["pixels_used"] == n.sum()
    assert set(report["rejected"]) >= {"unusable", "miss", "grazing", "theta_d", "shadowed",
                                       "outlier"}
    assert report["timings_s"]["total"] > 0 and report["theta_d_deg"]["max"] < 1e-4
    assert out.read_text().startswith("# flashbrdf extract")


def _edit(scene, fn):
    doc = json.loads((scene / "scene.json").read_text())
    fn(doc)
    (scene / "scene.json").write_text(json.dumps(doc))


def _turn_camera_away(doc):
    doc["camera"]["world_from_camera"] = [[-1, 0, 0, 0], [0, 1, 0, 0], [0, 0, -1, 0], [0, 0, 0, 1]]


def _bad_position(doc):
    doc["photos"][0]["light"]["position"] = [0, 0]


def _missing_photo(doc):
    doc["photos"][0]["file"] = "nowhere.exr"


def _wrong_size(doc):
    doc["camera"]["width"] = 95


def _point_light_on_normal_map(doc):
    doc["geometry"] = {"normal_map": "n.npy", "mask": "m.png"}


def _black_photo(scene):
    write_exr(scene / "flash0.exr", np.zeros((96, 96, 3)))


@pytest.mark.parametrize("edit, expect", [
    (_turn_camera_away, "does not see the geometry"),
    (_bad_position, "scene.json: photos[0].light.position: expected 3 numbers"),
    (_missing_photo, "nowhere.exr: file not found"),
    (_wrong_size, "flash0.exr: image is 96x96 but the camera is 95x96"),
    (_point_light_on_normal_map, "photos[0].light.type: a point light needs surface depth"),
    (_black_photo, "flash0.exr: no usable pixel"),
])
def test_bad_input_exits_2_with_one_line(scene, tmp_path, capsys, edit, expect):
    if edit is _black_photo:
        edit(scene)
    else:
        _edit(scene, edit)
    out = tmp_path / "out" / "slice.csv"
    assert main(["extract", str(scene), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and expect in err
    assert not out.exists() and not out.with_suffix(".json").exists()
    assert not list((tmp_path / "out").glob("*")) if (tmp_path / "out").exists() else True


def test_bad_options_exit_2(scene, tmp_path, capsys):
    out = tmp_path / "s.csv"
    assert main(["extract", str(scene), "--out", str(out), "--max-theta-d", "-1"]) == 2
    assert "--max-theta-d" in capsys.readouterr().err and not out.exists()


def test_far_light_rejected_by_theta_d(scene, tmp_path, capsys):
    """A light 0.5 m off axis gives theta_d ~ 13 deg: no sample, and the error says why."""
    _edit(scene, lambda d: d["photos"][0]["light"].update(position=[0.5, 0, 0]))
    assert main(["extract", str(scene), "--out", str(tmp_path / "s.csv")]) == 2
    assert "mostly 'theta_d'" in capsys.readouterr().err
    assert main(["extract", str(scene), "--out", str(tmp_path / "s.csv"),
                 "--max-theta-d", "20"]) == 0


@pytest.mark.parametrize("offset, warned", [(0.02, False), (0.16, False), (0.17, True)])
def test_a_flash_too_far_from_the_lens_is_warned_of(tmp_path, capsys, offset, warned):
    """The sphere's front is 0.9 m away: a flash 0.16 m off puts θd ≈ atan(0.16 / 0.9) / 2 =
    5.0° there and loses a fifth of the pixels; 0.17 m (5.4°) loses nearly all (measured 96%),
    and the slice then rests on a few dozen pixels: extract says so, and SLICE.json keeps it."""
    scene = write_synthetic_scene(tmp_path / "scene", sphere_mesh(subdivisions=3), ggx_lambert(),
                                  pinhole_camera(64, 64, 200.0), [point_light([offset, 0, 0])])
    capsys.readouterr()
    assert main(["extract", str(scene), "--out", str(tmp_path / "s.csv")]) == 0
    err = capsys.readouterr().err
    report = json.loads((tmp_path / "s.json").read_text())
    rejected = report["rejected"]
    share = rejected["theta_d"] / (rejected["theta_d"] + rejected["shadowed"]
                                   + rejected["outlier"] + report["coverage"]["pixels_used"])
    assert (share > 0.5) == warned
    assert ("lie past θd 5°" in err) == warned and bool(report["warnings"]) == warned


def test_photos_that_share_a_stem_are_told_apart_in_the_report(tmp_path):
    """Views in subfolders (ringA/img_0.exr, ringB/img_0.exr, as an import of a COLMAP model
    with image folders writes them): slice.json names each photo by its path there, not twice
    by one stem; a photo whose stem is its own keeps the stem."""
    scene = write_synthetic_scene(tmp_path / "scene", sphere_mesh(subdivisions=3), ggx_lambert(),
                                  pinhole_camera(64, 64, 200.0),
                                  [point_light([0.01, 0, 0]), point_light([0, 0.01, 0]),
                                   point_light([-0.01, 0, 0])])
    flashes = [p for p in json.loads((scene / "scene.json").read_text())["photos"]
               if p["role"] == "flash"]
    new_names = ["ringA/img_0.exr", "ringB/img_0.exr", "other.exr"]
    for photo, name in zip(flashes, new_names):
        (scene / name).parent.mkdir(exist_ok=True)
        (scene / photo["file"]).rename(scene / name)

    def rename(doc):
        for photo, name in zip([p for p in doc["photos"] if p["role"] == "flash"], new_names):
            photo["file"] = name
    _edit(scene, rename)
    assert main(["extract", str(scene), "--out", str(tmp_path / "s.csv")]) == 0
    report = json.loads((tmp_path / "s.json").read_text())
    assert [p["photo"] for p in report["photos"]] == ["ringA/img_0.exr", "ringB/img_0.exr",
                                                      "other"]


def test_normal_map_orthographic_directional(tmp_path):
    """Normal-map geometry (no ray casting) with an orthographic camera and a directional light
    along the view, rendered here from the analytic sphere: the slice comes back within 1%."""
    import cv2
    from flashbrdf.slice_extract import extract_slice
    size, radius = 160, 70.0
    v, u = np.mgrid[0:size, 0:size] - (size - 1) / 2
    inside = u ** 2 + v ** 2 < radius ** 2
    nz = -np.sqrt(np.clip(1 - (u ** 2 + v ** 2) / radius ** 2, 0, None))  # toward the camera
    normals = np.where(inside[..., None], np.stack([u / radius, v / radius, nz], -1), 0)
    brdf = ggx_lambert(alpha=0.3)
    wo = np.tile([0, 0, -1.0], (inside.sum(), 1))
    n = normals[inside]
    image = np.zeros((size, size, 3))
    image[inside] = brdf(wo, wo, n) * 2.0 * np.clip(-n[:, 2], 0, None)[:, None]  # E = 2
    np.save(tmp_path / "normals.npy", normals)
    cv2.imwrite(str(tmp_path / "mask.png"), inside.astype(np.uint8) * 255)
    write_exr(tmp_path / "flash.exr", image)
    doc = {"camera": orthographic_camera(size, size, 1.0),
           "geometry": {"normal_map": "normals.npy", "mask": "mask.png"},
           "photos": [{"file": "flash.exr", "role": "flash",
                       "light": {"type": "directional", "direction": [0, 0, -1],
                                 "irradiance_rgb": [2, 2, 2]}}]}
    (tmp_path / "scene.json").write_text(json.dumps(doc))
    result = extract_slice(tmp_path)
    truth = true_slice(brdf)
    ok = result.n >= 20
    assert ok.sum() >= 50
    assert np.median(np.abs(result.rho[ok] / truth[ok] - 1)) < 0.01


def test_silhouette_mask_is_the_outline_ring_not_the_frame():
    from flashbrdf.slice_extract import silhouette_mask
    obj = np.zeros((9, 12), bool)
    obj[2:7, 2:7] = True  # a 5x5 object
    obj[:, 9:] = True  # an object cut by the image frame
    ring = silhouette_mask(obj, 1)
    assert ring[2:7, 2:7].sum() == 16 and not ring[3:6, 3:6].any()
    assert ring[:, 9].all() and not ring[:, 10:].any()  # frame side kept
    assert not silhouette_mask(obj, 0).any()


def test_half_diff_thetas_match_brdf_angles():
    """slice_extract's lean theta_h/theta_d (no phi_d, float32-ready) equals brdf.angles'."""
    from flashbrdf.brdf.angles import half_diff_from_world
    from flashbrdf.slice_extract import half_diff_thetas
    rng = np.random.default_rng(5)
    n = rng.normal(size=(2000, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    wi, wo = (v / np.linalg.norm(v, axis=1, keepdims=True)
              for v in (n + rng.normal(scale=0.6, size=n.shape) for _ in range(2)))
    wo[:5] = wi[:5] = n[:5]  # theta_h = theta_d = 0 exactly
    th, td, _ = half_diff_from_world(wi, wo, n)
    ours_h, ours_d = half_diff_thetas(wi, wo, n)
    assert np.abs(ours_h - th).max() < 1e-12 and np.abs(ours_d - td).max() < 1e-12
    h32, d32 = half_diff_thetas(*(v.astype(np.float32) for v in (wi, wo, n)))
    assert np.abs(h32 - th).max() < 1e-5 and np.abs(d32 - td).max() < 1e-5  # float32 path


@pytest.mark.parametrize("long_scale, warned", [(16.0, True), (1.0, False)])
def test_an_exposure_series_whose_clipped_pixels_hold_no_value_is_warned_of(tmp_path, capsys,
                                                                             long_scale, warned):
    """One view and flash twice, the second 16 times as long with its clipped pixels at +inf (a
    float image's mark, no value): they count as brighter than every measured sample of their
    θh bin and void the bins the short photo measured. extract names both photos and points to
    `brackets`; two photos at one scale (repeats to average noise) are not warned of."""
    from flashbrdf.capture import load_photo
    scene = write_synthetic_scene(tmp_path / "scene", sphere_mesh(subdivisions=3), ggx_lambert(),
                                  pinhole_camera(64, 64, 200.0), [point_light([0.01, 0, 0])])
    image = load_photo(scene / "flash0.exr")[0]
    ceiling = 1.5 * float(image.max())
    long = image * long_scale
    write_exr(scene / "long.exr", np.where(long >= ceiling, np.inf, long))

    def add(doc):
        doc["photos"].append({**doc["photos"][0], "file": "long.exr", "scale": long_scale,
                              "saturation": ceiling})
    _edit(scene, add)
    capsys.readouterr()
    assert main(["extract", str(scene), "--out", str(tmp_path / "s.csv")]) == 0
    lines = [w for w in json.loads((tmp_path / "s.json").read_text())["warnings"]
             if "brackets" in w]
    assert len(lines) == int(warned)
    if warned:
        assert lines[0].startswith("photos[1] clips ") and "(+inf)" in lines[0]
        assert "photos[0] is the same view" in lines[0]
        assert lines[0] in capsys.readouterr().err


def test_an_exposure_series_given_as_separate_photos_gives_the_short_photos_slice(tmp_path):
    """One view and flash twice, the second 16 times as long and clipped at 1.5 times the short
    photo's brightest pixel (its clipped pixels hold the clip value, as a sensor's do). A clipped
    sample is a lower bound, 1.5 max / 16 here, below what the short photo measured in its bin:
    it is set aside, not counted brighter than every measured sample, so the pair gives the
    short photo's own slice. When clipped samples were taken as +inf they voided most of the
    bins the short photo measured."""
    from flashbrdf.capture import load_photo
    scene = write_synthetic_scene(tmp_path / "scene", sphere_mesh(subdivisions=3), ggx_lambert(),
                                  pinhole_camera(64, 64, 200.0), [point_light([0.01, 0, 0])])
    assert main(["extract", str(scene), "--out", str(tmp_path / "short.csv")]) == 0
    image = load_photo(scene / "flash0.exr")[0]
    ceiling = 1.5 * float(image.max())
    write_exr(scene / "long.exr", np.minimum(image * 16.0, ceiling))

    def add(doc):
        doc["photos"].append({**doc["photos"][0], "file": "long.exr", "scale": 16.0,
                              "saturation": ceiling})
    _edit(scene, add)
    assert main(["extract", str(scene), "--out", str(tmp_path / "pair.csv")]) == 0
    (short, _), (pair, _) = (read_slice_csv(tmp_path / f"{name}.csv")
                             for name in ("short", "pair"))
    assert json.loads((tmp_path / "pair.json").read_text())["photos"][1]["clipped"] > 100
    measured = np.isfinite(short).all(1)
    assert measured.sum() >= 50
    assert np.array_equal(np.isfinite(pair).all(1), measured)
    truth = true_slice(ggx_lambert())
    error = np.abs(pair / truth - 1)[measured]
    assert np.median(error) < 1e-3  # as the short photo alone: its own error is 1e-4
    # a bin still holding clipped samples above its median takes the median, which sits off the
    # bin's centre by up to half a bin: within the truth's change over half a bin
    half_bin = (np.abs(np.roll(truth, -1, 0) - np.roll(truth, 1, 0)) / (4 * truth))[measured]
    assert np.all(error <= half_bin + 1e-3)
