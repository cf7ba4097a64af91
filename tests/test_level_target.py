"""The slice's absolute level from a diffuse target of known reflectance (scene.json "level"):
a capture rendered at an intensity the scene does not know is recovered within 2%."""

import json

import numpy as np
import pytest
import trimesh

from flashbrdf.brdf.views import read_slice_csv
from flashbrdf.cli.main import main
from synthetic import (by_region, combine, ggx_lambert, pinhole_camera, point_light, sphere_mesh,
                       true_slice, write_synthetic_scene)

TRUE_INTENSITY = 3.7   # what the flash gave; scene.json says 1
REFLECTANCE = 0.18     # a grey card


def card_mesh(z=1.15, half=0.25):
    """A square card facing the camera (normal -z) behind the sphere, with vertex normals."""
    vertices = np.array([[-half, -half, z], [half, -half, z], [half, half, z], [-half, half, z]])
    mesh = trimesh.Trimesh(vertices, [[0, 2, 1], [0, 3, 2]], process=False)
    mesh.vertex_normals = np.tile([0.0, 0.0, -1.0], (4, 1))
    return mesh


def lambert(albedo):
    def brdf(wi, wo, normal):
        return np.full((len(wi), 3), albedo / np.pi)
    return brdf


@pytest.fixture(scope="module")
def capture_with_card(tmp_path_factory):
    """A sphere (GGX) before a grey card, flash 3 cm right of the lens at 3.7x the intensity the
    scene states; object.ply is the sphere alone, card.ply the card."""
    folder = tmp_path_factory.mktemp("card")
    sphere, card = sphere_mesh(), card_mesh()
    brdf = by_region([ggx_lambert(), lambert(REFLECTANCE)], lambda p: (p[:, 2] > 1.12).astype(int))
    write_synthetic_scene(folder, combine(sphere, card), brdf, pinhole_camera(160, 160, 500.0),
                          [point_light([0.03, 0, 0], [TRUE_INTENSITY] * 3)])
    sphere.export(str(folder / "object.ply"), vertex_normal=True)
    card.export(str(folder / "card.ply"), vertex_normal=True)
    doc = json.loads((folder / "scene.json").read_text())
    doc["photos"][0]["light"]["intensity_rgb"] = [1.0, 1.0, 1.0]
    (folder / "scene.json").write_text(json.dumps(doc))
    return folder


def _with_level(folder, tmp_path, level):
    doc = json.loads((folder / "scene.json").read_text())
    doc["level"] = level
    tmp_path.mkdir(parents=True, exist_ok=True)
    for name in ("object.ply", "card.ply", "flash0.exr"):
        (tmp_path / name).symlink_to(folder / name)
    (tmp_path / "scene.json").write_text(json.dumps(doc))
    return tmp_path


def _median_ratio(path):
    rho, n = read_slice_csv(path)
    want = true_slice(ggx_lambert())
    ok = n >= 20
    return float(np.median(rho[ok] / want[ok])), int(ok.sum())


def test_without_a_level_the_slice_is_relative(capture_with_card, tmp_path):
    """The unknown intensity scales the whole slice (3.7x here), and every output says the level
    is relative."""
    assert main(["extract", str(capture_with_card), "--out", str(tmp_path / "s.csv")]) == 0
    ratio, bins = _median_ratio(tmp_path / "s.csv")
    assert bins >= 40 and abs(ratio / TRUE_INTENSITY - 1) < 0.02
    level = json.loads((tmp_path / "s.json").read_text())["level"]
    assert level["absolute"] is False and "relative" in level["note"]
    assert "# level: relative" in (tmp_path / "s.csv").read_text()


def test_a_grey_card_recovers_the_level_within_2_percent(capture_with_card, tmp_path):
    scene = _with_level(capture_with_card, tmp_path / "scene",
                        {"target": {"mesh": "card.ply", "reflectance": REFLECTANCE}})
    out = tmp_path / "s.csv"
    assert main(["extract", str(scene), "--out", str(out)]) == 0
    ratio, bins = _median_ratio(out)
    assert bins >= 40 and abs(ratio - 1) < 0.02, ratio
    level = json.loads((tmp_path / "s.json").read_text())["level"]
    assert level["absolute"] is True and level["samples"] > 1000
    # the flash, calibrated: the intensity it really had, in the scene's units
    np.testing.assert_allclose(level["flash_intensity_rgb"][0], TRUE_INTENSITY, rtol=0.02)
    # and infer carries it into BRDF.json
    assert main(["infer", "--slice", str(out), "--method", "chandraker", "--out",
                 str(tmp_path / "b.binary")]) == 0
    assert json.loads((tmp_path / "b.json").read_text())["level"]["absolute"] is True


def test_a_target_out_of_view_is_bad_input(capture_with_card, tmp_path, capsys):
    far = card_mesh(z=-5.0)   # behind the camera: never seen
    scene = _with_level(capture_with_card, tmp_path / "scene",
                        {"target": {"mesh": "far.ply", "reflectance": [0.18, 0.18, 0.18]}})
    far.export(str(scene / "far.ply"), vertex_normal=True)
    assert main(["extract", str(scene), "--out", str(tmp_path / "s.csv")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "level.target" in err[0] and not (tmp_path / "s.csv").exists()
    assert "seen in 0 usable flash pixels" in err[0] and "within 60°" in err[0]


@pytest.mark.parametrize("level,field", [({"target": {"mesh": "card.ply", "reflectance": 1.5}},
                                          "level.target.reflectance"),
                                         ({"calibrated": "yes"}, "level.calibrated"),
                                         ({}, "level")])
def test_a_bad_level_field_is_named(capture_with_card, tmp_path, capsys, level, field):
    scene = _with_level(capture_with_card, tmp_path / "scene", level)
    assert main(["extract", str(scene), "--out", str(tmp_path / "s.csv")]) == 2
    assert field in capsys.readouterr().err


def test_a_card_in_other_units_is_bad_input(capture_with_card, tmp_path, capsys):
    """card.ply in cm beside a scene in metres: it was accepted, and its level divided the slice
    by the square of its extra distance (ρ × 0.002 from a photogrammetry model); a target over
    TARGET_DEPTH_RATIO times as far as the object is refused, naming the target."""
    scene = _with_level(capture_with_card, tmp_path / "scene",
                        {"target": {"mesh": "card_cm.ply", "reflectance": REFLECTANCE}})
    card_cm = card_mesh()
    card_cm.apply_scale(100.0)
    card_cm.export(str(scene / "card_cm.ply"), vertex_normal=True)
    assert main(["extract", str(scene), "--out", str(tmp_path / "s.csv")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "level.target" in err[0] and not (tmp_path / "s.csv").exists()
    ratio = float(err[0].split("the target lies ")[1].split("x")[0])
    assert 100 < ratio < 140       # 115 m against the sphere's ~0.9 m


def test_a_card_far_behind_an_orthographic_view_under_a_directional_flash_is_used(tmp_path):
    """Distance sets the level only for a point light through a pinhole: an orthographic camera's
    depth is from an arbitrary plane and a directional light's irradiance does not fall off. With
    the image plane 2 cm before the sphere and the card 60 cm behind it (depth ratio ~12), the
    card must still give the level (the distance check refused it)."""
    from synthetic import directional_light, orthographic_camera
    sphere, card = sphere_mesh(), card_mesh(z=1.5, half=0.3)
    brdf = by_region([ggx_lambert(), lambert(REFLECTANCE)], lambda p: (p[:, 2] > 1.4).astype(int))
    pose = np.eye(4)
    pose[2, 3] = 0.88
    folder = write_synthetic_scene(tmp_path / "scene", combine(sphere, card), brdf,
                                   orthographic_camera(160, 160, 0.0025, pose),
                                   [directional_light([0, 0, -1], [TRUE_INTENSITY] * 3)])
    sphere.export(str(folder / "object.ply"), vertex_normal=True)
    card.export(str(folder / "card.ply"), vertex_normal=True)
    doc = json.loads((folder / "scene.json").read_text())
    doc["photos"][0]["light"]["irradiance_rgb"] = [1.0, 1.0, 1.0]
    doc["level"] = {"target": {"mesh": "card.ply", "reflectance": REFLECTANCE}}
    (folder / "scene.json").write_text(json.dumps(doc))
    assert main(["extract", str(folder), "--out", str(tmp_path / "s.csv")]) == 0
    rho, n = read_slice_csv(tmp_path / "s.csv")
    want = true_slice(ggx_lambert())
    ok = n >= 20
    assert ok.sum() >= 20 and abs(np.median(rho[ok] / want[ok]) - 1) < 0.02
