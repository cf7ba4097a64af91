"""Checks of the planar-cards scene writer (benchmarks/planar_scenes.py) that planar_cards.py and
multi_material.py rely on: exact pixel <-> plane mapping, linearisation, and the real data's
orientation. Run: `python -m pytest benchmarks/check_planar_scenes.py`."""

import json
import os
from pathlib import Path

import cv2
import numpy as np
import pytest

from benchmarks.planar_scenes import plane_point_from_pixel, planar_card_scenes, rectified_plane_camera

SHARED = Path(os.environ.get("FLASHBRDF_SHARED", Path(__file__).resolve().parents[2] / "shared"))
CARDS = SHARED / "data" / "real" / "flash-planar-cards-blue"


def _ray_hit_on_plane(camera, u, v):
    """Contract pinhole: back-project pixel (u, v) and intersect the world plane z = 0."""
    pose = np.array(camera["world_from_camera"])
    d_cam = np.stack([(u - camera["cx"]) / camera["fx"], (v - camera["cy"]) / camera["fy"],
                      np.ones_like(u)], -1)
    d_world, origin = d_cam @ pose[:3, :3].T, pose[:3, 3]
    t = -origin[2] / d_world[..., 2]
    return origin + t[..., None] * d_world


@pytest.mark.parametrize("pos", [(0.0, 0.0, 0.2), (0.03, -0.02, 0.17), (-0.05, 0.04, 0.3)])
def test_camera_sees_the_square_exactly(pos):
    side, width, height = 0.06848, 64, 48
    camera = rectified_plane_camera(np.array(pos), side, width, height)
    v, u = np.mgrid[0:height, 0:width].astype(float)
    hits = _ray_hit_on_plane(camera, u, v)
    np.testing.assert_allclose(hits, plane_point_from_pixel(u, v, side, width, height), atol=1e-12)
    # The outer pixel edges are the square's edges; image up is world +y.
    corner = _ray_hit_on_plane(camera, np.array(-0.5), np.array(-0.5))
    np.testing.assert_allclose(corner[:2], [-side / 2, side / 2], atol=1e-12)
    rot = np.array(camera["world_from_camera"])[:3, :3]
    assert np.isclose(np.linalg.det(rot), 1.0)  # right-handed, a proper rotation


def _fake_capture(folder):
    folder.mkdir()
    rng = np.random.default_rng(0)
    for k in range(2):
        cv2.imwrite(str(folder / f"{k:02d}.png"), rng.integers(0, 256, (32, 32, 3), dtype=np.uint8))
    pos = "1.0,0.3,16.7\n-2.0,1.4,18.8\n"
    (folder / "camera_pos.txt").write_text(pos)
    (folder / "light_pos.txt").write_text(pos)
    (folder / "image_size.txt").write_text("6.848")
    (folder / "light_power.txt").write_text("1500.0,1500.0,1500.0")


def test_writes_one_scene_per_view(tmp_path):
    import OpenImageIO as oiio
    _fake_capture(tmp_path / "src")
    views = planar_card_scenes(tmp_path / "src", tmp_path / "out")
    assert [v.name for v in views] == ["view_00", "view_01"]
    scene = json.loads((views[1] / "scene.json").read_text())
    assert [p["role"] for p in scene["photos"]] == ["flash", "reference"]
    light = scene["photos"][0]["light"]
    # Flash at the camera; 1500 pixel-units*cm^2 is 0.15 pixel-units*m^2.
    assert light["type"] == "point" and np.allclose(light["position"], 0, atol=1e-12)
    assert np.allclose(light["intensity_rgb"], 0.15)
    np.testing.assert_allclose(np.array(scene["camera"]["world_from_camera"])[:3, 3],
                               [-0.02, 0.014, 0.188])
    # (x/255)^2.2 as the README says, clipped 255 -> NaN.
    png = cv2.imread(str(tmp_path / "src" / "01.png"))[..., ::-1]
    exr = oiio.ImageInput.open(str(views[1] / "01.exr")).read_image("float")
    clipped = np.any(png == 255, axis=2)
    assert np.isnan(exr[clipped]).all() and np.isfinite(exr[~clipped]).all()
    np.testing.assert_allclose(exr[~clipped], (png[~clipped] / 255.0) ** 2.2, rtol=1e-6)
    import trimesh
    mesh = trimesh.load(views[1] / "plane.ply")
    assert np.allclose(mesh.face_normals, [0, 0, 1]) and np.isclose(mesh.area, 0.06848 ** 2)


@pytest.mark.skipif(not CARDS.is_dir(), reason=f"real planar cards not found at {CARDS}")
def test_real_highlights_fall_under_the_lens(tmp_path):
    """Orientation check on the real data: a flash highlight on a flat glossy surface sits where
    the normal faces the lens, i.e. at the plane point below the camera. Blurred-brightest spots
    of 3 views in different corners must land near that point's pixel, far closer than under the
    mirrored (image up = -y) hypothesis. The cards vary over space, which shifts the blurred
    maximum: over all 9 views the distance is 40-166 px of 1024 (median 102; views 1, 3, 6:
    102, 63, 40) against 147-1031 px mirrored (median 479). The bounds below hold for any subset
    with that median: < 150 px, and mirrored > 3x."""
    # Three views far apart (linked, not copied), to keep the test fast.
    picked = [1, 3, 6]
    small = tmp_path / "cards_subset"
    small.mkdir()
    for i, k in enumerate(picked):
        (small / f"{i:02d}.png").symlink_to(CARDS / f"{k:02d}.png")
    rows = (CARDS / "camera_pos.txt").read_text().split()
    (small / "camera_pos.txt").write_text("\n".join(rows[k] for k in picked) + "\n")
    (small / "light_pos.txt").write_text("\n".join(rows[k] for k in picked) + "\n")
    (small / "image_size.txt").write_text((CARDS / "image_size.txt").read_text())
    views = planar_card_scenes(small, tmp_path / "cards")
    import OpenImageIO as oiio
    errors, mirrored = [], []
    for view in views:
        scene = json.loads((view / "scene.json").read_text())
        cam = scene["camera"]
        image = oiio.ImageInput.open(str(view / scene["photos"][0]["file"])).read_image("float")
        small_lum = cv2.resize(np.nan_to_num(image.mean(axis=2), nan=1.0), None, fx=0.25, fy=0.25,
                               interpolation=cv2.INTER_AREA)
        luminance = cv2.GaussianBlur(small_lum, (0, 0), 6)
        v, u = (np.array(np.unravel_index(np.argmax(luminance), luminance.shape)) + 0.5) * 4 - 0.5
        x, y = np.array(cam["world_from_camera"])[:2, 3]
        side = 0.06848
        u_pred = (x + side / 2) * cam["width"] / side - 0.5
        v_pred = (side / 2 - y) * cam["height"] / side - 0.5
        v_mirror = (y + side / 2) * cam["height"] / side - 0.5
        errors.append(np.hypot(u - u_pred, v - v_pred))
        mirrored.append(np.hypot(u - u_pred, v - v_mirror))
    assert np.median(errors) < 150, errors
    assert np.median(mirrored) > 3 * np.median(errors), (errors, mirrored)
