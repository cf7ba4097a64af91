"""Renders under an environment map when a capture has no reference photo (or run --envmap):
the object from the flash camera and a sphere per material, with known answers for a Lambertian
BRDF under a constant map."""

import base64
import json

import numpy as np
import pytest

from flashbrdf import capture
from flashbrdf.brdf.models import Lambert
from flashbrdf.cli.main import main
from flashbrdf.pipeline.previews import camera_facing_envmap, preview_camera, render_previews
from flashbrdf.render import SceneGeometry, read_image, write_exr
from synthetic import ggx_lambert, pinhole_camera, point_light, sphere_mesh, write_synthetic_scene


@pytest.fixture
def flash_only(tmp_path):
    return write_synthetic_scene(tmp_path / "scene", sphere_mesh(), ggx_lambert(),
                                 pinhole_camera(96, 96, 600.0), [point_light([0.02, 0, 0])])


def test_lambert_under_a_constant_map_is_albedo_times_radiance(flash_only, tmp_path):
    """rho = a/pi under L from every direction: every visible pixel's expected value is a L (no
    occluder on a sphere), for the object and the sphere alike. 16 samples a pixel leave a
    per-pixel noise of a few per cent (MIS of the map's and the BRDF's sampling); the mean over
    the thousands of lit pixels is within 1%, their median within 3%."""
    envmap = tmp_path / "grey.exr"
    write_exr(envmap, np.full((32, 64, 3), 2.0, np.float32))
    scene = capture.load_scene(flash_only)
    table = np.full((90, 90, 3), 0.5 / np.pi)
    table[:, 89] = np.nan
    out = tmp_path / "out"
    found = render_previews(scene, SceneGeometry(scene), {"lambert": Lambert(0.5)},
                            {"lambert": {1: table}}, envmap, out, spp=16)
    obj = read_image(out / "lambert" / "preview_object.exr")
    sphere = read_image(out / "lambert" / "preview_sphere.exr")
    for image in (obj, sphere):
        lit = image[..., 0] > 0
        assert lit.sum() > 1000
        assert abs(image[lit].mean() - 1.0) < 0.01 and abs(np.median(image[lit]) - 1.0) < 0.03
    assert found == {"lambert": {"object": "lambert/preview_object.png",
                                 "spheres": {1: "lambert/preview_sphere.png"}}}


def test_the_map_turns_with_the_camera_and_small_cameras_keep_their_view():
    from flashbrdf.capture.scene import Camera
    pose = np.eye(4)
    pose[:3, :3] = [[0, 0, 1], [1, 0, 0], [0, 1, 0]]  # a camera looking along world +y
    big = Camera("pinhole", 4000, 3000, pose, fx=3000.0, fy=3000.0, cx=1999.5, cy=1499.5)
    rotation = camera_facing_envmap(big)
    assert np.allclose(rotation @ rotation.T, np.eye(3)) and np.isclose(np.linalg.det(rotation), 1)
    # the map's up (+y) is the camera's up (-y in the camera frame), its centre (-z) behind it
    assert np.allclose(rotation[:, 1], -pose[:3, 1]) and np.allclose(rotation[:, 2], pose[:3, 2])
    small = preview_camera(big, 640)
    assert (small.width, small.height) == (640, 480)
    point = np.array([[0.3, 5.0, -0.2]])   # in front of the camera
    uv_big, _ = capture.project_points(big, point)
    uv_small, _ = capture.project_points(small, point)
    np.testing.assert_allclose((uv_small + 0.5) * 4000 / 640, uv_big + 0.5, rtol=1e-9)


def test_run_without_reference_photos_renders_previews(flash_only, tmp_path):
    out = tmp_path / "run"
    assert main(["run", str(flash_only), "--out", str(out), "--methods", "chandraker"]) == 0
    report = json.loads((out / "report.json").read_text())
    assert report["references"] == []
    renders = report["previews"]["renders"]["chandraker"]
    assert (out / renders["object"]).is_file() and (out / renders["spheres"]["1"]).is_file()
    assert (out / "envmap_studio.exr").is_file()
    assert "## Renders under an environment map" in (out / "report.md").read_text()
    # and report.html shows the same renders: the PNGs run wrote, byte for byte
    from flashbrdf.pipeline.report_html import page_data
    meta, _ = page_data(out / "report.html")
    shown = {r["what"]: base64.b64decode(r["src"].removeprefix("data:image/png;base64,"))
             for r in meta["previews"]["renders"]}
    assert meta["previews"]["envmap"] == "envmap_studio.exr"
    assert shown == {"the object": (out / renders["object"]).read_bytes(),
                     "a sphere": (out / renders["spheres"]["1"]).read_bytes()}


def test_run_envmap_that_is_not_there_is_bad_input(flash_only, tmp_path, capsys):
    missing = tmp_path / "none.hdr"
    assert main(["run", str(flash_only), "--out", str(tmp_path / "o"), "--methods", "chandraker",
                 "--envmap", str(missing)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(missing) in err[0] and not (tmp_path / "o").exists()
