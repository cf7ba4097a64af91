"""Known geometry, part 2: a camera-frame normal map with a mask (contract geometry.normal_map).

No ray casting and no depth: normals go from the camera frame to world with world_from_camera, and
view directions are the reversed pixel rays.
"""

from pathlib import Path

import numpy as np

from flashbrdf.files.errors import DECODE_ERRORS, InputError
from flashbrdf.capture.camera import pixel_rays
from flashbrdf.capture.geometry import Surface
from flashbrdf.capture.photo import read_float_image, read_object_mask
from flashbrdf.capture.scene import Scene


def load_normal_map(geometry, camera):
    """Read geometry.normal_map ((H, W, 3) camera-frame unit normals, .npy or .exr) and
    geometry.mask (PNG, nonzero = object). Returns (normals_camera (H, W, 3) float64 unit,
    mask (H, W) bool); pixels with a zero or non-finite normal are dropped from the mask."""
    path = Path(geometry.normal_map)
    if not path.is_file():
        raise InputError(path, "normal map not found")
    if path.suffix.lower() == ".npy":
        try:
            normals = np.load(path, allow_pickle=False)
        except DECODE_ERRORS as err:
            raise InputError(path, f"cannot read normal map: {err}") from None
        if not isinstance(normals, np.ndarray):  # a .npz archive under a .npy name
            raise InputError(path, "is a .npz archive, not a .npy array")
        if normals.dtype.kind not in "biuf":  # strings, complex, structured
            raise InputError(path, f"holds {normals.dtype} values; normals are real numbers")
    else:
        normals = read_float_image(path)
    normals = np.asarray(normals, dtype=np.float64)
    if normals.ndim != 3 or normals.shape[2] < 3:
        raise InputError(path, f"expected an H x W x 3 normal map, got shape {normals.shape}")
    normals = normals[..., :3]
    if normals.shape[:2] != camera.shape:
        raise InputError(path, f"normal map is {normals.shape[1]}x{normals.shape[0]} but the "
                               f"camera is {camera.width}x{camera.height}")
    mpath = Path(geometry.mask)
    if not mpath.is_file():
        raise InputError(mpath, "mask not found")
    mask = read_object_mask(mpath)
    if mask.shape != camera.shape:
        raise InputError(mpath, f"mask is {mask.shape[1]}x{mask.shape[0]} but the camera is "
                                f"{camera.width}x{camera.height}")
    length = np.linalg.norm(normals, axis=-1)
    good = np.isfinite(length) & (length > 1e-6)
    normals = np.where(good[..., None], normals / np.where(good, length, 1)[..., None], 0)
    return normals, mask & good


def surface_from_normal_map(geometry, camera=None, pixel_mask=None):
    """The Surface of normal-map geometry: no ray casting, no depth (points is None).

    geometry: capture.Geometry, or a capture.Scene (then camera defaults to the scene's).

    Normals go from the camera frame to world with world_from_camera; view directions are the
    reversed pixel rays (exact for orthographic cameras; for a pinhole, the direction toward the
    camera centre from any point on the pixel's ray).
    """
    if isinstance(geometry, Scene):
        camera = camera or geometry.camera
        geometry = geometry.geometry
    normals_cam, mask = load_normal_map(geometry, camera)
    if pixel_mask is not None:
        mask = mask & pixel_mask
    rows, cols = np.nonzero(mask)
    normals = camera.to_world(normals_cam[rows, cols], point=False)
    view = -np.array(pixel_rays(camera, rows, cols)[1])
    return Surface(rows, cols, None, normals, view, None)
