"""DiLiGenT photometric-stereo folders -> flashbrdf scene folders (the contract's import-diligent).

Frames (pbrt-like, named):
- DiLiGenT frame: x image right, y image up, z toward the camera (the dataset's own; its
  light_directions.txt rows are unit vectors in it, from the object toward the light).
- camera frame: OpenCV, x right, y down, z forward (the contract's), so
  camera_from_diligent = diag(1, -1, -1), a 180-degree turn about x (det +1, right-handed).
- world frame: we choose world = DiLiGenT frame, so the light directions are written unchanged
  and world_from_camera = diag(1, -1, -1, 1).

Photos: each 16-bit PNG k is divided by 65535 and by light_intensities.txt row k (RGB) and written
as a linear float32 EXR, so the directional light has irradiance_rgb = (1, 1, 1) and the contract's
pixel model reads pixel = rho * cos(theta_i) directly. Clipped pixels (65535 in any channel) are
written as NaN in reference photos: their true value is unknown, and NaN is the contract's "not a
measurement". In the flash photo the clipped channels are +inf, a float image's clip mark: a
right-censored sample that extraction counts as clipped.
8-bit PNGs (linear crops, the 16-bit value / 257) are divided by 255 instead, which gives the same
scale; scene.json then records each photo's bit_depth and a provenance precision_note.
"""

import os
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from flashbrdf.capture.importers.scene_json import dumps_scene
from flashbrdf.files.errors import InputError
from flashbrdf.files.outputs import check_outputs, staged_output_dir
from flashbrdf.render.images import write_exr

CAMERA_FROM_DILIGENT = np.diag([1.0, -1.0, -1.0])
WORLD_FROM_CAMERA = np.diag([1.0, -1.0, -1.0, 1.0])  # world = DiLiGenT frame
PNG16_MAX = 65535
EIGHT_BIT_NOTE = ("8-bit photos, read as linear (value / 255): 256 levels instead of 65536, so "
                  "dark pixels are coarse and precision is reduced: rounding alone puts the true "
                  "light ΔE-log {floor:.2f} from the reference photos (mean over their object "
                  "pixels), so renders within about that of them are as close as the photos "
                  "can tell")
_NOT_PHOTOS = {"mask.png", "normal_gt.png"}
# light intensities whose photos (pixel / intensity, float32) stay finite and not all zero
MIN_INTENSITY, MAX_INTENSITY = 1e-30, 1e30


@dataclass
class DiligentObject:
    """One DiLiGenT object folder, read and checked (nothing is loaded lazily except the photos).

    photo_paths: list of K Paths, in light order (row k of the light files is photo k).
    light_directions: (K, 3) unit vectors, DiLiGenT frame, object -> light.
    light_intensities: (K, 3) RGB, > 0.
    mask: (H, W) bool, object pixels with a valid normal.
    normals: (H, W, 3) float64 unit normals, DiLiGenT frame (0 outside the mask).
    """
    folder: Path
    photo_paths: list
    light_directions: np.ndarray
    light_intensities: np.ndarray
    mask: np.ndarray
    normals: np.ndarray


def _require(folder, name):
    path = folder / name
    if not path.is_file():
        raise InputError(path, "missing (a DiLiGenT object folder needs *.png, "
                               "light_directions.txt, light_intensities.txt, mask.png and "
                               "Normal_gt.mat)")
    return path


def _read_rows(path, what):
    """(K, 3) float64 from a whitespace- or comma-separated text file; InputError if malformed."""
    try:
        text = path.read_text()
        with warnings.catch_warnings():  # "input contained no data": a second stderr line
            warnings.simplefilter("ignore", UserWarning)
            rows = np.loadtxt(path, delimiter="," if "," in text else None, ndmin=2)
    except ValueError as err:
        raise InputError(path, f"cannot read {what} as rows of 3 numbers ({err})") from None
    if rows.size == 0:
        raise InputError(path, f"holds no rows (expected K rows of 3 numbers, {what})")
    if rows.ndim != 2 or rows.shape[1] != 3 or rows.shape[0] == 0:
        raise InputError(path, f"expected K rows of 3 numbers ({what}), got shape {rows.shape}")
    if not np.all(np.isfinite(rows)):
        raise InputError(path, f"{what} contain non-finite values")
    return rows


def _photo_paths(folder):
    """Photos in light order: filenames.txt when present (DiLiGenT ships it), else sorted *.png."""
    listing = folder / "filenames.txt"
    if listing.is_file():
        try:
            text = listing.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as err:
            raise InputError(listing, f"cannot read the list of photos ({err})") from None
        names = [line.strip() for line in text.splitlines() if line.strip()]
        paths = [folder / name for name in names]
        written = {}  # each photo is written as <stem>.exr: two of one stem would be one file
        for path in paths:
            if not path.is_file():
                raise InputError(path, "listed in filenames.txt but missing")
            name, given = path.stem + ".exr", os.path.relpath(path, folder)
            if name in written:
                raise InputError(listing, f"{given} and {written[name]} would both be written as "
                                          f"{name} (a photo listed twice, or two of one name): "
                                          "list each photo once")
            written[name] = given
        if not paths:
            raise InputError(listing, "lists no photo")
        return paths
    paths = sorted(p for p in folder.glob("*.png") if p.name.lower() not in _NOT_PHOTOS)
    if not paths:
        raise InputError(folder, "no photos (*.png other than mask.png and Normal_gt.png)")
    return paths


def read_png_rgb(path):
    """Read a 16-bit (or 8-bit) linear PNG as (H, W, 3) uint16 / uint8 RGB (OpenCV, BGR flipped).

    DiLiGenT ships 16-bit photos; many photometric-stereo repositories ship crops of them as
    linear 8-bit (the 16-bit value / 257), which import_diligent reads as linear with a note.
    InputError for any other pixel type or channel count.
    """
    from flashbrdf.capture.photo import imread_unchanged  # InputError over OpenCV's size limit
    image = imread_unchanged(path)
    if image is None:
        raise InputError(path, "cannot be read as an image")
    if image.dtype not in (np.uint16, np.uint8):
        raise InputError(path, f"expected a 16-bit (or 8-bit) linear PNG, got {image.dtype}")
    if image.ndim == 2:
        image = np.repeat(image[..., None], 3, axis=2)
    elif image.shape[2] == 4:
        image = image[..., :3]
    elif image.shape[2] != 3:
        raise InputError(path, f"expected 1, 3 or 4 channels, got {image.shape[2]}")
    return np.ascontiguousarray(image[..., ::-1])


def _read_normals(path):
    import scipy.io
    try:
        mat = scipy.io.loadmat(os.fspath(path))
    except Exception as err:  # scipy raises several types for corrupt .mat files
        raise InputError(path, f"cannot be read as a MATLAB file ({err})") from None
    if "Normal_gt" not in mat:
        raise InputError(path, "has no variable 'Normal_gt'")
    normals = np.asarray(mat["Normal_gt"])
    if normals.dtype.kind not in "biuf":  # a string, cell array (object), struct or complex
        raise InputError(path, f"Normal_gt holds {normals.dtype} values; normals are real numbers")
    normals = normals.astype(np.float64)
    if normals.ndim != 3 or normals.shape[2] != 3:
        raise InputError(path, f"Normal_gt must be H x W x 3, got shape {normals.shape}")
    return normals


def read_diligent(obj_dir):
    """Read and check a DiLiGenT object folder -> DiligentObject. InputError on any bad input."""
    folder = Path(obj_dir)
    if not folder.is_dir():
        raise InputError(folder, "not a folder")
    directions = _read_rows(_require(folder, "light_directions.txt"), "light directions")
    intensities = _read_rows(_require(folder, "light_intensities.txt"), "light intensities")
    mask_path, normals_path = _require(folder, "mask.png"), _require(folder, "Normal_gt.mat")
    photos = _photo_paths(folder)
    if not (len(photos) == len(directions) == len(intensities)):
        raise InputError(folder, f"{len(photos)} photos but {len(directions)} light directions and "
                                 f"{len(intensities)} light intensities (need one row per photo)")
    norm = np.linalg.norm(directions, axis=1)
    if np.any(np.abs(norm - 1.0) > 0.05):
        raise InputError(folder / "light_directions.txt", "rows must be unit vectors")
    # > 0, and within what pixel / intensity in 32-bit floats keeps finite and not all zero:
    # 1e-50 made the photos inf and NaN, 1e308 (inf in float32) black, with exit 0
    odd = intensities[~((intensities >= MIN_INTENSITY) & (intensities <= MAX_INTENSITY))]
    if odd.size:
        raise InputError(folder / "light_intensities.txt",
                         f"intensity {odd[0]:g} is outside {MIN_INTENSITY:g}..{MAX_INTENSITY:g} "
                         "(intensities must be > 0; photos are stored as pixel / intensity in "
                         "32-bit floats)")
    from flashbrdf.capture.photo import read_object_mask  # InputError over OpenCV's limits
    mask = read_object_mask(mask_path)
    normals = _read_normals(normals_path)
    if normals.shape[:2] != mask.shape:
        raise InputError(normals_path, f"size {normals.shape[1]}x{normals.shape[0]} differs from "
                                       f"mask.png's {mask.shape[1]}x{mask.shape[0]}")
    length = np.linalg.norm(normals, axis=2)
    mask &= np.isfinite(length) & (length > 0.5)
    if not mask.any():
        raise InputError(mask_path, "no object pixel with a valid normal")
    normals = np.where(mask[..., None], normals / np.where(mask, length, 1.0)[..., None], 0.0)
    return DiligentObject(folder, photos, directions / norm[:, None], intensities, mask, normals)


def rounding_delta_e(raw, linear, mask, top, intensity, seed=0):
    """(sum, count) over a photo's measured object pixels of the ΔE-log (brdf.metrics) between
    its stored values `linear` and the light that rounded to the same codes `raw`: code + u,
    u uniform in ±½ per channel (seeded; in [0, ½) at code 0), / top / intensity. Its mean is
    the error a render of the exact light would show from rounding alone."""
    from flashbrdf.brdf.metrics import delta_e_log
    seen = mask & np.isfinite(linear).all(axis=2)
    if not seen.any():
        return 0.0, 0
    codes = raw[seen].astype(np.float64)
    u = np.random.default_rng(seed).uniform(-0.5, 0.5, codes.shape)
    # a channel at code 0 held light in [0, ½) of a code: no negative light
    light = (codes + np.where(codes == 0, np.abs(u), u)) / top
    return float(delta_e_log(light / intensity, linear[seen]).sum()), int(seen.sum())


def normals_to_camera(normals_diligent):
    """(..., 3) DiLiGenT-frame normals -> (..., 3) contract camera-frame normals (x, -y, -z)."""
    return np.asarray(normals_diligent) @ CAMERA_FROM_DILIGENT.T


def off_axis_note(light_directions, flash_index, max_theta_d_deg):
    """A warning when light `flash_index` (1-based) of `light_directions` (K, 3), DiLiGenT's
    frame (z toward the camera), is so far off the view that its θd, half the angle between
    light and view for a directional light and an orthographic camera, passes max_theta_d_deg:
    extraction would keep no pixel. It names the lights that would do. None otherwise."""
    d = np.asarray(light_directions, dtype=np.float64)
    theta_d = np.degrees(np.arccos(np.clip(d[:, 2] / np.linalg.norm(d, axis=1), -1, 1))) / 2
    k = flash_index - 1
    if theta_d[k] <= max_theta_d_deg:
        return None
    near = [int(i) + 1 for i in np.argsort(theta_d) if theta_d[i] <= max_theta_d_deg]
    return (f"warning: light {flash_index} is {2 * theta_d[k]:.1f}° off the view (θd "
            f"{theta_d[k]:.1f}°, past the {max_theta_d_deg:g}° extract keeps): extract and run "
            "will find no pixel; lights near the view: "
            + (", ".join(map(str, near[:6])) if near else "none"))


def import_diligent(obj_dir, flash_index, out_dir, progress=None, force=False, notify=None,
                    max_theta_d_deg=None):
    """Write the contract scene folder for a DiLiGenT object; returns the scene dict.

    flash_index: 1-based index of the photo used as the flash (directional light near the view).
    progress: optional callable wrapping an iterable (e.g. tqdm) for the photo loop.
    force: replace an existing out_dir that flashbrdf made (files.outputs.staged_output_dir).
    notify: optional callable taking one line (the reduced-precision note for 8-bit photos; the
    flash's θd past max_theta_d_deg, extraction's limit, when given).
    """
    import cv2

    obj = read_diligent(obj_dir)
    k_photos = len(obj.photo_paths)
    if not 1 <= int(flash_index) <= k_photos:
        raise InputError("--flash", f"index {flash_index} outside 1..{k_photos}")
    if notify is not None and max_theta_d_deg is not None:
        note = off_axis_note(obj.light_directions, int(flash_index), max_theta_d_deg)
        if note:
            notify(note)
    height, width = obj.mask.shape
    # The view is along -z: a normal with n_z <= 0 (the silhouette's n_z = 0 in Normal_gt, 72
    # pixels of the ball; a registered mesh's rim facing away) is a surface the camera cannot
    # see. The pixel model renders it 0 and extraction rejects it, while the photo shows it lit:
    # the reference photos mark it unknown (NaN), as a saturated pixel.
    facing_away = obj.mask & (obj.normals[..., 2] <= 0)
    loop = progress(range(k_photos)) if progress else range(k_photos)
    check_outputs(inputs=[obj.folder, *obj.photo_paths, obj.folder / "light_directions.txt",
                          obj.folder / "light_intensities.txt", obj.folder / "mask.png",
                          obj.folder / "Normal_gt.mat"], outputs=[out_dir], folders=[out_dir])
    with staged_output_dir(out_dir, force=force, command="import-diligent") as staged:
        tmp = Path(staged)
        photos, depths = [], set()
        rounding = []  # per reference photo: (sum, count) of its pixels' ΔE-log from rounding
        for k in loop:
            src = obj.photo_paths[k]
            raw = read_png_rgb(src)
            if raw.shape[:2] != (height, width):
                raise InputError(src, f"size {raw.shape[1]}x{raw.shape[0]} differs from mask.png's "
                                      f"{width}x{height}")
            top = np.iinfo(raw.dtype).max  # 65535, or 255 for 8-bit crops (65535 / 257)
            depths.add(raw.dtype.itemsize * 8)
            if len(depths) > 1:  # one photo of another depth is a mix-up, not a crop
                raise InputError(src, f"is {raw.dtype.itemsize * 8}-bit but the other photos are "
                                      f"{(depths - {raw.dtype.itemsize * 8}).pop()}-bit")
            clipped = np.any(raw >= top, axis=2)
            is_flash = k + 1 == int(flash_index)
            # Code 0 in every channel says only "below one step": in a float EXR a 0 would read
            # as a measured black (a render is compared there), so a reference photo stores it
            # as NaN, unknown, as a saturated pixel. The flash photo keeps it: extraction leaves
            # a 0 out either way.
            black = np.zeros_like(clipped) if is_flash else np.all(raw == 0, axis=2)
            linear = raw.astype(np.float32) / np.float32(top) \
                / obj.light_intensities[k].astype(np.float32)
            if is_flash:
                # A clipped flash pixel is right-censored, brighter than it reads: +inf is the
                # float image's clip mark, so extraction counts it (a bin half clipped or more is
                # left empty). As NaN it vanished, and a bin kept its dimmer unclipped rest.
                linear[raw >= top] = np.inf
            else:
                linear[clipped | black] = np.nan
            unseen = np.zeros_like(clipped) if is_flash else facing_away
            linear[unseen] = np.nan
            if not is_flash:
                rounding.append(rounding_delta_e(raw, linear, obj.mask, top,
                                                 obj.light_intensities[k], seed=k))
            name = src.stem + ".exr"
            write_exr(tmp / name, linear)
            photos.append({
                "file": name, "role": "flash" if is_flash else "reference",
                "scale": 1.0,
                "light": {"type": "directional",
                          "direction": [float(x) for x in obj.light_directions[k]],
                          "irradiance_rgb": [1.0, 1.0, 1.0]},
                "source": {"file": src.name, "index": k + 1, "bit_depth": raw.dtype.itemsize * 8,
                           f"divided_by_{top}_and_intensity_rgb":
                               [float(x) for x in obj.light_intensities[k]],
                           ("clipped_pixels_set_to_inf" if is_flash else
                            "clipped_pixels_set_to_nan"): int(clipped.sum()),
                           "black_pixels_set_to_nan": int(black.sum()),
                           # counted apart from the clipped and black ones it overlaps
                           "unseen_normal_pixels_set_to_nan":
                               int((unseen & ~(clipped | black)).sum())},
            })
        # The flash photo first: readers that take "the first flash" find it at once.
        photos.sort(key=lambda p: p["role"] != "flash")
        np.save(tmp / "normals.npy", normals_to_camera(obj.normals).astype(np.float32))
        cv2.imwrite(os.fspath(tmp / "mask.png"), obj.mask.astype(np.uint8) * 255)
        scene = {
            "camera": {"model": "orthographic", "width": int(width), "height": int(height),
                       "pixel_size": 1.0, "world_from_camera": WORLD_FROM_CAMERA.tolist()},
            "geometry": {"normal_map": "normals.npy", "mask": "mask.png"},
            "photos": photos,
            "provenance": {
                "importer": "flashbrdf import-diligent",
                "source_folder": os.fspath(obj.folder.absolute()),
                "flash_index": int(flash_index),
                "world_frame": "DiLiGenT frame (x image right, y image up, z toward the camera); "
                               "world_from_camera = diag(1,-1,-1,1)",
                "photos": "16-bit PNG / 65535 (8-bit: / 255) / light_intensities.txt row (RGB), "
                          "float32 EXR; clipped pixels (the top code value) are NaN, "
                          "in the flash photo +inf (clipped)",
                "cite": "B. Shi et al., A Benchmark Dataset and Evaluation for Non-Lambertian and "
                        "Uncalibrated Photometric Stereo, CVPR 2016 (research use only)",
            },
        }
        total, count = np.sum(rounding, axis=0) if rounding else (0.0, 0)
        floor = total / count if count else None
        scene["provenance"]["rounding_delta_e_log"] = floor
        if 8 in depths:
            note = EIGHT_BIT_NOTE.format(floor=floor if floor is not None else float("nan"))
            scene["provenance"]["precision_note"] = note
            if notify is not None:
                notify(f"note: {obj.folder.name}: {note}")
        (tmp / "scene.json").write_text(dumps_scene(scene), encoding="utf-8")
    return scene
