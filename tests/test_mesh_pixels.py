"""capture.mesh_pixels: the pixels whose ray can hit the mesh, so that the rays that can only
miss are never cast. It must keep every pixel whose ray hits (traced over the whole frame),
through any lens and camera model, and drop most of the bounding box the object leaves empty."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from flashbrdf.capture import MeshIntersector, mesh_pixels, pixel_box, surface_at_pixels
from flashbrdf.capture.scene import Camera
from synthetic import combine, sphere_mesh, torus_mesh

# a ring (tilted torus) around a ball: a bounding box the object fills loosely, a hole, and
# faces far smaller than a pixel on the ball and larger than a cell on the ring's outer side
MESH = MeshIntersector(combine(torus_mesh(major=0.09, minor=0.012, centre=(0.02, 0.01, 1.0),
                                          sections=(48, 16)),
                               sphere_mesh(radius=0.03, centre=(0.02, 0.01, 1.0),
                                           subdivisions=5)))


def _pose(degrees, position):
    pose = np.eye(4)
    pose[:3, :3] = Rotation.from_euler("xyz", degrees, degrees=True).as_matrix()
    pose[:3, 3] = position
    return pose


CAMERAS = {
    "pinhole": Camera("pinhole", 800, 600, np.eye(4), fx=3600.0, fy=3620.0, cx=365.3,
                      cy=320.8),
    "barrel": Camera("pinhole", 800, 600, np.eye(4), fx=3600.0, fy=3600.0, cx=412.0, cy=280.0,
                     distortion=np.array([-0.35, 0.12, 0.002, -0.001, 0.0])),
    "pincushion": Camera("pinhole", 800, 600, _pose([4, -3, 20], [0.01, 0.0, 0.05]),
                         fx=3200.0, fy=3200.0, cx=399.5, cy=299.5,
                         distortion=np.array([0.3, 0.05, 0.0, 0.0, 0.0])),
    # the ring runs out of the frame: cells past the frame must not wrap around
    "cut by the frame": Camera("pinhole", 640, 480, _pose([0, 0, 0], [0.07, 0.05, 0.2]),
                               fx=2800.0, fy=2800.0, cx=319.5, cy=239.5),
    "orthographic": Camera("orthographic", 720, 560, _pose([10, 20, 5], [0.02, 0.01, 0.6]),
                           pixel_size=0.0004),
}


@pytest.mark.parametrize("name", sorted(CAMERAS))
def test_every_hit_is_kept_and_most_misses_are_not_cast(name):
    camera = CAMERAS[name]
    rows, cols = (a.ravel() for a in np.indices(camera.shape))
    hits = surface_at_pixels(MESH, camera, rows, cols)
    kept_rows, kept_cols = mesh_pixels(camera, MESH.mesh.vertices, MESH.mesh.faces)
    kept = set((kept_rows * camera.width + kept_cols).tolist())
    assert len(hits.rows) > 500
    assert set((hits.rows * camera.width + hits.cols).tolist()) <= kept
    r0, r1, c0, c1 = pixel_box(camera, MESH.mesh.bounds)
    # the ring's hole and the box's empty corners go (~half the box); what is traced is the
    # hits and a band of one to three 8-px cells around the outline
    assert len(kept) < 0.8 * (r1 - r0) * (c1 - c0)
    assert np.all(np.diff(kept_rows * camera.width + kept_cols) > 0)  # row-major, no repeat
    # nothing far from the object: a cell's alignment, its one-cell margin and the 8-px block
    # reach at most 3 x 8 px past the faces' projection (undistorted: a lens adds its own slack)
    reach = 24 + (0 if camera.distortion is None else 8) + 1
    assert kept_rows.min() >= hits.rows.min() - reach and kept_rows.max() <= hits.rows.max() + reach
    assert kept_cols.min() >= hits.cols.min() - reach and kept_cols.max() <= hits.cols.max() + reach


def test_a_mesh_reaching_behind_the_camera_traces_the_whole_box():
    # the camera sits inside the ring's plane: some faces are behind it, where the perspective
    # projection of a face is not the rectangle of its corners
    camera = Camera("pinhole", 120, 90, _pose([0, 90, 0], [0.02, 0.01, 1.0]), fx=300.0,
                    fy=300.0, cx=59.5, cy=44.5)
    kept_rows, _ = mesh_pixels(camera, MESH.mesh.vertices, MESH.mesh.faces)
    r0, r1, c0, c1 = pixel_box(camera, MESH.mesh.bounds)
    assert len(kept_rows) == (r1 - r0) * (c1 - c0) == camera.width * camera.height
