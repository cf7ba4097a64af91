"""An object of two materials photographed from several views: the first view's pixels take
their material from the label image, the other views' from the label of the mesh face they hit
(LABELS.faces.npy), so each material's slice pools every view and matches its own BRDF."""

import cv2
import numpy as np
import pytest

from colmap_synthetic import make_colmap_capture, true_slice
from flashbrdf import capture
from flashbrdf.brdf.models import GGX
from flashbrdf.cli.main import main
from flashbrdf.render import MaterialMap, render_scene, write_exr
from synthetic import torus_mesh
from flashbrdf.brdf.views import read_slice_csv

MATERIALS = (GGX(alpha=0.18, specular=(0.5, 0.5, 0.5), diffuse=(0.55, 0.3, 0.15), fresnel=False),
             GGX(alpha=0.35, specular=(0.2, 0.2, 0.2), diffuse=(0.1, 0.25, 0.6), fresnel=False))


@pytest.fixture(scope="module")
def two_materials(tmp_path_factory):
    """The 6-view synthetic capture re-rendered with the torus in material 1 and the sphere in
    material 2; its label image (first view) and face labels."""
    made = make_colmap_capture(tmp_path_factory.mktemp("mv"), views=6)
    scene = capture.load_scene(made["truth"])
    n_torus = len(torus_mesh(centre=(0, 0, 0)).faces)  # colmap_synthetic.object_mesh: torus first
    n_faces = len(capture.load_mesh(scene.geometry.mesh)[0].faces)
    faces = np.where(np.arange(n_faces) < n_torus, 1, 2).astype(np.int32)
    camera = scene.photos_with_role("flash")[0].camera
    surface = capture.surface_from_mesh(capture.scene_intersector(scene), camera)
    labels = np.zeros(camera.shape, np.uint16)
    labels[surface.rows, surface.cols] = faces[surface.face]
    brdf = MaterialMap(list(MATERIALS), labels, camera, faces)
    for photo, image, _ in render_scene(scene, brdf, photos=scene.photos_with_role("flash"),
                                        progress=False):
        write_exr(made["images"] / f"{photo.stem}.exr", image)
    folder = made["out"]
    cv2.imwrite(str(folder / "labels.png"), labels)
    np.save(folder / "labels.faces.npy", faces)
    return made, folder / "labels.png"


def _median_error(rho, want):
    seen = np.isfinite(rho).all(axis=1)
    return float(np.median(np.abs(rho[seen] / want[seen] - 1))), int(seen.sum())


def test_each_material_pools_every_view(two_materials, tmp_path):
    """Noise-free renders: each material's median relative error over its bins < 1% (what one
    material's slice reaches in tests/test_import_colmap.py), and far more samples than the
    first view holds of it."""
    made, labels = two_materials
    out = tmp_path / "slices"
    assert main(["extract", str(made["truth"]), "--labels", str(labels), "--out", str(out)]) == 0
    first_view = np.bincount(cv2.imread(str(labels), cv2.IMREAD_UNCHANGED).ravel(), minlength=3)
    for k, model in enumerate(MATERIALS, start=1):
        rho, n = read_slice_csv(out / f"material_{k}.csv")
        error, bins = _median_error(rho, true_slice(model))
        assert bins >= 30 and error < 0.01, (k, bins, error)
        assert n.sum() > 2 * first_view[k]


def test_other_views_without_face_labels_are_refused(two_materials, tmp_path, capsys):
    made, labels = two_materials
    alone = tmp_path / "labels.png"
    alone.write_bytes(labels.read_bytes())   # no labels.faces.npy beside it
    assert main(["extract", str(made["truth"]), "--labels", str(alone), "--out",
                 str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "faces.npy" in err[0] and not (tmp_path / "o").exists()
