"""Describe the real flash-planar-cards capture (MaterialGAN format) as contract scene folders.

Source folder: NN.png (8-bit sRGB, each rectified to the material square), camera_pos.txt and
light_pos.txt (cm, one row per view), image_size.txt (side of the square, cm), light_power.txt
(an estimate). The material is the plane z = 0, centred at the origin.

World frame: the material plane z = 0 with +z its normal (toward the cameras), in metres.

Why a straight-down pinhole with a shifted principal point: a photo rectified to the material square
is exactly what a pinhole camera at the *same* centre of projection sees when its image plane is
parallel to the material (the map from the plane to such an image is a scale and a shift). So each
view is a pinhole at camera_pos with camera axes x = world +x, y = world -y, z = world -z (looking
straight down; image up = world +y, checked on the data: every view's flash highlight lands where
this camera puts the point under the lens), fx = fy = W * height / side and (cx, cy) moved so the
square fills the image. Every pixel's ray then leaves from the true camera position: the view
direction wo = normalize(camera_pos - p) is exact, and the flash (a point light at the camera,
position [0,0,0] in the camera frame) gives the exact wi. A camera "looking at the origin" would
not reproduce a rectified image; an orthographic camera would get wo wrong by up to ~17 degrees.

The contract has one camera per scene, so each view is its own scene folder, view_NN/, holding
that view's photo twice: as the flash photo (to infer from) and as the reference (to predict).
Inferring from view i and predicting view j is then `extract view_i` + `render view_j`.

Pixels: the README says linearise with (x/255)^2.2 (not the piecewise sRGB curve the contract's
"srgb" encoding means: at x = 10 they differ by 3.7x), so photos are written as linear EXR.
Pixels at 255 in any channel are clipped and written as NaN. light_power 1500 is in
pixel-units * cm^2; in metres that is intensity 1500e-4 = 0.15 (absolute scale is an estimate).
"""

from pathlib import Path

import numpy as np

from flashbrdf.capture.importers.scene_json import dumps_scene
from flashbrdf.files.errors import InputError
from flashbrdf.files.outputs import staged_output_dir
from flashbrdf.render.images import write_exr

CM = 0.01  # metres per centimetre
# Camera axes in world: x right = +x, y down = -y (image up is +y), z forward = -z (down).
WORLD_FROM_CAMERA_ROTATION = np.diag([1.0, -1.0, -1.0])


def _read_vectors(path, columns=3):
    if not path.is_file():
        raise InputError(path, "missing")
    try:
        rows = np.loadtxt(path, delimiter="," if "," in path.read_text() else None, ndmin=2)
    except ValueError as err:
        raise InputError(path, f"cannot read rows of numbers ({err})") from None
    if rows.shape[1] != columns or not np.all(np.isfinite(rows)):
        raise InputError(path, f"expected rows of {columns} finite numbers, got shape {rows.shape}")
    return rows


def rectified_plane_camera(camera_pos_m, side_m, width, height):
    """Contract pinhole camera (dict) whose image is the material square [-side/2, side/2]^2 at z = 0.

    camera_pos_m: (3,) camera centre, world metres, above the plane (z > 0).
    The square's edges land on the image's outer pixel edges (-0.5 and width - 0.5), so pixel
    (u, v) sees the plane point x = (u + 0.5) * side / W - side / 2, y = side / 2 - (v + 0.5) * side / H.
    """
    cx_w, cy_w, height_m = (float(c) for c in camera_pos_m)
    if height_m <= 0:
        raise InputError("camera_pos.txt", f"camera at z = {height_m} m is not above the plane")
    fx, fy = width * height_m / side_m, height * height_m / side_m
    pose = np.eye(4)
    pose[:3, :3], pose[:3, 3] = WORLD_FROM_CAMERA_ROTATION, (cx_w, cy_w, height_m)
    return {"model": "pinhole", "width": int(width), "height": int(height),
            "fx": fx, "fy": fy,
            "cx": (width - 1) / 2 + fx * cx_w / height_m,
            "cy": (height - 1) / 2 - fy * cy_w / height_m,
            "world_from_camera": pose.tolist()}


def plane_point_from_pixel(u, v, side_m, width, height):
    """(..., ) pixel coordinates -> (..., 3) world points on the material plane (metres)."""
    x = (np.asarray(u, float) + 0.5) * side_m / width - side_m / 2
    y = side_m / 2 - (np.asarray(v, float) + 0.5) * side_m / height
    return np.stack([x, y, np.zeros_like(x)], axis=-1)


def read_srgb8_as_linear(path, gamma=2.2):
    """8-bit PNG -> (H, W, 3) float32 linear RGB by (x/255)^gamma; clipped (255) pixels -> NaN."""
    from flashbrdf.capture.photo import imread_unchanged  # InputError over OpenCV's size limit
    image = imread_unchanged(path)
    if image is None:
        raise InputError(path, "cannot be read as an image")
    if image.dtype != np.uint8 or image.ndim != 3 or image.shape[2] < 3:
        raise InputError(path, f"expected an 8-bit RGB PNG, got {image.dtype} {image.shape}")
    rgb = image[..., 2::-1]
    linear = (rgb.astype(np.float32) / 255.0) ** np.float32(gamma)
    linear[np.any(rgb == 255, axis=2)] = np.nan
    return linear


def _plane_mesh(side_m):
    import trimesh
    h = side_m / 2
    return trimesh.Trimesh(vertices=[[-h, -h, 0], [h, -h, 0], [h, h, 0], [-h, h, 0]],
                           faces=[[0, 1, 2], [0, 2, 3]], vertex_normals=[[0, 0, 1.0]] * 4,
                           process=False)


def planar_card_scenes(src_dir, out_dir, progress=None):
    """Write one contract scene folder per view of a flash-planar-cards capture.

    Returns the list of view folders (Paths) out_dir/view_NN. out_dir is written atomically.
    progress: optional iterable wrapper (e.g. tqdm).
    """
    src = Path(src_dir)
    if not src.is_dir():
        raise InputError(src, "not a folder")
    cameras_cm = _read_vectors(src / "camera_pos.txt")
    lights_cm = _read_vectors(src / "light_pos.txt") if (src / "light_pos.txt").is_file() \
        else cameras_cm
    side_m = float(_read_vectors(src / "image_size.txt", columns=1)[0, 0]) * CM
    power = _read_vectors(src / "light_power.txt", columns=3)[0] \
        if (src / "light_power.txt").is_file() else np.full(3, 1500.0)
    photos = sorted(p for p in src.glob("[0-9]*.png"))
    if len(photos) != len(cameras_cm) or len(lights_cm) != len(cameras_cm):
        raise InputError(src, f"{len(photos)} photos, {len(cameras_cm)} camera positions and "
                              f"{len(lights_cm)} light positions: need one of each per view")
    views = []
    loop = progress(range(len(photos))) if progress else range(len(photos))
    # force: a dev tool that rebuilds its own output; it still never replaces a folder it did not make
    with staged_output_dir(out_dir, force=True, command="real_scenes") as staged:
        tmp = Path(staged)
        for k in loop:
            linear = read_srgb8_as_linear(photos[k])
            height, width = linear.shape[:2]
            camera = rectified_plane_camera(cameras_cm[k] * CM, side_m, width, height)
            camera_from_world = np.linalg.inv(np.array(camera["world_from_camera"]))
            light_cam = camera_from_world[:3, :3] @ (lights_cm[k] * CM) + camera_from_world[:3, 3]
            light = {"type": "point", "position": [round(float(x), 9) for x in light_cam],
                     "intensity_rgb": [float(p) * CM * CM for p in power]}
            name = f"view_{photos[k].stem}"
            folder = tmp / name
            folder.mkdir()
            write_exr(folder / f"{photos[k].stem}.exr", linear)
            _plane_mesh(side_m).export(folder / "plane.ply")
            photo = {"file": f"{photos[k].stem}.exr", "scale": 1.0, "light": light}
            # The same photo twice: the flash photo to infer from, the reference to predict.
            scene = {
                "camera": camera,
                "geometry": {"mesh": "plane.ply"},
                "photos": [{"role": role, **photo} for role in ("flash", "reference")],
                "provenance": {
                    "source": f"{src.name}/{photos[k].name}",
                    "camera_pos_cm": [float(x) for x in cameras_cm[k]],
                    "world_frame": "material plane z = 0, +z toward the cameras, metres; "
                                   "camera looks straight down with image up = +y",
                    "photos": "8-bit PNG linearised as (x/255)^2.2 (README), 255 -> NaN",
                    "light_intensity": "light_power.txt (an estimate) * 1e-4 (cm^2 -> m^2)",
                    "cite": "Y. Guo et al., MaterialGAN, SIGGRAPH Asia 2020 (research use only)",
                },
            }
            (folder / "scene.json").write_text(dumps_scene(scene), encoding="utf-8")
            views.append(Path(out_dir) / name)
        (tmp / "views.json").write_text(dumps_scene({
            "note": "a set of per-view scene folders (the contract has one camera per scene); "
                    "see each view_NN/scene.json", "views": [v.name for v in views]}),
            encoding="utf-8")
    return views


if __name__ == "__main__":  # python -m benchmarks.planar_scenes SRC_DIR OUT_DIR
    import sys
    for view in planar_card_scenes(sys.argv[1], sys.argv[2]):
        print(view)
