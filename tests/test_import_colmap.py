"""import-colmap on a synthetic multi-view flash capture with a known BRDF
(tests/colmap_synthetic.py): cameras converted exactly, in both model formats, with and without
the rigs and frames files; COLMAP's pixel convention checked against pycolmap's own projection;
import -> extract gives the known slice; the summary; the mesh frame check's reach.
"""

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from colmap_synthetic import make_colmap_capture, true_slice
from flashbrdf import capture
from flashbrdf.files.errors import InputError
from flashbrdf.capture.importers.colmap import import_colmap
from flashbrdf.capture.importers.colmap_model import read_colmap_model
from flashbrdf.capture.importers.colmap import match_photos, photo_size
from flashbrdf.capture.importers.colmap_model import ModelImage, contract_camera
from flashbrdf.cli.main import main
from flashbrdf.slice_extract import extract_slice

pycolmap = pytest.importorskip("pycolmap")


@pytest.fixture(scope="module")
def made(tmp_path_factory):
    """6 views, two COLMAP cameras (OPENCV with distortion, SIMPLE_RADIAL), noise-free photos,
    plus the pre-3.12 layouts (no rigs and frames files) of both formats."""
    out = tmp_path_factory.mktemp("colmap")
    made = make_colmap_capture(out, views=6)
    for name in ("sparse", "sparse_bin"):
        old = out / f"{name}_old"
        shutil.copytree(out / name, old)
        for f in old.iterdir():
            if f.stem in ("rigs", "frames"):
                f.unlink()
    return made


LAYOUTS = ["sparse", "sparse_bin", "sparse_old", "sparse_bin_old"]


@pytest.mark.parametrize("layout", LAYOUTS)
def test_cameras_and_poses_converted_exactly(made, tmp_path, layout):
    """Text keeps 17 significant digits and binary is exact: the only error left is the
    quaternion <-> matrix round trip, ~1e-16 per entry, so 1e-12 is far above it and far below
    any real error (a 0.5 px shift is 1.7e-3 of fx)."""
    done = import_colmap(made["out"] / layout, made["images"], made["mesh"], tmp_path / "s",
                         flash_offset=(0.03, -0.02, 0))
    assert done.model.format == ("binary" if "bin" in layout else "text")
    assert done.model.rigs_and_frames == ("old" not in layout)
    got = capture.load_scene(tmp_path / "s")
    truth = capture.load_scene(made["truth"])
    assert len(got.photos) == len(truth.photos) == 6
    for a, b in zip(got.photos, truth.photos):
        assert a.file == b.file                       # the photos, referenced, never copied
        ca, cb = a.camera, b.camera
        assert (ca.width, ca.height) == (cb.width, cb.height)
        for key in ("fx", "fy", "cx", "cy"):
            assert getattr(ca, key) == pytest.approx(getattr(cb, key), rel=1e-12, abs=1e-12)
        np.testing.assert_allclose(ca.distortion, cb.distortion, atol=1e-15)
        np.testing.assert_allclose(ca.world_from_camera, cb.world_from_camera, atol=1e-12)
        np.testing.assert_array_equal(a.light.position, [0.03, -0.02, 0])
    assert got.geometry.mesh == truth.geometry.mesh


def test_pixel_centres_match_pycolmaps_projection(made, tmp_path):
    """Independent of the importer's own arithmetic: pycolmap projects the model's 3D points in
    COLMAP's convention (top-left pixel centre at (0.5, 0.5)), capture.project_points in the
    contract's (at (0, 0)), lens distortion included; they must differ by exactly 0.5 px."""
    import_colmap(made["sparse"], made["images"], made["mesh"], tmp_path / "s")
    scene = capture.load_scene(tmp_path / "s")
    rec = pycolmap.Reconstruction(str(made["sparse"]))
    points = made["points"][:200]
    for photo in scene.photos:
        image = rec.image(json.loads((tmp_path / "s" / "scene.json").read_text())["photos"][
            photo.index]["source"]["image_id"])
        pose = image.cam_from_world()
        local = points @ pose.rotation.matrix().T + pose.translation
        expected = rec.camera(image.camera_id).img_from_cam(local) - 0.5
        uv, z = capture.project_points(photo.camera, points)
        assert np.all(z > 0)
        np.testing.assert_allclose(uv, expected, atol=1e-6)


def _median_error(result, truth, n_min=20):
    ok = result.n >= n_min
    return float(np.median(np.max(np.abs(result.rho[ok] / truth[ok] - 1), axis=1))), int(ok.sum())


def test_round_trip_gives_the_known_slice(made, tmp_path):
    """Noise-free photos rendered from the true cameras: the imported scene must give the slice
    of the hand-written truth scene to float precision, and that slice is the BRDF's within the
    spread of theta_h inside a bin (< 1% median; the flash 3.6 cm off the lens at 0.6 m puts
    theta_d near 1.7 deg, where GGX without Fresnel is flat)."""
    import_colmap(made["sparse_bin"], made["images"], made["mesh"], tmp_path / "s",
                  flash_offset=(0.03, -0.02, 0))
    got = extract_slice(tmp_path / "s")
    want = extract_slice(made["truth"])
    np.testing.assert_array_equal(got.n, want.n)
    np.testing.assert_allclose(got.rho, want.rho, rtol=1e-6)
    error, bins = _median_error(got, true_slice(made["brdf"]))
    assert bins >= 60 and error < 0.01
    assert len(got.report["photos"]) == 6 and all(p["on_surface"] > 0
                                                  for p in got.report["photos"])


def test_encoding_srgb_for_16_bit_photos_a_converter_wrote_with_the_curve(made, tmp_path):
    """16-bit PNGs holding the photos through the sRGB curve (what RAW converters export by
    default): read as linear (16-bit's default) the slice's shape is bent by the curve; with
    --encoding srgb the slice is the EXR photos' times the one factor the PNGs were scaled by,
    to 16-bit quantisation averaged over a bin's pixels (< 0.1% per bin, against a bend of
    tens of %). srgb on EXR photos is refused."""
    import cv2
    from flashbrdf.brdf.colour import srgb_encode
    folder = tmp_path / "png16"
    folder.mkdir()
    exrs = sorted(made["images"].glob("*.exr"))
    peak = max(float(capture.load_photo(e)[0].max()) for e in exrs)
    for exr in exrs:
        linear = np.clip(capture.load_photo(exr)[0] / peak, 0, 1)
        encoded = srgb_encode(linear)
        cv2.imwrite(str(folder / f"{exr.stem}.png"),
                    np.round(65535 * encoded[..., ::-1]).astype(np.uint16))
    want = extract_slice(made["truth"])
    ratios = {}
    for encoding in (None, "srgb"):
        out = tmp_path / f"s_{encoding}"
        import_colmap(made["sparse_bin"], folder, made["mesh"], out,
                      flash_offset=(0.03, -0.02, 0), encoding=encoding)
        got = extract_slice(out)
        ok = (got.n >= 20) & (want.n >= 20)
        ratios[encoding] = np.log(got.rho[ok] * peak / want.rho[ok])
    assert np.abs(ratios["srgb"]).max() < 0.001
    assert np.ptp(ratios[None]) > 0.2
    floats = tmp_path / "float_tiff"          # floats by their samples, not their extension
    floats.mkdir()
    for exr in exrs:
        cv2.imwrite(str(floats / f"{exr.stem}.tif"),
                    capture.load_photo(exr)[0][..., ::-1].astype(np.float32))
    for folder in (made["images"], floats):
        with pytest.raises(InputError, match="--encoding"):
            import_colmap(made["sparse_bin"], folder, made["mesh"], tmp_path / "bad",
                          flash_offset=(0.03, -0.02, 0), encoding="srgb")
        assert not (tmp_path / "bad").exists()


def test_cli_summary(made, tmp_path, capsys):
    """Two of the six photos missing: four matched, two skipped and named; both cameras listed
    with their photo counts; reprojection error near the keypoints' 0.3 px noise (the mean
    norm of a 2D Gaussian of sigma 0.3 is 0.38 px); the floor's points (20%) off the mesh."""
    photos = tmp_path / "photos"
    photos.mkdir()
    for name in made["names"][:4]:
        (photos / f"{name}.exr").symlink_to(made["images"] / f"{name}.exr")
    out = tmp_path / "scene"
    assert main(["import-colmap", str(made["sparse"]), "--images", str(photos), "--mesh",
                 str(made["mesh"]), "--out", str(out), "--flash-offset=0.03,-0.02,0",
                 "--intensity", "2,2,2"]) == 0
    text = capsys.readouterr().out
    assert "matched 4 images to photos; skipped 2 with no photo: view_04.jpg, view_05.jpg" \
        in text
    assert "camera 1: OPENCV 240x180, fx 300 fy 303 cx 125.8 cy 85.6" in text
    assert "camera 2: SIMPLE_RADIAL 240x180, fx 330 fy 330 cx 116.3 cy 93.7" in text
    assert text.count("; 2 photos") == 2
    error = float(text.split("mean reprojection error: ")[1].split(" px")[0])
    assert 0.3 < error < 0.46
    share = float(text.split("3D points on the mesh: ")[1].split("%")[0])
    assert 75 <= share <= 82       # 80% on the surface, less the few seen only at the rim
    doc = json.loads((out / "scene.json").read_text())
    assert [p["file"] for p in doc["photos"]] == [f"../photos/{n}.exr"
                                                  for n in made["names"][:4]]
    assert doc["photos"][0]["light"]["intensity_rgb"] == [2.0, 2.0, 2.0]
    assert sorted(p.name for p in photos.iterdir()) == [f"{n}.exr" for n in made["names"][:4]]


def test_summary_says_why_the_reprojection_error_is_missing(made, tmp_path, capsys,
                                                             monkeypatch):
    """With 3D points whose error pycolmap cannot compute, the summary does not claim there are
    none."""
    from flashbrdf.capture.importers.colmap_model import ColmapModel
    monkeypatch.setattr(ColmapModel, "mean_reprojection_error", lambda self: None)
    assert main(["import-colmap", str(made["sparse"]), "--images", str(made["images"]),
                 "--mesh", str(made["mesh"]), "--out", str(tmp_path / "scene")]) == 0
    assert "mean reprojection error: n/a (not computable)" in capsys.readouterr().out


def test_mesh_frame_check_reach(made, tmp_path):
    """The mesh_frame limits as its docstring states them: the true mesh passes, with exact
    points, points scattered by 2% of the mesh's diagonal, or tracks listing every camera whose
    image the point falls in (occlusion ignored, as a careless exporter might); a mesh moved by
    13% of its diagonal, scaled 0.9 or 1.05 about its centre, or turned 90 degrees is refused."""
    import trimesh
    from flashbrdf.capture.geometry import MeshIntersector, load_mesh
    from flashbrdf.capture.importers.mesh_frame import check_mesh_frame
    done = import_colmap(made["sparse"], made["images"], made["mesh"], tmp_path / "ok")
    assert done.frame.hidden == 0 and done.frame.problem() is None
    model = done.model
    points, observed, observers = model.sight_lines()
    cams = [p["camera"] for p in done.scene["photos"]]
    centres = np.array([im.centre for im in model.images])
    careless = [(k, c) for k, p in enumerate(points) for cam, c in zip(cams, centres)
                if _in_view(cam, p)]
    mesh, _ = load_mesh(made["mesh"])
    diagonal = float(np.linalg.norm(np.ptp(mesh.vertices, axis=0)))
    scattered = points + np.random.default_rng(0).normal(0, 0.02 * diagonal, points.shape)
    true_mesh = MeshIntersector(mesh, True)
    for p, o, c in [(points, observed, observers), (scattered, observed, observers),
                    (points, np.array([k for k, _ in careless]),
                     np.array([c for _, c in careless]))]:
        assert check_mesh_frame(true_mesh, p, o, c, cams).problem() is None
    assert check_mesh_frame(true_mesh, points, observed, observers, cams).warning() is None
    T = trimesh.transformations
    centre = mesh.bounds.mean(axis=0)
    # turned 8°: it passes (its points are within the tolerance in places), but is warned of,
    # and so is a model without points, whose mesh nothing checks
    turned = mesh.copy()
    turned.apply_transform(T.rotation_matrix(np.radians(8), [1, 0, 0], centre))
    check = check_mesh_frame(MeshIntersector(turned, False), points, observed, observers, cams)
    assert check.problem() is None and "lie on it" in check.warning()
    assert "not checked" in check_mesh_frame(true_mesh, np.zeros((0, 3)), [], np.zeros((0, 3)),
                                             cams).warning()
    for transform in [T.translation_matrix([0.13 * diagonal, 0, 0]), T.scale_matrix(0.9, centre),
                      T.scale_matrix(1.05, centre), T.rotation_matrix(np.pi / 2, [1, 0, 0],
                                                                       centre)]:
        moved = mesh.copy()
        moved.apply_transform(transform)
        check = check_mesh_frame(MeshIntersector(moved, False), points, observed, observers,
                                 cams)
        assert check.problem() is not None
    moved = mesh.copy()
    moved.apply_transform(T.scale_matrix(1.05, centre))
    moved.export(tmp_path / "moved.ply")
    with pytest.raises(InputError, match="moved.ply: not in the model's frame: it hides"):
        import_colmap(made["sparse"], made["images"], tmp_path / "moved.ply", tmp_path / "s")
    assert not (tmp_path / "s").exists()


def _in_view(cam, point):
    pose = np.asarray(cam["world_from_camera"])
    x, y, z = (point - pose[:3, 3]) @ pose[:3, :3]
    return z > 0 and 0 <= cam["fx"] * x / z + cam["cx"] < cam["width"] and \
        0 <= cam["fy"] * y / z + cam["cy"] < cam["height"]


CAMERA_CASES = [
    ("SIMPLE_PINHOLE", [400.0, 100.5, 80.5], None),
    ("PINHOLE", [400.0, 410.0, 101.0, 79.0], None),
    ("SIMPLE_RADIAL", [400.0, 100.5, 80.5, -0.1], [-0.1, 0, 0, 0, 0]),
    ("RADIAL", [400.0, 100.5, 80.5, -0.1, 0.03], [-0.1, 0.03, 0, 0, 0]),
    ("OPENCV", [400.0, 410.0, 101.0, 79.0, -0.1, 0.03, 0.002, -0.001],
     [-0.1, 0.03, 0.002, -0.001, 0]),
    ("FULL_OPENCV", [400.0, 410.0, 101.0, 79.0, -0.1, 0.03, 0.002, -0.001, 0.01, 0.0, 0.0, 0.0],
     [-0.1, 0.03, 0.002, -0.001, 0.01]),
    ("FULL_OPENCV", [400.0, 410.0, 101.0, 79.0, -0.1, 0.03, 0.002, -0.001, 0.01, 0.05, -0.02,
                     0.004], [-0.1, 0.03, 0.002, -0.001, 0.01, 0.05, -0.02, 0.004]),
]


@pytest.mark.parametrize("name,params,distortion", CAMERA_CASES,
                         ids=[f"{c[0]}-{len(c[1])}" for c in CAMERA_CASES])
def test_every_camera_model_projects_as_pycolmap(name, params, distortion):
    """Each supported model's contract camera (through capture.project_points, OpenCV) puts a
    spread of points 0.5 px from where pycolmap puts them; FULL_OPENCV's k4..k6 become OpenCV's
    rational model (8 coefficients), and drop to the contract's 5 when they are 0."""
    cam = pycolmap.Camera.create_from_model_name(3, name, params[0], 200, 160)
    cam.params = params
    got = contract_camera(cam, "cameras.txt: camera 3", np.eye(4))
    assert got.get("distortion") == distortion
    rng = np.random.default_rng(1)
    local = np.column_stack([rng.uniform(-0.2, 0.2, (300, 2)), rng.uniform(0.8, 1.2, 300)])
    loaded = capture.Camera("pinhole", 200, 160, np.eye(4), fx=got["fx"], fy=got["fy"],
                            cx=got["cx"], cy=got["cy"],
                            distortion=None if distortion is None else np.array(distortion))
    uv, _ = capture.project_points(loaded, local)
    np.testing.assert_allclose(uv, cam.img_from_cam(local) - 0.5, atol=1e-7)


def test_unsupported_camera_model_named():
    cam = pycolmap.Camera.create_from_model_name(7, "OPENCV_FISHEYE", 300.0, 200, 160)
    with pytest.raises(InputError, match="cameras.txt: camera 7: camera model OPENCV_FISHEYE"):
        contract_camera(cam, "cameras.txt: camera 7", np.eye(4))


class _Model:
    def __init__(self, *names):
        self.images = [ModelImage(k + 1, n, 1, np.eye(4)) for k, n in enumerate(names)]


def _touch(folder, *names):
    for name in names:
        path = folder / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(b"")


def test_photos_matched_by_stem_and_subfolder(tmp_path):
    _touch(tmp_path, "a.dng", "b.EXR", "b.txt", "cam2/a.exr", "notes.xmp", "c.bmp")
    matched, skipped = match_photos(_Model("a.jpg", "b.jpg", "cam2/a.jpg", "c.jpg", "d.jpg"),
                                    tmp_path)
    assert [(im.name, p.relative_to(tmp_path).as_posix()) for im, p in matched] == [
        ("a.jpg", "a.dng"), ("b.jpg", "b.EXR"), ("cam2/a.jpg", "cam2/a.exr")]
    assert skipped == ["c.jpg", "d.jpg"]     # .bmp is no photo format of the contract


def test_two_photos_of_one_stem_refused(tmp_path):
    _touch(tmp_path, "a.jpg", "a.dng")
    with pytest.raises(InputError, match=r"a.jpg: a.dng and a.jpg share the stem 'a'"):
        match_photos(_Model("a.jpg"), tmp_path)


def test_one_photo_for_two_model_images_refused(tmp_path):
    _touch(tmp_path, "0001.exr")
    with pytest.raises(InputError, match="0001.exr: is the photo of two model images"):
        match_photos(_Model("left/0001.jpg", "right/0001.jpg"), tmp_path)


def test_photo_size_from_headers(made, tmp_path):
    assert photo_size(made["images"] / "view_00.exr") == (240, 180)
    import cv2
    cv2.imwrite(str(tmp_path / "p.png"), np.zeros((7, 9, 3), np.uint16))
    cv2.imwrite(str(tmp_path / "p.jpg"), np.zeros((5, 11, 3), np.uint8))
    assert photo_size(tmp_path / "p.png") == (9, 7)
    assert photo_size(tmp_path / "p.jpg") == (11, 5)


def test_exif_orientation_is_named_not_applied(made, tmp_path, capsys):
    """Photos are used as stored, as COLMAP uses them (it ignores the EXIF orientation): JPEGs
    with Orientation 6 and the stored pixels of the model's images import, and the summary names
    them; a photo whose pixels were turned a quarter (Orientation 8) is refused, and the message
    says that the tag asks for a turn flashbrdf does not make."""
    import OpenImageIO as oiio
    from flashbrdf.capture.importers.colmap import photo_header

    def write_jpeg(path, rgb, orientation):
        spec = oiio.ImageSpec(rgb.shape[1], rgb.shape[0], 3, "uint8")
        spec.attribute("Orientation", orientation)
        out = oiio.ImageOutput.create(str(path))
        assert out.open(str(path), spec) and out.write_image(rgb) and out.close()

    stored, turned = tmp_path / "stored", tmp_path / "turned"
    stored.mkdir(), turned.mkdir()
    for exr in sorted(made["images"].glob("*.exr")):
        rgb, _ = capture.load_photo(exr)
        srgb = (255 * np.clip(rgb / max(rgb.max(), 1e-6), 0, 1) ** (1 / 2.2)).astype(np.uint8)
        write_jpeg(stored / f"{exr.stem}.jpg", srgb, 6)
        write_jpeg(turned / f"{exr.stem}.jpg", np.ascontiguousarray(np.rot90(srgb)), 8)
    assert photo_header(stored / "view_00.jpg") == (240, 180, 6, False)
    common = [str(made["sparse"]), "--mesh", str(made["mesh"])]
    capsys.readouterr()
    assert main(["import-colmap", *common, "--images", str(stored),
                 "--out", str(tmp_path / "ok")]) == 0
    n = len(list(stored.glob("*.jpg")))
    assert f"{n} photos carry an EXIF orientation other than 1" in capsys.readouterr().out
    assert main(["import-colmap", *common, "--images", str(turned),
                 "--out", str(tmp_path / "bad")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "is 180x240" in err[0] and "EXIF orientation 8" in err[0]
    assert not (tmp_path / "bad").exists()


def test_raw_photo_size_is_the_decoded_size():
    """rawpy's sizes (and flip) without decoding: the size capture.load_photo gives."""
    from conftest import shared_path
    path = shared_path("data", "real", "raw", "colorchart.dng")
    rgb, _ = capture.load_photo(path)
    assert photo_size(path) == (rgb.shape[1], rgb.shape[0])


def test_read_model_formats_agree(made):
    models = [read_colmap_model(made["out"] / layout) for layout in LAYOUTS]
    for m in models[1:]:
        assert [im.name for im in m.images] == [im.name for im in models[0].images]
        for a, b in zip(m.images, models[0].images):
            np.testing.assert_allclose(a.world_from_camera, b.world_from_camera, atol=1e-12)
    assert Path(models[0].files["frames"]).name == "frames.txt"
    assert "frames" not in models[2].files


def test_negative_flash_offset_without_equals_sign(made, tmp_path):
    """`--flash-offset -0.03,0,0` is a value, not an unknown option (before Python 3.13
    argparse took it for one)."""
    out = tmp_path / "s"
    assert main(["import-colmap", str(made["sparse"]), "--images", str(made["images"]),
                 "--mesh", str(made["mesh"]), "--out", str(out), "--flash-offset",
                 "-0.03,0.02,0", "--intensity", "1e-2,1e-2,1e-2"]) == 0
    light = json.loads((out / "scene.json").read_text())["photos"][0]["light"]
    assert light == {"type": "point", "position": [-0.03, 0.02, 0.0],
                     "intensity_rgb": [0.01, 0.01, 0.01]}


def test_a_target_or_a_calibrated_flash_goes_into_the_scene(made, tmp_path, capsys):
    """--target/--reflectance write scene.json's "level" (the mesh relative to the scene folder,
    as the photos are); --calibrated writes its own, with the --intensity it vouches for; a
    reflectance without a target, and --calibrated without --intensity (the placeholder 1,1,1
    would pass as measured), are refused."""
    card = tmp_path / "card.ply"
    card.write_bytes(made["mesh"].read_bytes())
    common = [str(made["sparse"]), "--images", str(made["images"]), "--mesh", str(made["mesh"])]
    out = tmp_path / "with_card"
    assert main(["import-colmap", *common, "--out", str(out), "--target", str(card),
                 "--reflectance", "0.18"]) == 0
    from flashbrdf.capture import load_scene
    level = load_scene(out).level
    assert level.target_mesh == card.resolve()
    np.testing.assert_array_equal(level.reflectance, [0.18, 0.18, 0.18])
    calibrated = tmp_path / "calibrated"
    assert main(["import-colmap", *common, "--out", str(calibrated), "--calibrated",
                 "--intensity", "3.7,3.6,3.5"]) == 0
    assert load_scene(calibrated).level.calibrated
    scene = json.loads((calibrated / "scene.json").read_text())
    assert scene["photos"][0]["light"]["intensity_rgb"] == [3.7, 3.6, 3.5]
    # a target no photo has in view, or whose faces all turn away from the cameras or hide
    # behind the object, could give extract no pixel: refused here, naming its file
    # (the cameras ring the object 25-50° above it, up +z: a card under it facing down faces
    # none of them; 50 units away it is in no photo)
    import trimesh
    corners = np.array([[-0.1, -0.1, -0.1], [0.1, -0.1, -0.1], [0.1, 0.1, -0.1], [-0.1, 0.1, -0.1]])
    down = trimesh.Trimesh(corners, [[0, 2, 1], [0, 3, 2]], process=False)
    assert np.allclose(down.face_normals, [0, 0, -1])
    far = trimesh.Trimesh(corners + [50.0, 0, 0], [[0, 1, 2], [0, 2, 3]], process=False)
    # inside the object's sphere (radius 0.045), facing up at the cameras: in view, but hidden
    inside = trimesh.Trimesh(corners * [0.2, 0.2, 0.0], [[0, 1, 2], [0, 2, 3]], process=False)
    assert np.allclose(inside.face_normals, [0, 0, 1])
    for name, mesh in (("down.ply", down), ("far.ply", far), ("inside.ply", inside)):
        mesh.export(tmp_path / name)
        capsys.readouterr()
        assert main(["import-colmap", *common, "--out", str(tmp_path / "bad"), "--target",
                     str(tmp_path / name), "--reflectance", "0.18"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and f"{name}: no photo has this target in view" in err[0]
        assert not (tmp_path / "bad").exists()
    for flag, extra in (("--reflectance", ["--reflectance", "0.18"]),
                        ("--calibrated", ["--calibrated"])):
        capsys.readouterr()
        assert main(["import-colmap", *common, "--out", str(tmp_path / "bad"), *extra]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and flag in err[0] and not (tmp_path / "bad").exists()
    # --target alone: it said "--reflectance: expected 3 finite numbers, got ()"
    assert main(["import-colmap", *common, "--out", str(tmp_path / "bad"), "--target",
                 str(tmp_path / "down.ply")]) == 2
    assert "--target needs the target's reflectance" in capsys.readouterr().err


def test_two_model_images_of_one_name_blame_the_model(made, tmp_path, capsys):
    """A model listing one name twice was blamed on the photo ("is the photo of two model images,
    view_01.jpg and view_01.jpg ... give each its own photo, in subfolders"), which no photo
    layout can fix; it names the model's images file and both image ids."""
    import re
    sparse = tmp_path / "sparse"
    shutil.copytree(made["sparse"], sparse)
    text = (sparse / "images.txt").read_text()
    names = re.findall(r"^\d+ (?:\S+ ){8}(\S+)$", text, flags=re.M)
    (sparse / "images.txt").write_text(text.replace(names[1], names[0]))
    assert main(["import-colmap", str(sparse), "--images", str(made["images"]), "--mesh",
                 str(made["mesh"]), "--out", str(tmp_path / "scene")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{sparse / 'images.txt'}: images " in err[0]
    assert f"are both named {names[0]}" in err[0] and not (tmp_path / "scene").exists()
