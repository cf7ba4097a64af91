"""A flash photo lit unlike scene.json says is named: ambient shots registered by SfM beside the
flash photos were imported as flash photos, and pulled the slice's peak bins to 0.52x, silently."""

import json

import numpy as np

from flashbrdf.cli.main import main
from synthetic import ggx_lambert, pinhole_camera, point_light, sphere_mesh, write_synthetic_scene


def test_a_photo_off_the_pooled_level_is_named(tmp_path, capsys):
    # three photos of one view; the third's flash gave a twentieth of what scene.json states
    lights = [point_light([0.03, 0, 0])] * 2 + [point_light([0.03, 0, 0], [0.05] * 3)]
    folder = write_synthetic_scene(tmp_path / "scene", sphere_mesh(), ggx_lambert(),
                                   pinhole_camera(96, 96, 400.0), lights, photons=5000)
    doc = json.loads((folder / "scene.json").read_text())
    doc["photos"][2]["light"]["intensity_rgb"] = [1.0, 1.0, 1.0]
    (folder / "scene.json").write_text(json.dumps(doc))
    assert main(["extract", str(folder), "--out", str(tmp_path / "s.csv")]) == 0
    err = capsys.readouterr().err
    assert "1 of 3 flash photos read under half or over twice" in err and "flash2 (0." in err
    photos = json.loads((tmp_path / "s.json").read_text())["photos"]
    levels = [p["level_vs_slice"] for p in photos]
    # the pooled median is the two true photos' level: they read ~1, the dim one ~0.05
    assert abs(levels[0] - 1) < 0.05 and abs(levels[1] - 1) < 0.05
    assert 0.03 < levels[2] < 0.08


def test_photos_that_agree_are_not_named(tmp_path, capsys):
    lights = [point_light([0.03, 0, 0]), point_light([-0.03, 0, 0])]
    folder = write_synthetic_scene(tmp_path / "scene", sphere_mesh(), ggx_lambert(),
                                   pinhole_camera(96, 96, 400.0), lights, photons=5000)
    assert main(["extract", str(folder), "--out", str(tmp_path / "s.csv")]) == 0
    assert "flash photos read" not in capsys.readouterr().err
    levels = [p["level_vs_slice"] for p in json.loads((tmp_path / "s.json").read_text())["photos"]]
    assert np.allclose(levels, 1.0, atol=0.05)


def test_the_photo_records_of_one_pool_are_not_shared_between_slices(tmp_path):
    """Every material's samples share the pool's per-photo records: writing each slice's levels
    into them made every material's coverage read the last one's."""
    from flashbrdf import capture
    from flashbrdf.slice_extract.extract import ExtractOptions, bin_samples, collect_samples
    lights = [point_light([0.03, 0, 0]), point_light([-0.03, 0, 0])]
    folder = write_synthetic_scene(tmp_path / "scene", sphere_mesh(), ggx_lambert(),
                                   pinhole_camera(96, 96, 400.0), lights, photons=5000)
    samples = collect_samples(capture.load_scene(folder), ExtractOptions())
    whole = bin_samples(samples)
    half = bin_samples(samples.subset(samples.photo == 0))
    assert all("level_vs_slice" not in p for p in samples.per_photo)
    assert [("level_vs_slice" in p) for p in half.report["photos"]] == [True, False]
    assert all("level_vs_slice" in p for p in whole.report["photos"])
    assert "level_vs_slice" not in bin_samples(samples, photo_levels=False).report["photos"][0]
