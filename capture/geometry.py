"""Known geometry, part 1: a mesh traced with Embree (embreex). (Normal maps: capture.normal_map.)

Shading normals (contract): the file's vertex normals interpolated barycentrically and
renormalised, or the face normal when the file has none. Normals are kept as the file gives them,
never flipped toward the viewer: a surface seen from its back shows up as cos(theta_o) < 0, which
slice extraction rejects and reports ("backfacing"), so a wrongly wound mesh is diagnosed, not
silently "fixed".

Embree works in float32. Vertices no face uses are dropped on load, the scene is re-centred on
the median of the vertices (a stray far piece does not move it), and hit points are recomputed
in float64 from Embree's barycentrics on the original vertices, so points sit on the triangle to
float64 precision. Shadow rays start a small distance (1e-4 x the diagonal of the vertices'
central 99%) along the ray, which clears float32 self-hits at cos(theta_i) >= 0.01.
"""

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from embreex import rtcore_scene
from embreex.mesh_construction import TriangleMesh

from flashbrdf.files.errors import InputError, no_file
from flashbrdf.capture.camera import embree_rays, mesh_pixels
from flashbrdf.capture.scene import Scene
from flashbrdf.capture.scene_fields import MAX_COORDINATE, beyond_coordinates

_CHUNK = 1 << 21  # rays per Embree call: bounds temporary memory to ~100 MB
_SHADOW_OFFSET = 1e-4  # x the diagonal of the vertices' central 99% (MeshIntersector.scale)


@dataclass(frozen=True, eq=False)
class Hits:
    """First hits of a batch of rays; shapes follow the rays' leading shape (...).

    hit (...) bool; points (..., 3) world; normals (..., 3) unit shading normals (0 where missed);
    face (...) int face index, -1 where missed; distance (...) along the unit ray (inf if missed;
    Embree's float32 value: points are the precise float64 hit positions).
    """
    hit: np.ndarray
    points: np.ndarray
    normals: np.ndarray
    face: np.ndarray
    distance: np.ndarray


@dataclass(frozen=True, eq=False)
class Surface:
    """The visible surface under a set of pixels (only pixels that see the object).

    rows, cols (N,) int pixel coordinates; points (N, 3) world or None (normal-map geometry has no
    depth); normals (N, 3) unit world shading normals; view_dirs (N, 3) unit world directions
    toward the camera (omega_o); face (N,) int or None.
    """
    rows: np.ndarray
    cols: np.ndarray
    points: np.ndarray
    normals: np.ndarray
    view_dirs: np.ndarray
    face: np.ndarray = None


def load_mesh(path):
    """Read a mesh file (any format trimesh reads) as one trimesh.Trimesh, unprocessed.

    Returns (mesh, has_vertex_normals). InputError if missing, unreadable or without faces.
    """
    # trimesh costs 1.4 s to import (python -X importtime, 2 cores), paid only by mesh scenes
    import trimesh
    path = Path(path)
    if not path.is_file():
        raise no_file(path, "mesh file", "mesh file not found")
    if path.suffix.lower() == ".ply":
        _check_ascii_ply_length(path)
    try:
        loaded = trimesh.load(str(path), process=False)
    except ImportError as err:  # a loader's optional dependency, often for a format it is not
        raise InputError(path, "cannot read mesh: trimesh cannot decode it (corrupt, or of a "
                               f"kind that needs {err.name or 'a module'}, not installed)") \
            from None
    except Exception as err:  # trimesh raises many types for bad files
        raise InputError(path, f"cannot read mesh: {err}") from None
    # loaders hand file normals to the constructor, which caches them (force="mesh",
    # Scene.dump() and Trimesh.copy() drop that cache, so read it before anything else touches
    # the mesh)
    parts = ([loaded] if isinstance(loaded, trimesh.Trimesh) else
             _scene_parts(loaded, path) if isinstance(loaded, trimesh.Scene) else [])
    parts = [g for g in parts if len(g.faces)]
    if not parts:
        raise InputError(path, "no triangles in the mesh")
    with_normals = ["vertex_normals" in g._cache.cache for g in parts]
    has_normals = any(with_normals)
    if len(parts) == 1:
        mesh = parts[0]
    else:
        # a part without normals is shaded with its face normals (the contract's fallback), the
        # others with theirs: one part without them turned the whole object faceted
        parts = [g if given or not has_normals else _faceted(g)
                 for g, given in zip(parts, with_normals)]
        offsets = np.cumsum([0] + [len(g.vertices) for g in parts[:-1]])
        mesh = trimesh.Trimesh(
            np.concatenate([g.vertices for g in parts]),
            np.concatenate([g.faces + o for g, o in zip(parts, offsets)]),
            vertex_normals=(np.concatenate([g.vertex_normals for g in parts])
                            if has_normals else None), process=False)
    faces, count = np.asarray(mesh.faces), len(mesh.vertices)
    if faces.min() < 0 or faces.max() >= count:
        bad = int(faces.min() if faces.min() < 0 else faces.max())
        raise InputError(path, f"a face refers to vertex {bad}, but the mesh has {count} vertices")
    mesh = _referenced_only(mesh, has_normals)
    if not np.all(np.isfinite(mesh.vertices)):
        raise InputError(path, "mesh has non-finite vertex coordinates")
    odd = beyond_coordinates(mesh.vertices)
    if odd is not None:
        raise InputError(path, f"a vertex coordinate {odd:.6g} is beyond ±{MAX_COORDINATE:g} (rays "
                               "are 32-bit floats)")
    return mesh, has_normals


def _faceted(mesh):
    """The mesh with each face on vertices of its own, whose normals are the face's: interpolated
    vertex normals then shade it with face normals."""
    import trimesh
    faces = np.asarray(mesh.faces)
    return trimesh.Trimesh(np.asarray(mesh.vertices)[faces].reshape(-1, 3),
                           np.arange(faces.size).reshape(-1, 3),
                           vertex_normals=np.repeat(mesh.face_normals, 3, axis=0), process=False)


def _referenced_only(mesh, has_normals):
    """The mesh without the vertices no face uses (photogrammetry leaves them after cleaning):
    they would widen the box of pixels traced and weigh in the float32 frame's centre. Not
    trimesh's remove_unreferenced_vertices: it drops the file's vertex normals for recomputed
    ones."""
    import trimesh
    faces = np.asarray(mesh.faces)
    used = np.unique(faces)
    if len(used) == len(mesh.vertices):
        return mesh
    new_index = np.zeros(len(mesh.vertices), dtype=np.int64)
    new_index[used] = np.arange(len(used))
    return trimesh.Trimesh(np.asarray(mesh.vertices)[used], new_index[faces],
                           vertex_normals=(np.asarray(mesh.vertex_normals)[used]
                                           if has_normals else None), process=False)


def _check_ascii_ply_length(path):
    """InputError naming an ASCII PLY whose body holds more or fewer data lines than its header's
    elements declare (a truncated or appended file): trimesh reads such a file silently, and a
    binary PLY of the same damage is already refused by its length. No-op for binary PLY."""
    with open(path, "rb") as f:
        if f.readline().strip() != b"ply":
            return                                 # trimesh names what it is not
        declared, ascii_format = 0, False
        for line in f:
            words = line.split()
            if words[:2] == [b"format", b"ascii"]:
                ascii_format = True
            elif words[:1] == [b"element"] and len(words) == 3 and words[2].isdigit():
                declared += int(words[2])
            elif words[:1] == [b"end_header"]:
                break
        else:
            return
        if not ascii_format:
            return
        held = sum(1 for line in f if line.strip())
    if held != declared:
        raise InputError(path, f"ASCII PLY header declares {declared} vertex/face lines, the file "
                               f"holds {held} (truncated or appended)")


def _scene_parts(scene, path):
    """The triangle meshes of a trimesh.Scene (glTF, GLB, multi-object files) placed by the scene
    graph, as Scene.dump() places them, but keeping each file's vertex normals (transformed by the
    inverse transpose of the node's matrix and renormalised), which dump() drops."""
    import trimesh
    parts = []
    for node in scene.graph.nodes_geometry:
        transform, name = scene.graph[node]
        geometry = scene.geometry[name]
        if not isinstance(geometry, trimesh.Trimesh):
            continue
        normals = geometry._cache.cache.get("vertex_normals")
        part = geometry.copy()
        part.apply_transform(transform)
        if normals is not None:
            linear = transform[:3, :3]
            if not np.all(np.isfinite(linear)) or abs(np.linalg.det(linear)) < 1e-12:
                raise InputError(path, f"scene node {node!r} has a singular transform")
            normals = np.asarray(normals, dtype=np.float64) @ np.linalg.inv(linear)
            normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-300)
            part = trimesh.Trimesh(part.vertices, part.faces, vertex_normals=normals,
                                   process=False)
        parts.append(part)
    return parts


class MeshIntersector:
    """Embree (embreex) ray queries on a trimesh mesh. Build once, query many times.

    mesh: trimesh.Trimesh (world units); use_vertex_normals: interpolate mesh.vertex_normals for
    shading (pass load_mesh's has_vertex_normals), else use face normals.
    """

    def __init__(self, mesh, use_vertex_normals=None):
        self.mesh = mesh
        if use_vertex_normals is None:
            use_vertex_normals = "vertex_normals" in mesh._cache.cache
        self.vertices = np.asarray(mesh.vertices, dtype=np.float64)
        self.faces = np.asarray(mesh.faces, dtype=np.int64)
        self.face_normals = np.asarray(mesh.face_normals, dtype=np.float64)
        self.vertex_normals = (np.asarray(mesh.vertex_normals, dtype=np.float64)
                               if use_vertex_normals else None)
        # The float32 frame is centred, and the shadow offset scaled, on the bulk of the vertices
        # (median, central 99%), not the bounding box: a few triangles kept far from the object
        # (a Poisson skirt, a stray piece) would otherwise move the object's coordinates to where
        # float32 keeps ~1e-4 of its size and push shadow rays' starts off it.
        self.centre = np.median(self.vertices, axis=0)
        relative = (self.vertices - self.centre).astype(np.float32)
        # per-face corners (relative to the centre) and corner normals, float32: one gather per
        # hit instead of two, at half the memory traffic (float32 is ~1e-7 of the mesh size)
        self.corners = relative[self.faces]  # (F, 3, 3)
        self.corner_normals = (None if self.vertex_normals is None
                               else self.vertex_normals[self.faces].astype(np.float32))
        low, high = np.percentile(self.vertices, [0.5, 99.5], axis=0)
        self.scale = float(np.linalg.norm(high - low)) or 1.0
        self._scene = rtcore_scene.EmbreeScene()
        TriangleMesh(scene=self._scene, vertices=relative, indices=self.faces.astype(np.int32))

    def embree_first_hit(self, origins, directions):
        """Embree's own first-hit query, nothing else: origins (N, 3) float32 already shifted by
        -centre, directions (N, 3) float32. Returns embreex's dict: primID (N,) (-1 = miss),
        u, v (barycentrics), tfar, Ng."""
        return self._scene.run(origins, directions, output=1)

    def raw_first_hit(self, origins, directions):
        """First-hit query for world-frame float64 rays (N, 3): see embree_first_hit."""
        o = (np.asarray(origins, dtype=np.float64) - self.centre).astype(np.float32)
        return self.embree_first_hit(o, np.asarray(directions, dtype=np.float32))

    def is_convex(self):
        return is_convex(self.mesh)


def scene_intersector(scene):
    """MeshIntersector for scene.geometry.mesh (InputError if the scene uses a normal map)."""
    if scene.geometry.mesh is None:
        raise InputError(f"{scene.json_path}: geometry", "has no mesh (it is a normal map)")
    mesh, has_normals = load_mesh(scene.geometry.mesh)
    return MeshIntersector(mesh, use_vertex_normals=has_normals)


def _as_intersector(target):
    """MeshIntersector from a MeshIntersector, a trimesh.Trimesh or a capture.Scene."""
    if isinstance(target, MeshIntersector):
        return target
    if isinstance(target, Scene):
        return scene_intersector(target)
    return MeshIntersector(target)


def intersect(target, origins, directions):
    """First hit of each ray with the mesh.

    target: MeshIntersector (build it once and reuse it), trimesh.Trimesh or capture.Scene;
    origins, directions: (..., 3) world, directions unit. Returns Hits with the rays' leading
    shape. No Python loop over rays (chunked Embree calls).
    """
    mi = _as_intersector(target)
    directions = np.asarray(directions, dtype=np.float64)
    lead = directions.shape[:-1]
    d = directions.reshape(-1, 3)
    o = np.broadcast_to(np.asarray(origins, dtype=np.float64), directions.shape).reshape(-1, 3)
    n = len(d)
    face = np.full(n, -1, dtype=np.int64)
    bary = np.zeros((n, 2), dtype=np.float32)
    distance = np.full(n, np.inf)
    for s in range(0, n, _CHUNK):
        r = mi.raw_first_hit(o[s:s + _CHUNK], d[s:s + _CHUNK])
        face[s:s + _CHUNK] = r["primID"]
        bary[s:s + _CHUNK, 0], bary[s:s + _CHUNK, 1] = r["u"], r["v"]
        distance[s:s + _CHUNK] = r["tfar"]  # unit directions, unscaled scene: world units
    hit = face >= 0
    distance[~hit] = np.inf
    points = np.zeros((n, 3))
    normals = np.zeros((n, 3))
    f = face[hit]
    weights = _barycentric_weights(bary[hit, 0], bary[hit, 1])
    points[hit] = _hit_points(mi, f, weights)
    normals[hit] = _shading_normals(mi, f, weights)
    return Hits(hit.reshape(lead), points.reshape(lead + (3,)), normals.reshape(lead + (3,)),
                face.reshape(lead), distance.reshape(lead))


def _barycentric_weights(u, v):
    """(M, 3) float32 corner weights from Embree's (u, v) (M,): hit = w0 p0 + u p1 + v p2."""
    u = np.asarray(u, dtype=np.float32).reshape(-1)
    v = np.asarray(v, dtype=np.float32).reshape(-1)
    w = np.empty((len(u), 3), dtype=np.float32)
    w[:, 0], w[:, 1], w[:, 2] = 1 - u - v, u, v
    return w


def _interpolate(corner_values, face, weights):
    """(M, 3) = sum_k weights[:, k] corner_values[face, k]."""
    # np.take: several times faster than fancy indexing for row gathers
    return np.einsum("mk,mkj->mj", weights, np.take(corner_values, face, axis=0))


def _hit_points(mi, face, weights):
    """(M, 3) float64 world hit points."""
    return _interpolate(mi.corners, face, weights).astype(np.float64) + mi.centre


def _shading_normals(mi, face, weights, dtype=np.float64):
    """(M, 3) unit shading normals (dtype) at barycentric weights (M, 3) on faces (M,)."""
    if mi.corner_normals is None:
        return np.take(mi.face_normals, face, axis=0).astype(dtype, copy=False)
    n = _interpolate(mi.corner_normals, face, weights).astype(dtype, copy=False)
    length = np.sqrt(np.einsum("ij,ij->i", n, n))
    ok = length > 1e-6
    n /= np.where(ok, length, 1.0)[:, None]
    if not ok.all():  # degenerate interpolated normal: fall back to the face's
        n[~ok] = mi.face_normals[face[~ok]]
    return n


def occluded(target, points, directions, max_dist=None):
    """Whether the segment from each point along `directions` hits the mesh (shadow rays).

    points, directions: (..., 3) world, directions unit; max_dist: (...) or scalar, the length
    of the segment (the distance to a point light), None for a directional light (unbounded).
    Returns (...) bool. Rays start 1e-4 x the mesh's size (MeshIntersector.scale) along the ray
    to clear self-hits.
    """
    mi = _as_intersector(target)
    directions = np.asarray(directions, dtype=np.float64)
    lead = directions.shape[:-1]
    d = directions.reshape(-1, 3)
    p = np.broadcast_to(np.asarray(points, dtype=np.float64), directions.shape).reshape(-1, 3)
    eps = _SHADOW_OFFSET * mi.scale
    o = p + eps * d
    n = len(d)
    if max_dist is None:
        far = np.full(n, 1e30, dtype=np.float32)
    else:
        far = np.broadcast_to(np.asarray(max_dist, dtype=np.float64), lead).reshape(-1)
        far = np.maximum(far - 2 * eps, 0).astype(np.float32)
    blocked = np.zeros(n, dtype=bool)
    for s in range(0, n, _CHUNK):
        oc = (o[s:s + _CHUNK] - mi.centre).astype(np.float32)
        r = mi._scene.run(oc, d[s:s + _CHUNK].astype(np.float32), dists=far[s:s + _CHUNK].copy(),
                          query="OCCLUDED")
        blocked[s:s + _CHUNK] = np.asarray(r) != -1
    return blocked.reshape(lead)


def is_convex(mesh):
    """True when the mesh is convex (trimesh's test), so no point can shadow another front-facing
    point: shadow rays can be skipped. Accepts a MeshIntersector too."""
    mesh = mesh.mesh if isinstance(mesh, MeshIntersector) else mesh
    return bool(mesh.is_convex)


def surface_from_mesh(target, camera, pixel_mask=None):
    """Trace the camera's pixels (those in pixel_mask (H, W) bool, default all) against the mesh.

    Returns a Surface holding only the pixels whose ray hits. Only pixels whose ray can reach a
    face are traced (capture.mesh_pixels): the others cannot hit.
    """
    mi = _as_intersector(target)
    rows, cols = mesh_pixels(camera, mi.mesh.vertices, mi.mesh.faces)
    if pixel_mask is not None:
        wanted = pixel_mask[rows, cols]
        rows, cols = rows[wanted], cols[wanted]
    return surface_at_pixels(mi, camera, rows, cols)


def surface_sample(target, camera, count):
    """A Surface of up to `count` of the camera's pixels whose ray can reach a face, evenly
    spaced through them (mesh_pixels' order): enough to tell whether the camera sees the object,
    or what share of its pixels carry a label, without tracing the whole view."""
    mi = _as_intersector(target)
    rows, cols = mesh_pixels(camera, mi.mesh.vertices, mi.mesh.faces)
    step = max(1, len(rows) // count)
    return surface_at_pixels(mi, camera, rows[::step], cols[::step])


def surface_at_pixels(target, camera, rows, cols, dtype=np.float64):
    """Trace the rays of pixels (rows, cols) (N,) int against the mesh; a Surface of the hits.

    The hot path of extraction: float32 rays straight into Embree, geometry only for the rays
    that hit. Points are float64 world; normals and view directions are `dtype` (extraction
    asks for float32: ~1e-7 rad, far finer than any theta_h bin).
    """
    mi = _as_intersector(target)
    rows, cols = np.asarray(rows), np.asarray(cols)
    origins, directions = embree_rays(camera, rows, cols, mi.centre)
    r = mi.embree_first_hit(origins, directions)
    face = r["primID"]
    hit = face >= 0
    rows, cols = np.compress(hit, rows), np.compress(hit, cols)
    face = np.compress(hit, face).astype(np.int64)
    weights = _barycentric_weights(np.compress(hit, r["u"]), np.compress(hit, r["v"]))
    relative = _interpolate(mi.corners, face, weights)  # float32, relative to mi.centre
    points = relative.astype(np.float64) + mi.centre
    normals = _shading_normals(mi, face, weights, dtype)
    if camera.model == "orthographic":
        view = np.tile(-camera.forward.astype(dtype), (len(points), 1))
    else:
        view = (camera.centre_world - mi.centre).astype(np.float32) - relative
        view = view.astype(dtype, copy=False)
        view /= np.sqrt(np.einsum("ij,ij->i", view, view))[:, None]
    return Surface(rows, cols, points, normals, view, face)
