"""Is a mesh in a photogrammetry model's frame? Judged from the model's 3D points and cameras.

A camera saw each 3D point of the model, so in the model's frame the mesh must
- carry the points: the ray from a camera that saw a point meets the mesh first at the point,
  within a tolerance (a point "on the mesh");
- not hide them: a point none of whose sight lines ends on the mesh and most of which meet it
  well before the point (a "hidden" point) is one the cameras could not have seen through it;
- stand in front of the cameras that photographed it.
The tolerance is TOLERANCE_FRACTION of the mesh's bounding-box diagonal. The limits below refuse
a mesh moved by 13% of its diagonal, scaled by 0.9 or 1.05 about its centre, turned 90 degrees,
in millimetres or far away, and accept the true mesh with points scattered about it by up to 2%
of its diagonal, or with tracks that list cameras which could not see the point
(tests/test_import_colmap.py).
A mesh in other units, moved, turned or from another reconstruction fails one of these. Points
of the background (a table, a wall) are neither on the mesh nor hidden by it: they do not count
against it, so a mesh cropped to the object passes.
"""

from dataclasses import dataclass

import numpy as np

from flashbrdf.files.errors import InputError

TOLERANCE_FRACTION = 0.01      # "on the mesh": within 1% of its bounding-box diagonal
NEAR_FRACTION = 0.1            # points within 10% of the diagonal of its box are "around" it
MIN_SHARE_AROUND = 0.2         # of the points around the mesh, at least this share on it
MIN_VIEW_SHARE = 0.5           # of the photos' cameras, at least this share must see the mesh
# hidden points per point on the mesh: ~0 in frame (a point a little inside a smoothed surface),
# 0.9 with points scattered by 2% of the diagonal, >= 1.4 for the wrong meshes above
MAX_HIDDEN_PER_ON = 1.0
# below this share of the points around it on the mesh, a mesh that passes is warned of: the
# sample data's torus turned 10-20° reads 0.25-0.50 (its slice then off by 20-30%), in frame
# 0.95, with its points scattered by 2% of the diagonal 0.31
WARN_SHARE_AROUND = 0.6
VERTICES_CHECKED = 4000


@dataclass(frozen=True)
class FrameCheck:
    """What the model says of the mesh. points: 3D points checked (sampled when many);
    on_mesh: of them, those a camera saw on the mesh; hidden: those the mesh hides (see above);
    around: those within NEAR_FRACTION of the mesh's box, on_around: of those, on the mesh;
    observations, on_observations, hidden_observations: camera-point sight lines checked, those
    ending on the mesh, those it blocks; tolerance: model units; views, views_seeing: photos'
    cameras, and those with the mesh in front and in the image."""
    points: int
    on_mesh: int
    hidden: int
    around: int
    on_around: int
    observations: int
    on_observations: int
    hidden_observations: int
    tolerance: float
    views: int
    views_seeing: int

    @property
    def share_on_mesh(self):
        return self.on_mesh / self.points if self.points else None

    def warning(self):
        """What the check could not rule out for a mesh it passes, or None."""
        if not self.points:
            return ("the model has no 3D points, so the mesh's frame was not checked: a mesh in "
                    "other units, moved or turned is not caught, and would skew every θh")
        if self.around >= 10 and self.on_around < WARN_SHARE_AROUND * self.around:
            return (f"only {self.on_around} of the {self.around} 3D points around the mesh "
                    f"({100 * self.on_around / self.around:.0f}%) lie on it: unless the "
                    "reconstruction is that noisy, the mesh is turned or moved a little (10-20° "
                    "skews the slice by 20-30%); compare it with the points, e.g. in MeshLab")
        return None

    def problem(self):
        """Why the mesh is not in the model's frame, or None."""
        if self.views and self.views_seeing < MIN_VIEW_SHARE * self.views:
            return (f"only {self.views_seeing} of the {self.views} photos' cameras have it in "
                    "front of them and in view")
        if not self.points:
            return None
        if self.on_mesh == 0:
            return (f"none of the model's {self.points} 3D points lies on it (within "
                    f"{self.tolerance:.3g} model units)")
        if self.hidden >= 10 and self.hidden > MAX_HIDDEN_PER_ON * self.on_mesh:
            return (f"it hides {self.hidden} of the model's {self.points} 3D points from the "
                    f"cameras that saw them (against {self.on_mesh} on it)")
        if self.around >= 10 and self.on_around < MIN_SHARE_AROUND * self.around:
            return (f"only {self.on_around} of the {self.around} 3D points around it lie on it "
                    f"(within {self.tolerance:.3g} model units)")
        return None


def _in_view(points, cam):
    """(N,) bool: points (N, 3) in front of the camera (a contract camera dict) and inside its
    image. The lens is taken as a pinhole: distortion moves points by pixels, and far outside
    the field its polynomial folds them back in."""
    pose = np.asarray(cam["world_from_camera"], dtype=np.float64)
    # a point at z ≈ 0 divides to inf (or past float64), which reads as "not in view"
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        local = (points - pose[:3, 3]) @ pose[:3, :3]
        z = local[:, 2]
        u = cam["fx"] * local[:, 0] / z + cam["cx"]
        v = cam["fy"] * local[:, 1] / z + cam["cy"]
    return (z > 0) & (u >= -0.5) & (u <= cam["width"] - 0.5) & (v >= -0.5) & \
        (v <= cam["height"] - 0.5)


def _views_seeing(vertices, cameras):
    """How many of `cameras` (contract camera dicts) have >= 1% of `vertices` (N, 3) in view."""
    return sum(int(np.count_nonzero(_in_view(vertices, cam)) >= max(1, 0.01 * len(vertices)))
               for cam in cameras)


def require_target_facing_a_camera(mesh, has_normals, cameras, min_cos, path, occluder=None):
    """InputError naming the target's mesh file `path` when no point of `mesh` (a
    trimesh.Trimesh; its corners and face centres) is in view of one of `cameras` (contract
    camera dicts), with its normal within arccos(min_cos) of the way to that camera and, when
    `occluder` (a capture.MeshIntersector of the object) is given, not hidden behind it: extract
    could take no pixel of it. The normals are extract's: the file's vertex normals when it has
    them (has_normals), else the faces'."""
    if has_normals:
        points, normals = np.asarray(mesh.vertices), np.asarray(mesh.vertex_normals)
    else:
        face_normals = np.asarray(mesh.face_normals)
        points = np.concatenate([np.asarray(mesh.triangles).reshape(-1, 3),
                                 np.asarray(mesh.triangles_center)])
        normals = np.concatenate([np.repeat(face_normals, 3, axis=0), face_normals])
    for cam in cameras:
        to_camera = np.asarray(cam["world_from_camera"], dtype=np.float64)[:3, 3] - points
        facing = (np.einsum("ij,ij->i", normals, to_camera)
                  >= min_cos * np.linalg.norm(to_camera, axis=1))
        usable = facing & _in_view(points, cam)
        if occluder is not None and np.any(usable):
            usable[usable] = ~_hidden_behind(occluder, points[usable], to_camera[usable])
        if np.any(usable):
            return
    raise InputError(path, f"no photo has this target in view, facing its camera within "
                           f"{np.degrees(np.arccos(min_cos)):.0f}° and not hidden by the object "
                           "(is it in the model's frame, and its faces' normals toward the "
                           "cameras?)")


def _hidden_behind(occluder, points, to_camera):
    """(N,) bool: the object (a capture.MeshIntersector) blocks the sight line from each point
    (N, 3) to its camera (to_camera (N, 3), from the point), short of the point by more than the
    frame check's tolerance (a card touching the object is not hidden)."""
    return (_sight_gaps(occluder, points, points + to_camera)
            < -TOLERANCE_FRACTION * _diagonal(occluder))


def _diagonal(intersector):
    """The bounding-box diagonal of a capture.MeshIntersector's vertices (model units)."""
    vertices = intersector.vertices
    return float(np.linalg.norm(vertices.max(0) - vertices.min(0)))


def _sight_gaps(intersector, points, centres):
    """(N,) where the sight line from each camera centre (N, 3) toward its point (N, 3) first
    meets the mesh, less the distance to the point: ~0 when it ends on the point, negative when
    the mesh hides the point, inf when the line misses the mesh (and for a point at its centre)."""
    from flashbrdf.capture.geometry import intersect
    sight = points - centres
    length = np.linalg.norm(sight, axis=1)
    gaps = np.full(len(points), np.inf)
    valid = length > 0
    hits = intersect(intersector, centres[valid], sight[valid] / length[valid, None])
    gaps[valid] = hits.distance - length[valid]
    return gaps


def check_mesh_frame(intersector, points, observed_point, observer_centre, cameras):
    """FrameCheck of a mesh against a model.

    intersector: capture.MeshIntersector of the mesh; points (P, 3) 3D points of the model;
    observed_point (M,) int index into points and observer_centre (M, 3): one camera-point
    sight line per row; cameras: contract camera dicts of the photos.
    """
    vertices = intersector.vertices
    diagonal = _diagonal(intersector)
    tolerance = TOLERANCE_FRACTION * diagonal
    rng = np.random.default_rng(0)
    pick = rng.choice(len(vertices), size=min(VERTICES_CHECKED, len(vertices)), replace=False)
    views_seeing = _views_seeing(vertices[pick], cameras)
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    observed_point = np.asarray(observed_point, dtype=np.int64)
    on_point = np.zeros(len(points), dtype=bool)
    hidden_point = np.zeros(len(points), dtype=bool)
    on = hidden = 0
    if len(observed_point):
        gap = _sight_gaps(intersector, points[observed_point], observer_centre)
        on_line, hidden_line = np.abs(gap) <= tolerance, gap < -tolerance
        lines_of = observed_point
        count = np.bincount(lines_of, minlength=len(points))
        on_point = np.bincount(lines_of, on_line, minlength=len(points)) > 0
        # most of its sight lines blocked, none ending on it: one line alone may graze an edge
        hidden_point = ~on_point & (2 * np.bincount(lines_of, hidden_line, minlength=len(points))
                                    >= np.maximum(count, 1)) & (count > 0)
        on = int(np.count_nonzero(on_line))
        hidden = int(np.count_nonzero(hidden_line))
    margin = NEAR_FRACTION * diagonal
    around = np.all((points >= vertices.min(0) - margin) & (points <= vertices.max(0) + margin),
                    axis=1)
    return FrameCheck(points=len(points), on_mesh=int(on_point.sum()),
                      hidden=int(hidden_point.sum()),
                      around=int(around.sum()), on_around=int((on_point & around).sum()),
                      observations=int(len(observed_point)), on_observations=on,
                      hidden_observations=hidden, tolerance=tolerance, views=len(cameras),
                      views_seeing=views_seeing)


def require_mesh_in_frame(check, mesh_path):
    """InputError naming the mesh file when FrameCheck `check` finds it out of the frame."""
    problem = check.problem()
    if problem is not None:
        raise InputError(mesh_path, f"not in the model's frame: {problem}; the mesh must be in "
                                    "the model's coordinates and units (e.g. meshed from the "
                                    "same reconstruction)")
