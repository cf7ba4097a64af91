"""Camera.to_world / to_camera: the pose applied to points and directions, and its inverse."""

import numpy as np
from scipy.spatial.transform import Rotation

from flashbrdf.capture.camera import embree_rays, pixel_rays, project_points
from flashbrdf.capture.scene import Camera


def _camera():
    pose = np.eye(4)
    pose[:3, :3] = Rotation.from_euler("xyz", [30, -50, 110], degrees=True).as_matrix()
    pose[:3, 3] = [0.3, -1.2, 2.5]
    return Camera("pinhole", 64, 48, pose, fx=50.0, fy=50.0, cx=31.5, cy=23.5)


def test_to_world_and_to_camera_are_inverse_and_keep_lengths():
    camera = _camera()
    rng = np.random.default_rng(0)
    local = rng.normal(size=(100, 3))
    world = camera.to_world(local)
    # the camera origin goes to the centre and +z to the forward axis
    np.testing.assert_array_equal(camera.to_world(np.zeros(3)), camera.centre_world)
    np.testing.assert_allclose(camera.to_world([0, 0, 1], point=False), camera.forward, atol=1e-15)
    # a rigid pose: round trip to ~1e-15 of the coordinates' size (a few ulps), lengths kept
    np.testing.assert_allclose(camera.to_camera(world), local, atol=1e-14)
    dirs = camera.to_world(local, point=False)
    np.testing.assert_allclose(np.linalg.norm(dirs, axis=1), np.linalg.norm(local, axis=1),
                               rtol=1e-14)
    np.testing.assert_allclose(camera.to_camera(dirs, point=False), local, atol=1e-14)


def test_project_points_uses_the_camera_frame_depth():
    camera = _camera()
    # a point 2 m in front of the camera on its axis projects to the principal point at depth 2
    uv, z = project_points(camera, camera.to_world([0.0, 0.0, 2.0])[None])
    np.testing.assert_allclose(uv[0], [camera.cx, camera.cy], atol=1e-9)
    np.testing.assert_allclose(z, [2.0], rtol=1e-14)


def test_embree_rays_of_a_distorted_camera_match_its_exact_rays():
    # extraction's float32 rays read a cached undistortion map; they must be the exact
    # (float64, iterative) rays of the same pixels to float32 precision: a component of the
    # normalised (x, y, 1) ray, |.| <= 1.5 here, carries <= 1.5 x 2^-24 rounding in the map and
    # as much again in the rotation, ~2e-7 rad, i.e. 1e-5 px at f = 50 (2e-3 px at f = 7200).
    pose = _camera().world_from_camera
    camera = Camera("pinhole", 64, 48, pose, fx=50.0, fy=50.5, cx=33.0, cy=22.0,
                    distortion=np.array([-0.2, 0.05, 0.001, -0.002, 0.0]))
    rows, cols = (a.ravel() for a in np.indices(camera.shape))
    _, exact = pixel_rays(camera, rows, cols)
    for shift in (np.zeros(3), np.array([0.1, 0.2, -0.3])):
        origins, directions = embree_rays(camera, rows, cols, shift)
        unit = directions.astype(np.float64)
        unit /= np.linalg.norm(unit, axis=1, keepdims=True)
        assert np.abs(unit - exact).max() < 4e-7
        np.testing.assert_allclose(origins[0], camera.centre_world - shift, atol=1e-6)
    # a second lens replaces the cached map: its rays are its own, not the first lens's
    other = Camera("pinhole", 64, 48, pose, fx=50.0, fy=50.5, cx=33.0, cy=22.0,
                   distortion=np.array([0.3, 0.0, 0.0, 0.0, 0.0]))
    _, directions = embree_rays(other, rows, cols, np.zeros(3))
    unit = directions / np.linalg.norm(directions, axis=1, keepdims=True)
    assert np.abs(unit - pixel_rays(other, rows, cols)[1]).max() < 4e-7
    assert np.abs(unit - exact).max() > 1e-3  # the two lenses differ by far more


def test_a_wide_angle_lens_gets_colmaps_rays_into_its_corners():
    """An action-camera-like OPENCV lens (k1 -0.28, k2 0.08, ~100° across): the fixed-point
    inversion of the distortion converges slowly near the corners (normalised radius ~1.6),
    where 40 iterations left rays 3.3 px off at 800 px (17 px at 4000). COLMAP's own
    unprojection is the reference; 0.01 px is far below a pixel and far above the rounding."""
    import pycolmap
    width, height, f = 800, 600, 340.0
    lens = pycolmap.Camera.create_from_model_name(1, "OPENCV", f, width, height)
    lens.params = [f, f, width / 2, height / 2, -0.28, 0.08, 0.0, 0.0]
    camera = Camera("pinhole", width, height, np.eye(4), fx=f, fy=f, cx=width / 2 - 0.5,
                    cy=height / 2 - 0.5, distortion=np.array([-0.28, 0.08, 0, 0, 0]))
    rows, cols = (g.ravel() for g in np.mgrid[0:height:2, 0:width:2])
    want = np.asarray(lens.cam_from_img(np.c_[cols + 0.5, rows + 0.5]))   # COLMAP: centre +0.5
    _, exact = pixel_rays(camera, rows, cols)
    _, fast = embree_rays(camera, rows, cols, np.zeros(3))
    for directions in (exact, fast.astype(np.float64)):
        error_px = f * np.linalg.norm(directions[:, :2] / directions[:, 2:] - want, axis=1)
        assert error_px.max() < 0.01, error_px.max()


def test_the_pixel_box_of_a_distorted_lens_holds_every_hit_and_little_else():
    # A sphere off the axis of a strongly distorted lens: the box (margin 0) must hold every
    # pixel whose ray hits (traced over the whole frame), and be that set's bounding box
    # exactly up to the corners' slack (the sphere's bounding cube, ~1.3× its disc here), far
    # smaller than the frame the box used to be for any distorted lens.
    from flashbrdf.capture import MeshIntersector, pixel_box, surface_at_pixels
    from synthetic import sphere_mesh
    camera = Camera("pinhole", 160, 120, np.eye(4), fx=120.0, fy=120.0, cx=80.0, cy=60.0,
                    distortion=np.array([-0.25, 0.08, 0.001, -0.001, 0.0]))
    mesh = MeshIntersector(sphere_mesh(radius=0.08, centre=(0.25, 0.12, 1.0), subdivisions=4))
    rows, cols = (a.ravel() for a in np.indices(camera.shape))
    hits = surface_at_pixels(mesh, camera, rows, cols)
    r0, r1, c0, c1 = pixel_box(camera, mesh.mesh.bounds, margin=0)
    assert hits.rows.min() >= r0 and hits.rows.max() < r1
    assert hits.cols.min() >= c0 and hits.cols.max() < c1
    hit_area = (np.ptp(hits.rows) + 1) * (np.ptp(hits.cols) + 1)
    assert hit_area <= (r1 - r0) * (c1 - c0) <= 2.0 * hit_area < 0.25 * camera.width * camera.height


def test_views_alternating_between_two_lenses_undistort_each_lens_once(monkeypatch):
    """Views that alternate between two lenses (sample_data/colmap: two COLMAP cameras) kept one
    undistortion map and rebuilt it at every change of lens: 12 maps for 12 views, half of a
    1.5 MP extraction. Each lens's map is now built once (both fit the cache)."""
    import collections

    import flashbrdf.capture.camera as camera_module
    monkeypatch.setattr(camera_module, "_lens_grids", collections.OrderedDict(), raising=False)
    undistorted = []
    real = camera_module.cv2.undistortPoints

    def counted(points, *args, **kwargs):
        undistorted.append(len(points))
        return real(points, *args, **kwargs)

    monkeypatch.setattr(camera_module.cv2, "undistortPoints", counted)
    pose = _camera().world_from_camera
    lenses = [Camera("pinhole", 40, 30, pose, fx=50.0, fy=50.0, cx=19.5, cy=14.5,
                     distortion=np.array([k1, 0.0, 0.0, 0.0, 0.0])) for k1 in (-0.11, 0.07)]
    rows, cols = (a.ravel() for a in np.indices(lenses[0].shape))
    for view in range(6):
        embree_rays(lenses[view % 2], rows, cols, np.zeros(3))
    # one map per lens, each of its 40 x 30 pixels undistorted once (one batch: 1200 < 2^20)
    assert undistorted == [40 * 30, 40 * 30]
