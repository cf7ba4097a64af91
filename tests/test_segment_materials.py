"""Objects of several materials: segment, extract --labels, render --labels, run --materials.

The scene is a sphere (r = 0.1 m, 1 m away, 256² pinhole, flash 3 cm off the lens) whose
part with x + y/2 > 2 cm is MERL (NBRDF proxy) blue-acrylic and the rest red-specular-plastic,
rendered through the contract's pixel model (tests/synthetic.py, trimesh rays, not ours) with
Poisson noise of 2000 photons at the mean pixel, as a real photo has. A reference photo is the
same object under a directional light 18° off the view axis, with the same noise.
"""

import itertools
import json

import cv2
import numpy as np
import pytest

from flashbrdf.brdf.merl import read_merl
from flashbrdf.brdf.views import flash_slice, read_slice_csv
from flashbrdf.cli.main import main
from synthetic import (add_reference_photo, by_region, directional_light, pinhole_camera,
                       point_light, region_image, sphere_mesh, table_brdf, write_synthetic_scene)

MATERIALS = ("red-specular-plastic", "blue-acrylic")
PHOTONS = 2000


def _region(points):
    return (points[:, 0] + 0.5 * points[:, 1] > 0.02).astype(int)


@pytest.fixture(scope="module")
def two_materials(merl_proxy, tmp_path_factory):
    paths = merl_proxy(*MATERIALS)
    tables = [read_merl(p) for p in paths]
    brdf = by_region([table_brdf(t) for t in tables], _region)
    mesh, cam = sphere_mesh(), pinhole_camera(256, 256, 1000.0)
    folder = write_synthetic_scene(tmp_path_factory.mktemp("two") / "scene", mesh, brdf, cam,
                                   [point_light([0.03, 0, 0])], photons=PHOTONS)
    light = directional_light(np.array([0.25, -0.2, -1.0]) / np.linalg.norm([0.25, -0.2, -1.0]))
    add_reference_photo(folder, mesh, brdf, cam, light, PHOTONS)
    truth = region_image(mesh, cam, _region)
    cv2.imwrite(str(folder.parent / "true_labels.png"), truth.astype(np.uint16))
    return {"scene": folder, "tables": tables, "paths": paths, "truth": truth,
            "true_png": folder.parent / "true_labels.png", "faces": len(mesh.faces)}


@pytest.fixture(scope="module")
def segmented(two_materials):
    out = two_materials["scene"].parent / "seg" / "labels.png"
    assert main(["segment", str(two_materials["scene"]), "--out", str(out)]) == 0
    labels = cv2.imread(str(out), cv2.IMREAD_UNCHANGED)
    truth = two_materials["truth"]
    # labels are numbered by area; find which true material each one is
    best = max(itertools.permutations([1, 2]),
               key=lambda p: np.mean(np.choose(truth[truth > 0] - 1, p) == labels[truth > 0]))
    return out, labels, best


def test_auto_finds_two_materials_and_labels_98_percent(two_materials, segmented):
    out, labels, perm = segmented
    truth = two_materials["truth"]
    assert labels.dtype == np.uint16 and labels.max() == 2
    on = truth > 0
    right = np.mean(np.choose(truth[on] - 1, perm) == labels[on])
    # the boundary is a ~250-pixel curve through a 31,000-pixel disc: 98% leaves room for it
    assert right >= 0.98
    assert np.all(labels[~on] == 0)
    faces = np.load(out.with_name("labels.faces.npy"))
    assert faces.dtype == np.int32 and len(faces) == two_materials["faces"]
    assert set(np.unique(faces)) == {1, 2}


def test_material_slices_match_each_true_slice(two_materials, segmented, tmp_path):
    out, _, perm = segmented
    folder = tmp_path / "slices"
    assert main(["extract", str(two_materials["scene"]), "--labels", str(out), "--out",
                 str(folder)]) == 0
    coverage = json.loads((folder / "coverage.json").read_text())
    assert [m["label"] for m in coverage["materials"]] == [1, 2]
    for true_index, label in enumerate(perm):
        rho, n = read_slice_csv(folder / f"material_{label}.csv")
        truth = flash_slice(two_materials["tables"][true_index])[0]
        ok = (n >= 20) & np.all(np.isfinite(rho), 1) & np.all(truth > 0, 1)
        # noise: 2000 photons is 2.2% per pixel, averaged over >= 20 pixels: < 0.5%; the rest
        # is the flash's theta_d (up to 1.7 deg here) and the bin width
        error = np.median(np.abs(rho[ok] / truth[ok] - 1))
        assert ok.sum() >= 40 and error < 0.03, (label, ok.sum(), error)


def test_relit_with_inferred_brdfs_is_within_1_3_of_the_known_ones(two_materials, tmp_path):
    known = tmp_path / "known"
    paths = ",".join(str(two_materials["paths"][k]) for k in (0, 1))
    assert main(["render", str(two_materials["scene"]), "--brdf", paths, "--labels",
                 str(two_materials["true_png"]), "--out", str(known), "--spp", "1"]) == 0
    known_de = json.loads((known / "ref_compare.json").read_text())["delta_e_log_mean"]
    out = tmp_path / "run"
    assert main(["run", str(two_materials["scene"]), "--out", str(out), "--spp", "1"]) == 0
    report = json.loads((out / "report.json").read_text())
    assert [m["label"] for m in report["materials"]] == [1, 2]
    assert all(set(m["brdf"]) == {"dsgplvm"} for m in report["materials"])
    assert (out / "slice.csv").is_file() and (out / "labels.faces.npy").is_file()
    inferred = report["references"][0]["delta_e_log_mean"]
    # measured 2026-12-01: known 0.44 (the reference's photon noise), inferred 0.51
    assert inferred <= 1.3 * known_de, (inferred, known_de)
    assert "![labels](figures/labels.png)" in (out / "report.md").read_text()
    # report.html shows each material's BRDF from run's own predictions, their variance too
    from flashbrdf.pipeline.report_html import page_data
    meta, _ = page_data(out / "report.html")
    per_material = [d for d in meta["brdf"] if d["material"] is not None]
    assert [d["material"] for d in per_material] == [1, 2]
    assert all("variance" in d["methods"]["dsgplvm"] or "variance_constant" in
               d["methods"]["dsgplvm"] for d in per_material)
    assert [e["label"] for e in meta["materials"]["entries"]] == [1, 2]
    # the test can fail: the two tables swapped are far off
    swapped = tmp_path / "swapped"
    paths = ",".join(str(two_materials["paths"][k]) for k in (1, 0))
    assert main(["render", str(two_materials["scene"]), "--brdf", paths, "--labels",
                 str(two_materials["true_png"]), "--out", str(swapped), "--spp", "1"]) == 0
    swapped_de = json.loads((swapped / "ref_compare.json").read_text())["delta_e_log_mean"]
    assert swapped_de > 3 * 1.3 * known_de


def _labelled_right(merl_proxy, folder, names, region, seed, *options):
    """Two MERL (NBRDF proxy) tables laid out by `region` on the test sphere, `segment` with
    `options`: (K, share of object pixels labelled right under the better naming)."""
    tables = [read_merl(p) for p in merl_proxy(*names)]
    mesh, cam = sphere_mesh(), pinhole_camera(256, 256, 1000.0)
    scene = write_synthetic_scene(folder / "scene", mesh,
                                  by_region([table_brdf(t) for t in tables], region), cam,
                                  [point_light([0.03, 0, 0])], photons=PHOTONS, seed=seed)
    out = folder / "labels.png"
    assert main(["segment", str(scene), "--out", str(out), *options]) == 0
    labels = cv2.imread(str(out), cv2.IMREAD_UNCHANGED)
    truth = region_image(mesh, cam, region)
    on = truth > 0
    return int(labels.max()), max(np.mean(labels[on] == truth[on]),
                                  np.mean(labels[on] == 3 - truth[on]))


def test_auto_keeps_a_photon_starved_black_beside_a_bright_wood(merl_proxy, tmp_path):
    """Two materials that share the theta_h bins about equally (the sphere's two halves), one of
    them black-obsidian (rho ~1e-4, a few photons a pixel): one slice for the object then
    follows whichever holds more samples in each bin and fits half the black's samples as well
    as their own slice does, so the black's own test alone gave 0.63-0.65 against 0.6 on noise
    seeds 0-5 (K = 1), while the wood, its partner, fits its own slice 0.03 x as badly as the
    two's joint one. K must be 2, with the issue's 98% of object pixels labelled right
    (measured 98.5%: the black half's zero-photon pixels take the nearest label)."""
    k, right = _labelled_right(merl_proxy, tmp_path, ("black-obsidian", "pickled-oak-260"),
                               _region, 0)
    assert k == 2 and right >= 0.98, right


def _dots(points, spacing=0.012, radius=0.004):
    """1 inside a dot: within `radius` of a point of a cubic lattice of pitch `spacing` (m)."""
    q = (points - np.array([0, 0, 1.0])) / spacing
    return (np.linalg.norm(q - np.round(q), axis=1) * spacing < radius).astype(int)


def test_a_material_in_small_dots_keeps_its_dots(merl_proxy, tmp_path):
    """blue-acrylic dots (4 mm radius, ~4 px here, each ~50 px: under the clean-up's 0.2% of
    the object, 63 px) on red-specular-plastic, 16% of the sphere, with --materials 2. Each dot
    alone looks like speckle; together they are the material, so the clean-up must keep them.
    Measured 99.3% of object pixels right; 84.2% before, when every dot but the largest was
    cleared (the blue then held one dot). 98%: the issue's label target."""
    k, right = _labelled_right(merl_proxy, tmp_path, MATERIALS, _dots, 0, "--materials", "2")
    assert k == 2 and right >= 0.98, right


# a blob pattern: a smooth random field (8 plane waves, wavelengths 2-7 cm on the 10 cm sphere)
# above a threshold; regions cross every theta_h ring
BLOB_WAVES = np.array([[13, -161, 74], [70, 28, 166], [-146, -10, -276], [-10, 306, 130],
                       [-30, 84, 113], [-74, 265, -104], [-209, 340, 107], [152, -323, -92]])
BLOB_PHASES = np.array([2.77, 5.66, 6.02, 5.29, 1.85, 3.9, 3.36, 4.16])


def _blobs(points):
    field = np.cos((points - np.array([0, 0, 1.0])) @ BLOB_WAVES.T + BLOB_PHASES).sum(axis=1)
    return (field > 0.15).astype(int)


def test_materials_keep_their_names_from_one_theta_h_ring_to_the_next(merl_proxy, tmp_path):
    """fruitwood-241 and dark-specular-fabric in blobs: the k-slice assignment decides bin by
    bin, and over some theta_h rings the two materials' names came out exchanged (each ring split
    right, named wrong: 86.9% of pixels right). The pixels adjacent across the rings' edges put
    the names back (align_bin_labels): measured 96.4%. 95%: between the two; what is left is
    rings where one name holds both materials, which renaming cannot split."""
    k, right = _labelled_right(merl_proxy, tmp_path, ("fruitwood-241", "dark-specular-fabric"),
                               _blobs, 10)
    assert k == 2 and right >= 0.95, right


def test_auto_picks_one_material_on_the_sample_capture(tmp_path):
    from pathlib import Path
    sample = Path(__file__).resolve().parents[1] / "sample_data" / "capture"
    out = tmp_path / "labels.png"
    assert main(["segment", str(sample), "--out", str(out)]) == 0
    labels = cv2.imread(str(out), cv2.IMREAD_UNCHANGED)
    assert labels.max() == 1 and np.count_nonzero(labels) > 10000
    assert json.loads(out.with_suffix(".json").read_text())["materials"] == 1


def test_more_materials_asked_than_found_says_how_many_were_kept(two_materials, tmp_path,
                                                                capsys):
    """--materials 12 on two materials: a slice that explains under 2% of the pixels goes
    (slices.refine_labels), and labels.json says how many of the 12 asked were kept."""
    out = tmp_path / "labels.png"
    capsys.readouterr()
    assert main(["segment", str(two_materials["scene"]), "--out", str(out),
                 "--materials", "12"]) == 0
    report = json.loads(out.with_suffix(".json").read_text())
    warned = [line for line in capsys.readouterr().err.splitlines() if line.startswith(
        f"warning: --materials 12: {report['materials']} material(s) kept (")]
    assert len(warned) == 1 and "under 2% of the pixels" in warned[0]
    reason = report["criterion"]["reason"]
    kept = int(reason.split("; ")[1].split()[0])
    assert reason.startswith("--materials 12; ") and 2 <= kept < 12
    assert report["materials"] <= kept
    assert cv2.imread(str(out), cv2.IMREAD_UNCHANGED).max() == report["materials"]


@pytest.mark.parametrize("how", ["wrong_size", "empty_label", "count"])
def test_bad_labels_exit_2_with_one_line_and_no_output(two_materials, tmp_path, capsys, how):
    truth = two_materials["truth"].astype(np.uint16)
    bad = tmp_path / "bad.png"
    paths = [str(p) for p in two_materials["paths"]]
    if how == "wrong_size":
        cv2.imwrite(str(bad), truth[:-1])
    elif how == "empty_label":
        cv2.imwrite(str(bad), np.where(truth == 2, 3, truth).astype(np.uint16))
        paths.append(paths[0])
    else:
        cv2.imwrite(str(bad), truth)
        paths = paths[:1]
    out = tmp_path / "out"
    assert main(["render", str(two_materials["scene"]), "--brdf", ",".join(paths), "--labels",
                 str(bad), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "bad.png" in err[0] and not out.exists()
    if how != "count":
        assert main(["extract", str(two_materials["scene"]), "--labels", str(bad), "--out",
                     str(out)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "bad.png" in err[0] and not out.exists()


def test_object_pixels_left_at_0_take_their_neighbours_material_not_the_first(two_materials,
                                                                             tmp_path):
    """A 3-px band of 0 on each side of the border, no faces file: the band's blue pixels were
    drawn with table 1 (red), ΔE-log 1.07 against 0.44 with whole labels. Each takes its nearest
    labelled pixel's material now: the reference's error is the whole labels' within 5% (the
    band is 3% of the object; 1 px of it sits on the wrong side of a 1.5-px-face boundary)."""
    truth = two_materials["truth"].astype(np.uint16)
    border = cv2.dilate((truth == 2).astype(np.uint8), np.ones((7, 7), np.uint8)) & \
        cv2.dilate((truth == 1).astype(np.uint8), np.ones((7, 7), np.uint8))
    banded = np.where(border > 0, 0, truth).astype(np.uint16)
    assert 0.01 < np.mean(border[truth > 0]) < 0.06
    paths = ",".join(str(p) for p in two_materials["paths"])
    errors = {}
    for name, labels in (("whole", truth), ("banded", banded)):
        cv2.imwrite(str(tmp_path / f"{name}.png"), labels)
        assert main(["render", str(two_materials["scene"]), "--brdf", paths, "--labels",
                     str(tmp_path / f"{name}.png"), "--out", str(tmp_path / name),
                     "--spp", "1"]) == 0
        errors[name] = json.loads((tmp_path / name / "ref_compare.json").read_text())[
            "delta_e_log_mean"]
    assert errors["banded"] <= 1.05 * errors["whole"], errors


def test_a_faces_file_of_another_label_image_is_refused(two_materials, segmented, tmp_path,
                                                        capsys):
    """labels.png relabelled (1 and 2 swapped) beside the old labels.faces.npy: every other view
    put each material on the other's faces (ΔE-log 20 against 0.06). The faces the flash camera
    sees disagree with the image on nearly all its pixels: exit 2 naming the faces file."""
    out, labels, _ = segmented
    swapped = tmp_path / "labels.png"
    cv2.imwrite(str(swapped), np.where(labels > 0, 3 - labels, 0).astype(np.uint16))
    (tmp_path / "labels.faces.npy").write_bytes(out.with_name("labels.faces.npy").read_bytes())
    paths = ",".join(str(p) for p in two_materials["paths"])
    capsys.readouterr()
    for command in (["render", str(two_materials["scene"]), "--brdf", paths],
                    ["extract", str(two_materials["scene"])]):
        assert main(command + ["--labels", str(swapped), "--out", str(tmp_path / "out")]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        head = f"{tmp_path / 'labels.faces.npy'}: disagrees with labels.png on "
        assert len(err) == 1 and head in err[0]
        assert int(err[0].split(head)[1].split("%")[0]) >= 95
        assert not (tmp_path / "out").exists()
    # the faces file written with the image is accepted (its border faces disagree on ~1%)
    assert main(["extract", str(two_materials["scene"]), "--labels", str(out), "--out",
                 str(tmp_path / "out")]) == 0


def test_a_material_with_no_usable_pixel_is_warned_of_on_stderr(two_materials, tmp_path, capsys):
    """Label 2 only on background pixels: material_2.csv is empty, and the warning, which only
    coverage.json held, is printed."""
    labels = (two_materials["truth"] > 0).astype(np.uint16)
    labels[:5, :5] = 2
    cv2.imwrite(str(tmp_path / "l.png"), labels)
    capsys.readouterr()
    assert main(["extract", str(two_materials["scene"]), "--labels", str(tmp_path / "l.png"),
                 "--out", str(tmp_path / "out")]) == 0
    err = capsys.readouterr().err
    assert "warning: material 2: no usable pixel" in err
    assert "material 2 has no usable pixel" in (tmp_path / "out" / "material_2.csv").read_text()


def test_face_labels_carry_the_materials_to_another_camera(two_materials, segmented):
    """A camera 40° around the sphere sees the flash camera's labels through LABELS.faces.npy.

    The icosphere's faces are ~1.5 px across in the flash view, so a face on the boundary can
    go either way, and a strip of this view was never seen by the flash camera: it takes the
    nearest seen face's label, which continues the straight material boundary. Measured
    2026-12-01: 99.7%; 95% leaves room for those, while labels read through the wrong camera's
    pixel grid would be right on about half the pixels.
    """
    from flashbrdf import capture
    from flashbrdf.render import MaterialMap
    out, labels, perm = segmented
    angle = np.radians(40)
    rotation = np.array([[np.cos(angle), 0, np.sin(angle)], [0, 1, 0],
                         [-np.sin(angle), 0, np.cos(angle)]])
    pose = np.eye(4)
    pose[:3, :3] = rotation
    pose[:3, 3] = np.array([0, 0, 1.0]) - rotation @ np.array([0, 0, 1.0])
    other = pinhole_camera(256, 256, 1000.0, world_from_camera=pose)
    scene = capture.load_scene(two_materials["scene"])
    flash_camera = scene.photos_with_role("flash")[0].camera
    view_folder = two_materials["scene"].parent / "other_view"
    view_folder.mkdir(exist_ok=True)
    (view_folder / "object.ply").write_bytes((two_materials["scene"] / "object.ply").read_bytes())
    (view_folder / "ref.exr").write_bytes((two_materials["scene"] / "ref.exr").read_bytes())
    (view_folder / "scene.json").write_text(json.dumps({
        "camera": other, "geometry": {"mesh": "object.ply"},
        "photos": [{"file": "ref.exr", "role": "reference", "light": directional_light()}]}))
    other_camera = capture.load_scene(view_folder).camera
    surface = capture.surface_from_mesh(capture.scene_intersector(scene), other_camera)
    faces = np.load(out.with_name("labels.faces.npy"))
    seen = MaterialMap([None, None], labels, flash_camera, faces).point_labels(surface,
                                                                                other_camera)
    truth = region_image(sphere_mesh(), other, _region)[surface.rows, surface.cols]
    right = np.mean(np.choose(truth - 1, perm) == seen)
    assert len(seen) > 20000 and right >= 0.95, right


def test_run_export_exports_every_material(two_materials, tmp_path):
    # `run --export` on an object of two materials exports each material's table of the method,
    # as run exports the one table of a single-material object: export/material_<k>/ with every
    # format, the files naming the table where it is once run is done; the report renders the
    # Principled fits as one more method (each material its own fit). Before: nothing, exit 0.
    out = tmp_path / "run"
    assert main(["run", str(two_materials["scene"]), "--out", str(out), "--spp", "1",
                 "--methods", "chandraker", "--export"]) == 0
    for k in (1, 2):
        folder = out / "export" / f"material_{k}"
        assert sorted(p.name for p in folder.iterdir() if p.name != ".flashbrdf-output") == [
            "material.gltf", "mitsuba_principled.xml", "mitsuba_tabulated.xml",
            "principled.json"]
        table = str((out / "chandraker" / f"material_{k}" / "brdf.binary").absolute())
        assert json.loads((folder / "principled.json").read_text())["table"] == table
    fits = [json.loads((out / "export" / f"material_{k}" / "principled.json").read_text())[
        "fit"]["lab_log_2d"] for k in (1, 2)]
    report = json.loads((out / "report.json").read_text())
    rows = {r["method"]: r["delta_e_log_mean"] for r in report["references"]}
    assert set(rows) == {"chandraker", "chandraker-principled"}
    # the fits' render against the photo: off by the tables' error plus at most about the
    # worse fit's own (the same CIELAB-of-log units; the fit's is a mean over bins, so this is a
    # rule of thumb, as in test_pipeline_run). Measured: 1.34 against 0.52 + 4.99 (the red
    # plastic's peaky chandraker table is the hard fit); the fits swapped between the two
    # materials (blue on red) would be far off.
    assert rows["chandraker-principled"] < rows["chandraker"] + max(fits), (rows, fits)
    assert "material 2's chandraker BRDF exported to export/material_2/" in (
        out / "report.md").read_text()
    # each material's slice is warned of as a single-material run's is: the blue part starts
    # ~10° off the highlight (x + y/2 > 2 cm on a 10 cm sphere), so its peak is the prior's;
    # the red one holds the highlight, all but the first bin or two (θh < 1°)
    peaks = {int(w.split()[1].rstrip(":")): float(w.split("θh below ")[1].split("°")[0])
             for w in report["warnings"] if "not observed (the specular peak)" in w}
    assert len(peaks) == 2 and max(peaks.values()) > 5 and min(peaks.values()) < 1
    md = (out / "report.md").read_text()
    assert all(f"material {k}: θh below" in md for k in peaks)


def test_batch_export_names_every_materials_table_where_it_is(two_materials, tmp_path):
    # batch --export on an object of two materials: each export/material_<k>/ names the table
    # where it is in OUT_DIR/<capture>/, not in the batch's staging folder (gone)
    import shutil
    captures = tmp_path / "captures"
    shutil.copytree(two_materials["scene"], captures / "a")
    out = tmp_path / "out"
    assert main(["batch", str(captures), "--out", str(out), "--spp", "1",
                 "--methods", "chandraker", "--export"]) == 0
    for k in (1, 2):
        folder = out / "a" / "export" / f"material_{k}"
        table = str((out / "a" / "chandraker" / f"material_{k}" / "brdf.binary").absolute())
        assert json.loads((folder / "principled.json").read_text())["table"] == table
        assert f'value="{table}"' in (folder / "mitsuba_tabulated.xml").read_text()
