"""A synthetic multi-view flash capture with its COLMAP model, for import-colmap's tests, the
benchmark and sample_data/colmap.

    python tests/colmap_synthetic.py --out sample_data/colmap   # the shipped sample

The object: a tilted torus around a sphere (each shadows the other under an offset flash), with
analytic vertex normals and a known BRDF (render.GGX, Fresnel off: its theta_d = 0 slice is
known exactly). Views sit on two rings around it, each photographed with a flash at
FLASH_OFFSET in the camera frame and rendered by flashbrdf's own renderer (render.render_scene:
the contract's pixel model, per-photo cameras, lens distortion, shadow rays). Two COLMAP cameras
share the views: an OPENCV one with distortion and a SIMPLE_RADIAL one, both with the principal
point off centre.

Written into OUT:
  images/view_NN.exr      the flash photos (linear, photon noise if asked)
  object.ply              the mesh, in the model's frame (metres)
  sparse/ (text) and sparse_bin/ (binary): the COLMAP model written by pycolmap. Its images are
                          named view_NN.jpg (SfM ran on JPEGs; the flash photos are EXR). Its 3D
                          points lie on the visible surface, plus BACKGROUND_SHARE on a floor the
                          mesh does not hold; their 2D points carry Gaussian noise.
  truth/scene.json        the scene written by hand from the true cameras (paths ../images, ..)
The true contract cameras are the ones in truth/scene.json.
"""

import argparse
import json
import os
import sys
from pathlib import Path

import numpy as np

try:  # as tests' helper (tests/ on the path) or as tests.colmap_synthetic (benchmarks)
    from synthetic import combine, sphere_mesh, torus_mesh
except ImportError:
    from tests.synthetic import combine, sphere_mesh, torus_mesh

FLASH_OFFSET = (0.03, -0.02, 0.0)   # metres, camera frame: right of and above the lens
BACKGROUND_SHARE = 0.2
# COLMAP cameras, in COLMAP's own convention (pixel centres at +0.5): model, W, H, params
CAMERAS = {1: ("OPENCV", 240, 180, [300.0, 303.0, 126.3, 86.1, -0.12, 0.05, 0.0015, -0.001]),
           2: ("SIMPLE_RADIAL", 240, 180, [330.0, 116.8, 94.2, 0.08])}


def ggx_model():
    from flashbrdf.brdf.models import GGX
    return GGX(alpha=0.18, specular=(0.5, 0.5, 0.5), diffuse=(0.55, 0.3, 0.15), fresnel=False)


def true_slice(model):
    """rho (90, 3) of a render BRDF model at the MERL theta_h bin centres, theta_d = 0."""
    from flashbrdf.brdf.merl import theta_h_centres
    th = theta_h_centres()
    w = np.stack([np.sin(th), np.zeros_like(th), np.cos(th)], -1)
    return model.evaluate_local(w, w.copy())


def object_mesh():
    """A torus tilted 50 degrees about x around a sphere, centred on the origin."""
    return combine(torus_mesh(centre=(0, 0, 0)), sphere_mesh(radius=0.045, centre=(0, 0, 0),
                                                             subdivisions=4))


def look_at(centre, target=(0, 0, 0), up=(0, 0, 1)):
    """world_from_camera (4, 4) with OpenCV axes: z toward target, y down (against `up`)."""
    centre = np.asarray(centre, float)
    z = np.asarray(target, float) - centre
    z /= np.linalg.norm(z)
    y = -np.asarray(up, float) + np.dot(up, z) * z
    y /= np.linalg.norm(y)
    pose = np.eye(4)
    pose[:3, :3] = np.stack([np.cross(y, z), y, z], axis=1)
    pose[:3, 3] = centre
    return pose


def view_poses(views, distance=0.6):
    """Poses on two rings (elevation 25 and 50 degrees) around the origin."""
    poses = []
    for k in range(views):
        azimuth = 2 * np.pi * k / views
        elevation = np.radians(25 if k % 2 == 0 else 50)
        centre = distance * np.array([np.cos(elevation) * np.cos(azimuth),
                                      np.cos(elevation) * np.sin(azimuth), np.sin(elevation)])
        poses.append(look_at(centre))
    return poses


def contract_camera(camera_id, pose, cameras=CAMERAS):
    """The contract camera dict of COLMAP camera `camera_id` at `pose` (the truth)."""
    model, width, height, p = cameras[camera_id]
    if model == "SIMPLE_RADIAL":
        fx = fy = p[0]
        cx, cy, distortion = p[1], p[2], [p[3], 0.0, 0.0, 0.0, 0.0]
    elif model == "OPENCV":
        fx, fy, cx, cy = p[:4]
        distortion = [p[4], p[5], p[6], p[7], 0.0]
    elif model == "PINHOLE":
        fx, fy, cx, cy = p
        distortion = []
    elif model == "SIMPLE_PINHOLE":
        fx = fy = p[0]
        cx, cy, distortion = p[1], p[2], []
    else:
        raise ValueError(f"no truth for {model}")
    cam = {"model": "pinhole", "width": width, "height": height, "fx": fx, "fy": fy,
           "cx": cx - 0.5, "cy": cy - 0.5, "world_from_camera": np.asarray(pose).tolist()}
    if any(distortion):
        cam["distortion"] = distortion
    return cam


def _write_truth_scene(folder, names, cams, offset, intensity=(1.0, 1.0, 1.0)):
    folder.mkdir(parents=True, exist_ok=True)
    photos = [{"file": f"../images/{n}.exr", "role": "flash", "camera": cam,
               "light": {"type": "point", "position": list(offset),
                         "intensity_rgb": list(intensity)}} for n, cam in zip(names, cams)]
    scene = {"camera": cams[0], "geometry": {"mesh": "../object.ply"}, "photos": photos}
    (folder / "scene.json").write_text(json.dumps(scene, indent=1))
    return folder


def render_photos(truth_dir, brdf, photons=None, seed=0):
    """Render every flash photo of the truth scene: {stem: (H, W, 3) float32}."""
    from flashbrdf import capture
    from flashbrdf.render import render_scene
    scene = capture.load_scene(truth_dir)
    rng = np.random.default_rng(seed)
    images = {}
    for photo, image, _ in render_scene(scene, brdf, photos=scene.photos_with_role("flash"),
                                        progress=False):
        if photons is not None:
            image = (rng.poisson(np.maximum(image, 0) * photons) / photons).astype(np.float32)
        images[photo.stem] = image
    return images


def _surface_points(scene, intersector, count, rng):
    """World points on the visible surface: hits of random pixels of random views."""
    from flashbrdf import capture
    flash = scene.photos_with_role("flash")
    found = []
    while sum(len(f) for f in found) < count:
        cam = flash[rng.integers(len(flash))].camera
        rows = rng.uniform(0, cam.height - 1, 4 * count)
        cols = rng.uniform(0, cam.width - 1, 4 * count)
        origins, dirs = capture.pixel_rays(cam, rows, cols)
        hits = capture.intersect(intersector, origins, dirs)
        found.append(hits.points[hits.hit][: count // 4 + 1])
    return np.concatenate(found)[:count]


def _floor_points(count, rng, below=-0.13, reach=0.35):
    """Points on a floor the mesh does not hold (a table under the object)."""
    xy = rng.uniform(-reach, reach, (count, 2))
    return np.column_stack([xy, np.full(count, below)])


def _observations(scene, intersector, points, tolerance):
    """For each view k: (indices of the points it sees, their contract pixel (u, v))."""
    from flashbrdf import capture
    seen = []
    for photo in scene.photos_with_role("flash"):
        cam = photo.camera
        uv, z = capture.project_points(cam, points)
        inside = (z > 0) & (uv[:, 0] > 0) & (uv[:, 0] < cam.width - 1) & (uv[:, 1] > 0) & \
            (uv[:, 1] < cam.height - 1)
        sight = points - cam.centre_world
        length = np.linalg.norm(sight, axis=1)
        hits = capture.intersect(intersector, np.broadcast_to(cam.centre_world, points.shape),
                                 sight / length[:, None])
        visible = inside & (hits.distance > length - tolerance)
        index = np.flatnonzero(visible)
        seen.append((index, uv[index]))
    return seen


def write_colmap_model(folder, names, camera_ids, poses, points, seen, cameras=CAMERAS,
                       keypoint_noise_px=0.3, seed=0, binary=False, rigs_and_frames=True):
    """Write the COLMAP model of the views with pycolmap (COLMAP's conventions: cx + 0.5,
    cam_from_world). seen[k] = (point indices, contract (u, v)) of view k. Only points seen by
    two views or more are kept. rigs_and_frames=False writes the pre-3.12 layout."""
    import pycolmap
    rng = np.random.default_rng(seed)
    rec = pycolmap.Reconstruction()
    for camera_id, (model, width, height, params) in cameras.items():
        cam = pycolmap.Camera.create_from_model_name(camera_id, model, params[0], width, height)
        cam.params = params
        rec.add_camera_with_trivial_rig(cam)
    views_of = np.zeros(len(points), int)
    for index, _ in seen:
        views_of[index] += 1
    tracks = {}
    for k, (name, camera_id, pose) in enumerate(zip(names, camera_ids, poses)):
        index, uv = seen[k]
        keep = views_of[index] >= 2
        index, uv = index[keep], uv[keep]
        keypoints = uv + 0.5 + rng.normal(0, keypoint_noise_px, uv.shape)
        image = pycolmap.Image(name=f"{name}.jpg", keypoints=keypoints, camera_id=camera_id,
                               image_id=k + 1)
        cam_from_world = np.linalg.inv(pose)
        rec.add_image_with_trivial_frame(image, pycolmap.Rigid3d(
            pycolmap.Rotation3d(cam_from_world[:3, :3]), cam_from_world[:3, 3]))
        for slot, p in enumerate(index.tolist()):
            tracks.setdefault(p, []).append((k + 1, slot))
    for p, elements in sorted(tracks.items()):
        track = pycolmap.Track()
        for image_id, slot in elements:
            track.add_element(image_id, slot)
        rec.add_point3D(points[p], track)
    rec.update_point_3d_errors()
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    (rec.write_binary if binary else rec.write_text)(str(folder))
    if not rigs_and_frames:
        for name in ("rigs", "frames"):
            for ext in (".txt", ".bin"):
                (folder / f"{name}{ext}").unlink(missing_ok=True)
    return folder


def make_colmap_capture(out, views=10, photons=None, seed=0, points=1500, cameras=CAMERAS,
                        offset=FLASH_OFFSET, keypoint_noise_px=0.3, size_scale=1, renderer=None):
    """Render the capture and write everything listed in the module docstring into `out`.

    size_scale: multiplies every camera's size and intrinsics (a larger capture, same views).
    renderer: None (flashbrdf's renderer, the GGX of ggx_model), or a callable(truth scene
    folder) -> {stem: (H, W, 3) float32} (another renderer; brdf is then None).
    Returns a dict: out, images, mesh, sparse (text model), sparse_bin, truth (scene folder),
    brdf (render.GGX), names, camera_ids, poses, points (N, 3), cameras (COLMAP, as written).
    """
    from flashbrdf import capture
    out = Path(out)
    cameras = {cid: (m, w * size_scale, h * size_scale,
                     [v * size_scale if j < (3 if m.startswith("SIMPLE") else 4) else v
                      for j, v in enumerate(p)])
               for cid, (m, w, h, p) in cameras.items()}
    (out / "images").mkdir(parents=True, exist_ok=True)
    mesh = object_mesh()
    mesh.export(out / "object.ply", vertex_normal=True)
    names = [f"view_{k:02d}" for k in range(views)]
    ids = sorted(cameras)
    camera_ids = [ids[k % len(ids)] for k in range(views)]
    poses = view_poses(views)
    cams = [contract_camera(c, pose, cameras) for c, pose in zip(camera_ids, poses)]
    truth = _write_truth_scene(out / "truth", names, cams, offset)
    brdf = ggx_model() if renderer is None else None
    images = render_photos(truth, brdf, photons, seed) if renderer is None else renderer(truth)
    for stem, image in images.items():
        from flashbrdf.render import write_exr
        write_exr(out / "images" / f"{stem}.exr", image)
    scene = capture.load_scene(truth)
    intersector = capture.scene_intersector(scene)
    rng = np.random.default_rng(seed + 1)
    n_floor = int(round(BACKGROUND_SHARE * points))
    world = np.concatenate([_surface_points(scene, intersector, points - n_floor, rng),
                            _floor_points(n_floor, rng)])
    seen = _observations(scene, intersector, world, 1e-4 * intersector.scale)
    for folder, binary in (("sparse", False), ("sparse_bin", True)):
        write_colmap_model(out / folder, names, camera_ids, poses, world, seen, cameras,
                           keypoint_noise_px, seed, binary=binary)
    return {"out": out, "images": out / "images", "mesh": out / "object.ply",
            "sparse": out / "sparse", "sparse_bin": out / "sparse_bin", "truth": truth,
            "brdf": brdf, "names": names, "camera_ids": camera_ids, "poses": poses,
            "points": world, "cameras": cameras}


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", required=True)
    p.add_argument("--views", type=int, default=10)
    p.add_argument("--photons", type=float, default=2e4,
                   help="shot noise: a pixel of value v collects v * this photons")
    p.add_argument("--seed", type=int, default=0)
    a = p.parse_args(argv)
    made = make_colmap_capture(a.out, a.views, a.photons, a.seed)
    print(f"wrote {made['out']} ({os.path.relpath(made['sparse'])}, "
          f"{len(made['names'])} photos)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
