"""import-diligent on a synthetic DiLiGenT folder (answer known) and on the real ball (sign check)."""

import json
import os
from pathlib import Path

import cv2
import numpy as np
import pytest
import scipy.io

from flashbrdf.cli.main import main

# The shared folder sits beside the repo checkout; FLASHBRDF_SHARED overrides it (worktrees).
SHARED = Path(os.environ.get("FLASHBRDF_SHARED", Path(__file__).resolve().parents[2] / "shared"))
BALL = SHARED / "data" / "real" / "diligent-ball"
ALBEDO = np.array([0.30, 0.45, 0.60])  # rho in the photo's units: pixel = rho * cos(theta_i)


def _read_exr(path):
    import OpenImageIO as oiio
    inp = oiio.ImageInput.open(str(path))
    image = inp.read_image("float")
    inp.close()
    return image


def _sphere_normals(height, width, radius):
    """DiLiGenT-frame normals (x right, y up, z toward camera) of a sphere centred in the image."""
    v, u = np.mgrid[0:height, 0:width].astype(float)
    x, y = (u - (width - 1) / 2) / radius, -(v - (height - 1) / 2) / radius
    mask = x * x + y * y < 1.0
    z = np.sqrt(np.clip(1.0 - x * x - y * y, 0.0, None))
    return np.where(mask[..., None], np.stack([x, y, z], -1), 0.0), mask


def make_diligent(folder, height=40, width=48, radius=16.0):
    """Write a tiny Lambertian DiLiGenT folder: 4 lights, 16-bit PNGs, mask, Normal_gt.mat."""
    folder.mkdir(parents=True, exist_ok=True)
    normals, mask = _sphere_normals(height, width, radius)
    directions = np.array([[0.05, -0.06, 1.0], [0.5, 0.2, 0.85], [-0.4, 0.5, 0.75], [0.0, -0.7, 0.7]])
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    intensities = np.array([[0.9, 1.1, 1.6], [1.3, 1.6, 2.1], [1.0, 1.0, 1.0], [0.7, 0.8, 1.2]])
    for k, (light, intensity) in enumerate(zip(directions, intensities)):
        cos = np.clip(normals @ light, 0.0, None) * mask
        counts = np.round(ALBEDO * intensity * cos[..., None] * 65535 * 0.5)
        png = np.clip(counts, 0, 65535).astype(np.uint16)
        cv2.imwrite(str(folder / f"{k + 1:03d}.png"), png[..., ::-1])  # RGB -> BGR on disk
    np.savetxt(folder / "light_directions.txt", directions, fmt="%.6f")
    np.savetxt(folder / "light_intensities.txt", intensities * 0.5, fmt="%.6f")
    cv2.imwrite(str(folder / "mask.png"), np.repeat(mask[..., None], 3, 2).astype(np.uint8) * 255)
    scipy.io.savemat(folder / "Normal_gt.mat", {"Normal_gt": normals})
    return normals, mask, directions


def test_synthetic_scene_reproduces_pixel_model(tmp_path, capsys):
    normals, mask, directions = make_diligent(tmp_path / "obj")
    out = tmp_path / "scene"
    assert main(["import-diligent", str(tmp_path / "obj"), "--flash", "1", "--out", str(out)]) == 0
    scene = json.loads((out / "scene.json").read_text())
    cam = scene["camera"]
    assert cam["model"] == "orthographic" and cam["pixel_size"] == 1.0
    assert (cam["width"], cam["height"]) == (48, 40)
    roles = [p["role"] for p in scene["photos"]]
    assert roles.count("flash") == 1 and roles.count("reference") == 3
    assert scene["photos"][0]["file"] == "001.exr" and scene["photos"][0]["role"] == "flash"
    assert scene["geometry"] == {"normal_map": "normals.npy", "mask": "mask.png"}

    # Normals are in the OpenCV camera frame: the image top (y up in DiLiGenT) has n_y < 0 and
    # the centre faces the camera (n_z = -1, the camera looks along +z).
    n_cam = np.load(out / scene["geometry"]["normal_map"])
    assert n_cam[20 - 14, 24, 1] < -0.8 and n_cam[20, 24 + 14, 0] > 0.8
    assert n_cam[19:21, 23:25, 2].max() < -0.99
    written_mask = cv2.imread(str(out / "mask.png"), cv2.IMREAD_UNCHANGED) > 0
    assert written_mask.ndim == 2 and np.array_equal(written_mask, mask)

    # pixel = rho * E * cos(theta_i) with the scene's own quantities recovers ALBEDO to 16-bit
    # quantisation: counts >= 0.3*0.7*0.2*0.5*65535 ~ 1400 where cos > 0.2, so < 4e-4 relative.
    world_from_camera = np.array(cam["world_from_camera"])[:3, :3]
    for photo in scene["photos"]:
        light_cam = world_from_camera.T @ np.array(photo["light"]["direction"])
        cos = n_cam @ light_cam
        image = _read_exr(out / photo["file"])
        lit = written_mask & (cos > 0.2)
        rho = image[lit] / (np.array(photo["light"]["irradiance_rgb"]) * cos[lit, None])
        np.testing.assert_allclose(np.median(rho, axis=0), ALBEDO, rtol=1e-3)
        assert np.abs(rho / ALBEDO - 1).max() < 2e-3


def test_clipped_reference_pixels_become_nan(tmp_path):
    make_diligent(tmp_path / "obj")
    png = cv2.imread(str(tmp_path / "obj" / "002.png"), cv2.IMREAD_UNCHANGED)
    png[10, 30, 0] = 65535  # one channel clipped is enough: the pixel's colour is unknown
    cv2.imwrite(str(tmp_path / "obj" / "002.png"), png)
    assert main(["import-diligent", str(tmp_path / "obj"), "--flash", "1",
                 "--out", str(tmp_path / "s")]) == 0
    image = _read_exr(tmp_path / "s" / "002.exr")
    assert np.isnan(image[10, 30]).all()
    assert np.count_nonzero(np.isnan(image).any(axis=2)) == 1 + np.count_nonzero(
        (png == 0).all(axis=2))  # and the black background, stored as unknown too


def test_clipped_flash_pixels_are_counted_as_clipped_by_extract(tmp_path):
    """The flash photo's clipped pixels are right-censored (+inf), not NaN: extract counts
    them as clipped, and a θh bin clipped on more than half its pixels is left empty instead
    of reading as the mean of its unclipped rest (as NaN they vanished: the bin kept ALBEDO,
    "clipped 0"). The sphere is Lambertian, so the unclipped pixels give ALBEDO exactly."""
    normals, mask, directions = make_diligent(tmp_path / "obj")
    light, view = directions[0], np.array([0.0, 0.0, 1.0])
    half = (light + view) / np.linalg.norm(light + view)
    theta_h = np.degrees(np.arccos(np.clip(normals @ half, -1, 1)))
    bins = np.floor(np.sqrt(theta_h / 90) * 90).astype(int)
    target = 40  # θh 17.8-18.7°: well inside the disc, away from the silhouette
    members = np.argwhere(mask & (bins == target))
    assert len(members) >= 5
    chosen = members[: len(members) // 2 + 1]  # a majority of the bin
    png = cv2.imread(str(tmp_path / "obj" / "001.png"), cv2.IMREAD_UNCHANGED)
    png[chosen[:, 0], chosen[:, 1], 2] = 65535  # red (BGR on disk) clips
    cv2.imwrite(str(tmp_path / "obj" / "001.png"), png)
    assert main(["import-diligent", str(tmp_path / "obj"), "--flash", "1",
                 "--out", str(tmp_path / "s")]) == 0
    image = _read_exr(tmp_path / "s" / "001.exr")
    assert np.isposinf(image[chosen[:, 0], chosen[:, 1], 0]).all()
    assert main(["extract", str(tmp_path / "s"), "--out", str(tmp_path / "slice.csv")]) == 0
    report = json.loads((tmp_path / "slice.json").read_text())
    assert report["rejected"]["clipped"] == len(chosen)
    rows = [line.split(",") for line in (tmp_path / "slice.csv").read_text().splitlines()
            if line and not line.startswith(("#", "theta"))]
    assert rows[target][1] == "" and rows[target][4] == "0"  # unknown, not ALBEDO


def test_black_reference_pixels_become_nan_and_the_flash_keeps_its_zeros(tmp_path):
    """A pixel at code 0 in every channel is below one step, not a measured black: in a
    reference photo's EXR it is NaN (not compared, as the 16-bit photo read directly would not
    compare it); the flash photo keeps 0 (extraction leaves it out either way). A pixel with
    one channel at 0 keeps its values."""
    make_diligent(tmp_path / "obj")
    raw = {k: cv2.imread(str(tmp_path / "obj" / f"00{k}.png"), cv2.IMREAD_UNCHANGED)
           for k in (1, 2)}
    assert main(["import-diligent", str(tmp_path / "obj"), "--flash", "2",
                 "--out", str(tmp_path / "s")]) == 0
    reference, flash = (_read_exr(tmp_path / "s" / f"00{k}.exr") for k in (1, 2))
    black = (raw[1] == 0).all(axis=2)
    assert 100 < black.sum() < black.size                      # the background, at least
    assert np.isnan(reference[black]).all() and np.isfinite(reference[~black]).all()
    assert np.isfinite(flash).all() and (flash[(raw[2] == 0).all(axis=2)] == 0).all()
    scene = json.loads((tmp_path / "s" / "scene.json").read_text())
    counts = {p["file"]: p["source"]["black_pixels_set_to_nan"] for p in scene["photos"]}
    assert counts["001.exr"] == black.sum() and counts["002.exr"] == 0


def _break(folder, how):
    if how == "missing_intensities":
        (folder / "light_intensities.txt").unlink()
    elif how == "missing_normals":
        (folder / "Normal_gt.mat").unlink()
    elif how == "size_mismatch":
        cv2.imwrite(str(folder / "003.png"), np.zeros((20, 20, 3), np.uint16))
    elif how == "eight_bit":
        cv2.imwrite(str(folder / "004.png"), np.zeros((40, 48, 3), np.uint8))
    elif how == "row_count":
        np.savetxt(folder / "light_directions.txt", np.tile([0.0, 0.0, 1.0], (3, 1)))


@pytest.mark.parametrize("how", ["missing_intensities", "missing_normals", "size_mismatch",
                                 "eight_bit", "row_count"])
def test_bad_input_exits_2_without_output(tmp_path, capsys, how):
    make_diligent(tmp_path / "obj")
    _break(tmp_path / "obj", how)
    out = tmp_path / "scene"
    assert main(["import-diligent", str(tmp_path / "obj"), "--flash", "1", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "obj" in err[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["obj"]  # no scene, no temp folder


@pytest.mark.parametrize("index", ["0", "5", "-1"])
def test_flash_index_out_of_range(tmp_path, capsys, index):
    make_diligent(tmp_path / "obj")
    assert main(["import-diligent", str(tmp_path / "obj"), "--flash", index,
                 "--out", str(tmp_path / "scene")]) == 2
    assert "--flash" in capsys.readouterr().err
    assert not (tmp_path / "scene").exists()


@pytest.mark.filterwarnings("error")  # a warning that reaches the user fails the test
def test_empty_light_file_is_one_line_on_stderr(tmp_path, capsys):
    """An empty light_directions.txt: numpy's loadtxt warned "input contained no data" before the
    error, two more lines on a terminal's stderr (safety.hold_native_stderr drops them only when
    stderr is a file or pipe)."""
    make_diligent(tmp_path / "obj")
    lights = tmp_path / "obj" / "light_directions.txt"
    lights.write_text("")
    assert main(["import-diligent", str(tmp_path / "obj"), "--flash", "1",
                 "--out", str(tmp_path / "scene")]) == 2
    assert capsys.readouterr().err.splitlines() == [
        f"flashbrdf import-diligent: error: {lights}: holds no rows (expected K rows of 3 "
        "numbers, light directions)"]
    assert not (tmp_path / "scene").exists()


def test_refuses_to_clobber_unrelated_folder(tmp_path, capsys):
    make_diligent(tmp_path / "obj")
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("keep me")
    assert main(["import-diligent", str(tmp_path / "obj"), "--flash", "1",
                 "--out", str(tmp_path / "mine")]) == 2
    assert (tmp_path / "mine" / "notes.txt").read_text() == "keep me"
    # --force replaces only a folder flashbrdf made.
    assert main(["import-diligent", str(tmp_path / "obj"), "--flash", "1",
                 "--out", str(tmp_path / "mine"), "--force"]) == 2
    assert (tmp_path / "mine" / "notes.txt").read_text() == "keep me"
    # ...a previous scene folder is kept without --force, and replaced as a whole with it.
    assert main(["import-diligent", str(tmp_path / "obj"), "--flash", "1",
                 "--out", str(tmp_path / "s")]) == 0
    assert main(["import-diligent", str(tmp_path / "obj"), "--flash", "3",
                 "--out", str(tmp_path / "s")]) == 2
    assert "--force" in capsys.readouterr().err
    assert main(["import-diligent", str(tmp_path / "obj"), "--flash", "3",
                 "--out", str(tmp_path / "s"), "--force"]) == 0
    assert json.loads((tmp_path / "s" / "scene.json").read_text())["photos"][0]["file"] == "003.exr"


@pytest.mark.skipif(not BALL.is_dir(), reason=f"real DiLiGenT ball not found at {BALL}")
def test_real_ball_light_sign_convention(tmp_path, capsys):
    """Lights point from the object toward the light in the DiLiGenT frame, as documented.

    On the (mostly diffuse) real ball, pixel brightness must rise monotonically with n.l for the
    written normals and light directions (Spearman rank correlation, which the specular peak does
    not spoil: measured >= 0.987 on the 23 lights > 35 degrees off axis); mirroring x and y of the
    light (the other plausible convention) must not (measured <= -0.43 there). Lights far off
    axis separate the two conventions: near the axis both look alike, so the 8 farthest are used.
    """
    from scipy.stats import spearmanr
    # A 9-photo DiLiGenT folder (the flash and 8 far-off-axis lights, linked, not copied) keeps
    # the test fast; the files and rows are the real ones.
    directions = np.loadtxt(BALL / "light_directions.txt")
    far = [k for k in np.argsort(-np.degrees(np.arccos(directions[:, 2])))[:8]]
    keep = sorted([51] + [int(k) for k in far])  # rows in the photos' (sorted) file order
    small = tmp_path / "ball_subset"
    small.mkdir()
    for k in keep:
        (small / f"{k + 1:03d}.png").symlink_to(BALL / f"{k + 1:03d}.png")
    for name in ("mask.png", "Normal_gt.mat"):
        (small / name).symlink_to(BALL / name)
    np.savetxt(small / "light_directions.txt", directions[keep])
    np.savetxt(small / "light_intensities.txt", np.loadtxt(BALL / "light_intensities.txt")[keep])
    out = tmp_path / "ball"
    flash = keep.index(51) + 1
    assert main(["import-diligent", str(small), "--flash", str(flash), "--out", str(out)]) == 0
    assert json.loads((out / "scene.json").read_text())["photos"][0]["file"] == "052.exr"
    scene = json.loads((out / "scene.json").read_text())
    n_cam = np.load(out / "normals.npy")
    mask = cv2.imread(str(out / "mask.png"), cv2.IMREAD_UNCHANGED) > 0
    rot = np.array(scene["camera"]["world_from_camera"])[:3, :3]
    rho_medians = []
    for photo in scene["photos"]:
        light_cam = rot.T @ np.array(photo["light"]["direction"])
        off_axis = np.degrees(np.arccos(-light_cam[2]))
        if off_axis < 35 and photo["role"] != "flash":
            continue
        luminance = _read_exr(out / photo["file"])[mask].mean(axis=1)
        cos, cos_mirror = n_cam[mask] @ light_cam, n_cam[mask] @ (light_cam * [-1, -1, 1])
        ok = np.isfinite(luminance) & (cos > 0.1)
        ok_mirror = np.isfinite(luminance) & (cos_mirror > 0.1)
        r = spearmanr(cos[ok], luminance[ok])[0]
        r_mirror = spearmanr(cos_mirror[ok_mirror], luminance[ok_mirror])[0]
        assert r > 0.95, (photo["file"], r)
        if photo["role"] != "flash":
            assert r_mirror < 0.0, (photo["file"], r, r_mirror)
        rho_medians.append(np.median(luminance[ok] / cos[ok]))
    # Division by light_intensities.txt makes the ball's albedo the same under every light.
    assert len(rho_medians) == 9
    assert np.std(rho_medians) / np.mean(rho_medians) < 0.05


POT2 = SHARED / "data" / "real" / "diligent-pot2"


def test_eight_bit_crops_read_as_linear_with_a_note(tmp_path, capsys):
    """An 8-bit linear copy (the 16-bit value / 257, as photometric-stereo repositories ship
    DiLiGenT crops) imports to the 16-bit import's values within 8-bit quantisation.

    8-bit code c = round(v16 / 257), read as c / 255 = v16 / 65535 + e with |e| <= 0.5 / 255; after
    the division by the light intensity (>= 0.35 here) the bound is 0.5 / 255 / 0.35 = 0.0056.
    A 16-bit reading of the 8-bit codes (c / 65535) would be 257x too dark and fail it.
    """
    make_diligent(tmp_path / "obj16")
    eight = tmp_path / "obj8"
    eight.mkdir()
    for path in (tmp_path / "obj16").iterdir():
        if path.suffix == ".png" and path.name != "mask.png":
            png16 = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
            cv2.imwrite(str(eight / path.name), np.round(png16 / 257.0).astype(np.uint8))
        else:
            (eight / path.name).write_bytes(path.read_bytes())
    assert main(["import-diligent", str(tmp_path / "obj16"), "--flash", "1",
                 "--out", str(tmp_path / "s16")]) == 0
    capsys.readouterr()
    assert main(["import-diligent", str(eight), "--flash", "1", "--out", str(tmp_path / "s8")]) == 0
    out = capsys.readouterr()
    notes = [line for line in out.out.splitlines() if line.startswith("note:")]
    assert len(notes) == 1 and "8-bit" in notes[0] and "precision" in notes[0] and not out.err
    scene = json.loads((tmp_path / "s8" / "scene.json").read_text())
    assert "8-bit" in scene["provenance"]["precision_note"]
    assert {p["source"]["bit_depth"] for p in scene["photos"]} == {8}
    scene16 = json.loads((tmp_path / "s16" / "scene.json").read_text())
    assert {p["source"]["bit_depth"] for p in scene16["photos"]} == {16}
    assert "precision_note" not in scene16["provenance"]
    for k in range(1, 5):
        a, b = _read_exr(tmp_path / "s8" / f"00{k}.exr"), _read_exr(tmp_path / "s16" / f"00{k}.exr")
        both = np.isfinite(a) & np.isfinite(b)
        # the reference photos' black (code 0) pixels are NaN: the 8-bit copy has a few more
        assert both.sum() > 0.9 * np.isfinite(b).sum() >= 0.3 * a.size  # the lit object, at least
        assert np.abs(a - b)[both].max() <= 0.5 / 255 / 0.35
    # the note's rounding figure: a render of the exact light (the 16-bit import, 257x finer)
    # against the 8-bit photos scores about what the note says rounding alone gives
    from flashbrdf.brdf.metrics import delta_e_log
    errors = []
    for photo in scene["photos"][1:]:                       # the reference photos
        a = _read_exr(tmp_path / "s8" / photo["file"])
        b = _read_exr(tmp_path / "s16" / photo["file"])
        both = np.isfinite(a).all(axis=2) & np.isfinite(b).all(axis=2)
        errors.append(delta_e_log(b[both], a[both]))
    actual = np.concatenate(errors).mean()
    # the 16-bit values' places inside their 8-bit code are near uniform, as the note's model
    # draws them: over the photos' thousands of pixels the two means agree within a few %
    assert scene["provenance"]["rounding_delta_e_log"] == pytest.approx(actual, rel=0.05)
    assert scene16["provenance"]["rounding_delta_e_log"] < actual / 100
    assert f"ΔE-log {scene['provenance']['rounding_delta_e_log']:.2f}" in notes[0]


@pytest.mark.skipif(not POT2.is_dir(), reason=f"real DiLiGenT pot2 (8-bit) not found at {POT2}")
def test_real_pot2_eight_bit_imports(tmp_path, capsys):
    """The real 8-bit pot2 crop (read in place, 3 photos linked) imports with the note, and each
    EXR pixel is the PNG code / 255 / the light's intensity, exactly up to float32 rounding."""
    names = (POT2 / "filenames.txt").read_text().split()
    keep = [51, 0, 40]  # 052 (the near-axis flash) and two others, rows in filenames.txt order
    small = tmp_path / "pot2_subset"
    small.mkdir()
    for k in keep:
        (small / names[k]).symlink_to(POT2 / names[k])
    for name in ("mask.png", "Normal_gt.mat"):
        (small / name).symlink_to(POT2 / name)
    (small / "filenames.txt").write_text("\n".join(names[k] for k in keep) + "\n")
    intensities = np.loadtxt(POT2 / "light_intensities.txt")[keep]
    np.savetxt(small / "light_directions.txt", np.loadtxt(POT2 / "light_directions.txt")[keep])
    np.savetxt(small / "light_intensities.txt", intensities, fmt="%.9g")
    out = tmp_path / "pot2"
    assert main(["import-diligent", str(small), "--flash", "1", "--out", str(out)]) == 0
    assert "precision is reduced" in capsys.readouterr().out
    scene = json.loads((out / "scene.json").read_text())
    assert scene["photos"][0]["file"] == names[51].replace(".png", ".exr")
    png = cv2.imread(str(POT2 / names[51]), cv2.IMREAD_UNCHANGED)[..., ::-1].astype(np.float64)
    exr = _read_exr(out / scene["photos"][0]["file"]).astype(np.float64)
    ok = np.isfinite(exr) & (png < 255)
    assert ok.sum() > 0.5 * ok.size
    expected = png / 255.0 / intensities[0]
    np.testing.assert_allclose(exr[ok], expected[ok], rtol=2e-6, atol=1e-9)


def test_rim_normals_facing_away_are_not_compared(tmp_path):
    """DiLiGenT's Normal_gt holds n_z = 0 on the silhouette (72 pixels of the real ball) and a
    registered mesh can give n_z < 0 there; the orthographic camera sees no such surface, so the
    pixel model renders them 0 (wo at or below the horizon) while the photo shows them lit.
    import-diligent keeps the mask (extraction and segmentation see what they saw) and writes
    those pixels as NaN in the reference photos, so a render of the true BRDF matches them.

    The true BRDF is a constant table rho = ALBEDO (photo units). With the rim compared, a
    render is 0 on ~12% of the pixels (delta E-log 4.9 mean); without it the only error is
    16-bit quantisation (< 4e-4 relative, delta E-log < 0.01), so < 0.05 holds."""
    from flashbrdf.brdf.merl import write_merl
    normals, mask, _ = make_diligent(tmp_path / "obj")
    rim = mask & ~(cv2.erode(mask.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0)
    flat = normals.copy()
    flat[rim, 2] = 0.0
    flat[rim] /= np.linalg.norm(flat[rim], axis=1, keepdims=True)
    rows, cols = np.nonzero(rim)
    flat[rows[::5], cols[::5], 2] = -0.1  # a few facing away
    scipy.io.savemat(tmp_path / "obj" / "Normal_gt.mat", {"Normal_gt": flat})
    out = tmp_path / "scene"
    assert main(["import-diligent", str(tmp_path / "obj"), "--flash", "1", "--out", str(out)]) == 0
    written = cv2.imread(str(out / "mask.png"), cv2.IMREAD_UNCHANGED) > 0
    assert np.array_equal(written, mask)
    assert np.isfinite(_read_exr(out / "001.exr")[rim]).all()  # the flash photo keeps them
    assert np.isnan(_read_exr(out / "002.exr")[rim]).all()
    scene = json.loads((out / "scene.json").read_text())
    counts = {p["file"]: p["source"]["unseen_normal_pixels_set_to_nan"] for p in scene["photos"]}
    expected = {}
    for photo in scene["photos"]:      # counted apart from the rim's black or clipped pixels
        raw = cv2.imread(str(tmp_path / "obj" / photo["source"]["file"]), cv2.IMREAD_UNCHANGED)
        other = (raw == 0).all(axis=2) | (raw >= 65535).any(axis=2)
        expected[photo["file"]] = 0 if photo["role"] == "flash" else int((rim & ~other).sum())
    assert counts == expected and 0 < expected["002.exr"] < rim.sum()
    table = tmp_path / "true.binary"
    write_merl(table, np.broadcast_to(ALBEDO, (90, 90, 180, 3)))
    assert main(["render", str(out), "--brdf", str(table), "--out", str(tmp_path / "r")]) == 0
    for stem in ("002", "003", "004"):
        got = json.loads((tmp_path / "r" / f"{stem}_compare.json").read_text())
        assert got["delta_e_log_mean"] < 0.05, (stem, got)


@pytest.mark.skipif(not BALL.is_dir(), reason=f"real DiLiGenT ball not found at {BALL}")
def test_a_flash_too_far_off_the_view_is_warned_of_at_import(tmp_path, capsys):
    """A directional light and an orthographic view: θd is half the angle between them, the
    same at every pixel. The ball's light 60 is 11.0° off (θd 5.5°, past extract's 5°): the
    import says so, and names the lights near the view (52, the one 0.0° off, first); light 52
    gets no warning. (The run of such a scene exited 2 with no hint of the cause.)"""
    from flashbrdf.capture.importers.diligent import off_axis_note
    directions = np.loadtxt(BALL / "light_directions.txt")
    note = off_axis_note(directions, 60, 5.0)
    assert note.startswith("warning: light 60 is 11.0° off the view (θd 5.5°")
    assert note.endswith("lights near the view: 52, 4, 53, 5")
    assert off_axis_note(directions, 52, 5.0) is None
    small = tmp_path / "ball"
    small.mkdir()
    for k in (51, 59):
        (small / f"{k + 1:03d}.png").symlink_to(BALL / f"{k + 1:03d}.png")
    for name in ("mask.png", "Normal_gt.mat"):
        (small / name).symlink_to(BALL / name)
    np.savetxt(small / "light_directions.txt", directions[[51, 59]])
    intensities = np.loadtxt(BALL / "light_intensities.txt")
    np.savetxt(small / "light_intensities.txt", intensities[[51, 59]])
    capsys.readouterr()
    assert main(["import-diligent", str(small), "--flash", "2", "--out", str(tmp_path / "s")]) == 0
    assert "warning: light 2 is 11.0° off the view" in capsys.readouterr().err



def test_the_rounding_figure_draws_no_negative_light(monkeypatch):
    """A channel at code 0 held light in [0, ½) of a code: the rounding figure's light is never
    negative (drawn in ±½ it went below 0 for half of such channels)."""
    import flashbrdf.brdf.metrics as metrics
    from flashbrdf.capture.importers.diligent import rounding_delta_e
    drawn = []
    monkeypatch.setattr(metrics, "delta_e_log", lambda light, stored: drawn.append(light)
                        or np.zeros(len(light)))
    raw = np.zeros((20, 20, 3), np.uint8)
    raw[..., 1:] = 7                                          # red at code 0, the rest lit
    linear = raw / 255.0
    assert rounding_delta_e(raw, linear, np.ones((20, 20), bool), 255, 1.0) == (0.0, 400)
    assert drawn[0][:, 0].min() >= 0 and drawn[0][:, 0].max() < 0.5 / 255
