"""Camera rays in the WORLD frame, one per pixel centre (contract camera conventions).

Pinhole: OpenCV axes (x right, y down, z forward); pixel (u, v) = (column, row), integer values at
pixel centres; u = fx X/Z + cx, v = fy Y/Z + cy.
Orthographic: pixel (u, v) starts at camera-frame ((u - (W-1)/2) s, (v - (H-1)/2) s, 0), along +z.

Lens distortion is handled by computing the exact ray of each *distorted* pixel centre (OpenCV's
iterative undistortPoints), so photos are never resampled: a photo's pixel (v, u) and the ray for
(v, u) describe the same scene point, and the render stage can produce images on the same grid.
"""

import collections
import functools
import threading

import cv2
import numpy as np

# OpenCV stops each point at the tolerance; a wide-angle lens's corners need up to ~200 steps
# of its fixed-point iteration (40 left them pixels off), and only they pay for them
_UNDISTORT_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-10)


def pixel_rays(camera, rows, cols):
    """Rays through the given pixel centres.

    rows, cols: (N,) pixel coordinates (v, u); integers are pixel centres.
    Returns origins (N, 3) and unit directions (N, 3), float64, WORLD frame. Pinhole origins are
    a read-only broadcast of the camera centre (no copy).
    """
    rows = np.asarray(rows, dtype=np.float64).ravel()
    cols = np.asarray(cols, dtype=np.float64).ravel()
    if camera.model == "orthographic":
        s = camera.pixel_size
        local = np.stack([(cols - (camera.width - 1) / 2) * s, (rows - (camera.height - 1) / 2) * s,
                          np.zeros_like(rows)], axis=-1)
        origins = camera.to_world(local)
        directions = np.broadcast_to(camera.forward, origins.shape)
        return origins, directions
    if camera.distortion is None:
        x = (cols - camera.cx) / camera.fx
        y = (rows - camera.cy) / camera.fy
    else:
        pts = np.stack([cols, rows], axis=-1).reshape(-1, 1, 2)
        norm = cv2.undistortPoints(pts, camera.intrinsics, camera.distortion, R=None, P=None,
                                   criteria=_UNDISTORT_CRITERIA).reshape(-1, 2)
        x, y = norm[:, 0], norm[:, 1]
    local = np.stack([x, y, np.ones_like(x)], axis=-1)
    local /= np.linalg.norm(local, axis=-1, keepdims=True)
    directions = camera.to_world(local, point=False)
    origins = np.broadcast_to(camera.centre_world, directions.shape)
    return origins, directions


# Lens maps kept at once, in bytes (the most recently used first; the newest is always kept).
# A capture's views often alternate between a few lenses (sample_data/colmap: two): one kept map
# was rebuilt at every change of lens, half of a 12-view 1.5 MP extraction.
LENS_GRID_CACHE_BYTES = 256 << 20
_lens_grids = collections.OrderedDict()
_lens_grids_lock = threading.Lock()


def _undistorted_grid(width, height, intrinsics, distortion):
    """(2, H, W) float32 normalised (x, y) of every distorted pixel centre, for one set of
    intrinsics (bytes keys). A photogrammetry capture shares its lenses over its views, and the
    iterative undistortion was a third of a 24-MP view's extraction; float32 keeps 3e-8 (4e-4 px
    at f = 7200), as fine as the float32 rays it feeds. Maps are kept up to
    LENS_GRID_CACHE_BYTES (one 24 MP map is 192 MB: then one is kept)."""
    key = (width, height, intrinsics, distortion)
    with _lens_grids_lock:
        grid = _lens_grids.get(key)
        if grid is not None:
            _lens_grids.move_to_end(key)
            return grid
    grid = _compute_undistorted_grid(width, height, intrinsics, distortion)
    with _lens_grids_lock:
        _lens_grids[key] = grid
        while len(_lens_grids) > 1 and (sum(g.nbytes for g in _lens_grids.values())
                                        > LENS_GRID_CACHE_BYTES):
            _lens_grids.popitem(last=False)
    return grid


def _compute_undistorted_grid(width, height, intrinsics, distortion):
    """_undistorted_grid's map, computed (OpenCV's iterative undistortion of every pixel)."""
    k = np.frombuffer(intrinsics).reshape(3, 3)
    d = np.frombuffer(distortion)
    grid = np.empty((2, height, width), np.float32)
    cols = np.arange(width, dtype=np.float64)
    step = max(1, (1 << 20) // width)  # rows a batch: bounds the float64 temporaries
    for r0 in range(0, height, step):
        r1 = min(height, r0 + step)
        pts = np.empty((r1 - r0, width, 2))
        pts[..., 0] = cols
        pts[..., 1] = np.arange(r0, r1)[:, None]
        norm = cv2.undistortPoints(pts.reshape(-1, 1, 2), k, d, R=None, P=None,
                                   criteria=_UNDISTORT_CRITERIA).reshape(r1 - r0, width, 2)
        grid[0, r0:r1], grid[1, r0:r1] = norm[..., 0], norm[..., 1]
    return grid


def _lens_grid(camera):
    """The cached (2, H, W) normalised (x, y) of a distorted pinhole camera's pixel centres."""
    return _undistorted_grid(camera.width, camera.height, camera.intrinsics.tobytes(),
                             np.asarray(camera.distortion, np.float64).tobytes())


def embree_rays(camera, rows, cols, shift):
    """float32 rays for Embree through pixel centres (rows, cols) (N,) int: origins - shift
    (N, 3) and directions (N, 3), WORLD frame, NOT unit length (Embree does not need them unit;
    this is the hot path of extraction, so the float64 work is left to the rays that hit)."""
    rows, cols = np.asarray(rows), np.asarray(cols)
    on_grid = rows.dtype.kind in "iu" and cols.dtype.kind in "iu"  # the cached map's pixels
    if camera.model == "pinhole" and (camera.distortion is None or on_grid):
        rot = camera.rotation.astype(np.float32)   # the hot path: float32 by hand, not to_world
        if camera.distortion is None:
            x = ((np.asarray(cols, np.float32) - np.float32(camera.cx)) / np.float32(camera.fx))
            y = ((np.asarray(rows, np.float32) - np.float32(camera.cy)) / np.float32(camera.fy))
        else:
            grid = _lens_grid(camera)
            flat = rows.astype(np.int64) * camera.width + cols
            x, y = grid[0].ravel()[flat], grid[1].ravel()[flat]
        directions = np.empty((len(x), 3), dtype=np.float32)
        directions[:] = rot[:, 2]
        directions += x[:, None] * rot[:, 0]
        directions += y[:, None] * rot[:, 1]
        origins = np.empty_like(directions)
        origins[:] = (camera.centre_world - shift).astype(np.float32)
        return origins, directions
    origins, directions = pixel_rays(camera, rows, cols)
    return (origins - shift).astype(np.float32), directions.astype(np.float32)


def camera_rays(camera):
    """One ray per pixel centre of `camera`.

    Returns origins (H, W, 3) and unit directions (H, W, 3), float64, WORLD frame.
    """
    rows, cols = np.mgrid[0:camera.height, 0:camera.width]
    origins, directions = pixel_rays(camera, rows, cols)
    shape = (camera.height, camera.width, 3)
    return origins.reshape(shape), directions.reshape(shape)


def view_directions(camera, points, rows=None, cols=None):
    """Unit directions from surface points toward the camera (omega_o), WORLD frame.

    points: (N, 3) world points, or None (then rows/cols give the pixels: the reversed pixel rays,
    which is exact for orthographic cameras and for points on the pixel's own ray).
    """
    if points is None:
        return -pixel_rays(camera, rows, cols)[1]
    points = np.asarray(points, dtype=np.float64)
    if camera.model == "orthographic":
        return np.broadcast_to(-camera.forward, points.shape).copy()
    w = camera.centre_world - points
    return w / np.linalg.norm(w, axis=-1, keepdims=True)


def project_points(camera, points):
    """Project WORLD points to pixel coordinates.

    points: (N, 3). Returns (N, 2) float64 (u, v) = (column, row), with lens distortion applied;
    depth (N,) camera-frame z (points behind a pinhole camera get z <= 0).
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    local = camera.to_camera(points)
    z = local[:, 2]
    if camera.model == "orthographic":
        s = camera.pixel_size
        uv = np.stack([local[:, 0] / s + (camera.width - 1) / 2,
                       local[:, 1] / s + (camera.height - 1) / 2], axis=-1)
        return uv, z
    if camera.distortion is None:
        with np.errstate(divide="ignore", invalid="ignore"):
            uv = np.stack([camera.fx * local[:, 0] / z + camera.cx,
                           camera.fy * local[:, 1] / z + camera.cy], axis=-1)
        return uv, z
    uv, _ = cv2.projectPoints(local.reshape(-1, 1, 3), np.zeros(3), np.zeros(3),
                              camera.intrinsics, camera.distortion)
    return uv.reshape(-1, 2), z


def pixel_box(camera, bounds, margin=2):
    """Pixel rectangle that can see an axis-aligned WORLD box: rays outside it cannot hit.

    bounds: (2, 3) [min, max] corners. Returns (row0, row1, col0, col1), half-open, clipped to
    the image; the whole image when the box straddles a pinhole camera's z = 0 plane. The
    projection of a box is the convex hull of its projected corners (perspective and affine maps
    keep convexity). Through a distorted lens that holds before the distortion: the box is the
    pixels whose undistorted centres (the cached lens grid the rays are built from) fall in the
    corners' undistorted bounding rectangle.
    """
    whole = (0, camera.height, 0, camera.width)
    lo, hi = np.asarray(bounds, dtype=np.float64)
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                        for z in (lo[2], hi[2])])
    uv, z = project_points(camera, corners)
    if camera.model == "pinhole" and np.any(z <= 1e-9):
        return whole
    if camera.model == "orthographic" and np.all(z < 0):
        return (0, 0, 0, 0)
    clip = lambda v, top: int(min(max(v, 0), top))  # noqa: E731
    if camera.model == "pinhole" and camera.distortion is not None:
        local = camera.to_camera(corners)
        normalised = local[:, :2] / local[:, 2:]
        (x0, y0), (x1, y1) = normalised.min(0), normalised.max(0)
        x, y = _lens_grid(camera)
        box = mask_box((x >= x0) & (x <= x1) & (y >= y0) & (y <= y1), margin)
        return (0, 0, 0, 0) if box is None else box
    c0, r0 = np.floor(uv.min(0)) - margin
    c1, r1 = np.ceil(uv.max(0)) + margin + 1
    return (clip(r0, camera.height), clip(r1, camera.height), clip(c0, camera.width),
            clip(c1, camera.width))


def mask_box(mask, margin=0):
    """(row0, row1, col0, col1), half-open ints: the smallest box holding every True pixel of
    mask (H, W) bool, grown by margin pixels and cut to the frame; None when none is True."""
    rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    if not rows.size:
        return None
    height, width = mask.shape
    return (int(max(rows[0] - margin, 0)), int(min(rows[-1] + margin + 1, height)),
            int(max(cols[0] - margin, 0)), int(min(cols[-1] + margin + 1, width)))


def mesh_pixels(camera, vertices, faces, cell_px=8):
    """The pixels whose ray can hit a face of the mesh: rows, cols (N,) int64, row-major.

    First the pixels that can see the mesh's bounding box (pixel_box). Then, in undistorted
    pixel coordinates (u = fx X/Z + cx for a pinhole, before the lens; the contract's u for an
    orthographic camera), a face projects inside the bounding rectangle of its corners: cells
    of cell_px pixels touched by some face's rectangle, and the cells next to them (for float32
    rays), are marked. The frame is cut into blocks of cell_px x cell_px pixels, and a block is
    traced whole when the rectangle its pixels' undistorted centres span (the cached lens grid
    the rays are built from) meets a marked cell. Every hit is kept, and the rays that could
    only miss (two thirds of a box the object fills loosely) are never cast. When the mesh is
    not wholly in front of a pinhole camera, or the lens maps the box far beyond the frame,
    every pixel of the box is returned. vertices (V, 3) WORLD; faces (F, 3) int.
    """
    vertices = np.asarray(vertices, np.float64)
    box = pixel_box(camera, np.stack([vertices.min(0), vertices.max(0)]))
    r0, r1, c0, c1 = box
    if r1 <= r0 or c1 <= c0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    found = _cell_pixels(camera, vertices, faces, box, cell_px)
    return box_pixels(box) if found is None else found


def box_pixels(box):
    """Every pixel of box (row0, row1, col0, col1), half-open: rows, cols (N,) int64, row-major."""
    r0, r1, c0, c1 = box
    rows, cols = np.divmod(np.arange((r1 - r0) * (c1 - c0), dtype=np.int64), max(c1 - c0, 1))
    return rows + r0, cols + c0


def _cell_pixels(camera, vertices, faces, box, cell_px):
    """mesh_pixels' pixels within box, or None (trace the whole box): a face reaches behind a
    pinhole camera, or the cells would far outnumber the blocks. A summed-area table of the
    marked cells answers each block in four look-ups: no per-pixel work before the rays."""
    r0, r1, c0, c1 = box
    faces = np.asarray(faces)
    local = camera.to_camera(vertices)
    if camera.model == "orthographic":
        u = local[:, 0] / camera.pixel_size + (camera.width - 1) / 2
        v = local[:, 1] / camera.pixel_size + (camera.height - 1) / 2
    else:
        if np.any(local[faces, 2] <= 1e-9):
            return None
        u = camera.fx * local[:, 0] / local[:, 2] + camera.cx
        v = camera.fy * local[:, 1] / local[:, 2] + camera.cy
    # blocks on one grid over the frame (so that a lens' block extents are cached once)
    block_rows = slice(r0 // cell_px, -(-r1 // cell_px))
    block_cols = slice(c0 // cell_px, -(-c1 // cell_px))
    foot_lo, foot_hi = (f[:, block_rows, block_cols] for f in _block_footprints(camera, cell_px))
    used = np.zeros(len(u), bool)
    used[faces.ravel()] = True
    # the cell grid spans what both the blocks and the faces reach: a lens' grid can hold far
    # values where its undistortion did not converge
    lo = (max(float(foot_lo[0].min()), float(u[used].min())),
          max(float(foot_lo[1].min()), float(v[used].min())))
    hi = (min(float(foot_hi[0].max()), float(u[used].max())),
          min(float(foot_hi[1].max()), float(v[used].max())))
    if hi[0] < lo[0] or hi[1] < lo[1]:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    n_u, n_v = (int((hi[k] - lo[k]) // cell_px) + 1 for k in range(2))
    if n_u * n_v > 4 * foot_lo[0].size + 4096:
        return None
    # cells per vertex (clipped one past the grid on each side, so that a face beyond it stays
    # beyond), then each face's cell rectangle from its corners' cells: int32 gathers
    cell_u = np.clip(np.floor((u - lo[0]) / cell_px), -1, n_u).astype(np.int32)
    cell_v = np.clip(np.floor((v - lo[1]) / cell_px), -1, n_v).astype(np.int32)
    corner_u, corner_v = cell_u[faces], cell_v[faces]
    start_u, stop_u = corner_u.min(1), corner_u.max(1) + 1
    start_v, stop_v = corner_v.min(1), corner_v.max(1) + 1
    seen = (stop_u > 0) & (start_u < n_u) & (stop_v > 0) & (start_v < n_v)
    start = np.stack([np.maximum(start_u[seen], 0), np.maximum(start_v[seen], 0)], axis=1)
    stop = np.stack([np.minimum(stop_u[seen], n_u), np.minimum(stop_v[seen], n_v)], axis=1)
    start, stop = start.astype(np.int64), stop.astype(np.int64)
    # each face's cell rectangle as +1/-1 corners of a 2D difference array: one pass for all
    corners = np.concatenate([start[:, 1] * (n_u + 1) + start[:, 0],
                              start[:, 1] * (n_u + 1) + stop[:, 0],
                              stop[:, 1] * (n_u + 1) + start[:, 0],
                              stop[:, 1] * (n_u + 1) + stop[:, 0]])
    signs = np.repeat(np.array([1.0, -1.0, -1.0, 1.0]), len(start))
    counts = np.bincount(corners, weights=signs, minlength=(n_v + 1) * (n_u + 1))
    marked = np.cumsum(np.cumsum(counts.reshape(n_v + 1, n_u + 1), 0), 1)[:n_v, :n_u] > 0.5
    marked = cv2.dilate(marked.view(np.uint8), np.ones((3, 3), np.uint8))
    table = np.zeros((n_v + 1, n_u + 1), np.int64)  # summed-area table of the marked cells
    table[1:, 1:] = np.cumsum(np.cumsum(marked, 0), 1)
    first = [np.clip(((foot_lo[k] - lo[k]) // cell_px).astype(np.int64), 0, n - 1)
             for k, n in ((0, n_u), (1, n_v))]
    last = [np.clip(((foot_hi[k] - lo[k]) // cell_px).astype(np.int64), 0, n - 1) + 1
            for k, n in ((0, n_u), (1, n_v))]
    marked_in_footprint = (table[last[1], last[0]] - table[first[1], last[0]]
                           - table[last[1], first[0]] + table[first[1], first[0]])
    # a block wholly past the grid (beyond every face) would read the edge cells: it sees none
    beyond = ((foot_hi[0] < lo[0]) | (foot_lo[0] > hi[0]) | (foot_hi[1] < lo[1])
              | (foot_lo[1] > hi[1]))
    blocks = (marked_in_footprint > 0) & ~beyond
    top, left = block_rows.start * cell_px, block_cols.start * cell_px
    inside = np.ascontiguousarray(np.repeat(np.repeat(blocks, cell_px, 0), cell_px, 1)[
        r0 - top:r1 - top, c0 - left:c1 - left])
    rows, cols = np.divmod(np.flatnonzero(inside), c1 - c0)
    return rows + r0, cols + c0


def _block_footprints(camera, cell_px):
    """Undistorted pixel coordinates spanned by each cell_px block of the frame: lo, hi
    (2, blocks_v, blocks_u) as (u, v). Without a lens, the blocks' own pixel ranges; through
    one, the exact extent of the block's pixels in the cached lens grid (not its corners': where
    the lens' undistortion does not converge, the grid is not smooth)."""
    blocks_v, blocks_u = -(-camera.height // cell_px), -(-camera.width // cell_px)
    if camera.model != "pinhole" or camera.distortion is None:
        starts_v, starts_u = np.meshgrid(np.arange(blocks_v) * cell_px,
                                         np.arange(blocks_u) * cell_px, indexing="ij")
        lo = np.stack([starts_u, starts_v]).astype(np.float64)
        hi = np.stack([np.minimum(starts_u + cell_px - 1, camera.width - 1),
                       np.minimum(starts_v + cell_px - 1, camera.height - 1)]).astype(np.float64)
        return lo, hi
    return _lens_block_extents(camera.width, camera.height, camera.intrinsics.tobytes(),
                               np.asarray(camera.distortion, np.float64).tobytes(), cell_px)


@functools.lru_cache(maxsize=4)  # small (1/64 of a map): one per lens of a capture
def _lens_block_extents(width, height, intrinsics, distortion, cell_px):
    """_block_footprints through a lens: min and max of the lens grid over each block, in
    undistorted pixel coordinates, once per lens (one pass over the cached grid)."""
    k = np.frombuffer(intrinsics).reshape(3, 3)
    grid = _undistorted_grid(width, height, intrinsics, distortion)
    blocks_v, blocks_u = -(-height // cell_px), -(-width // cell_px)
    lo, hi = [], []
    for axis, (focal, centre) in enumerate(((k[0, 0], k[0, 2]), (k[1, 1], k[1, 2]))):
        padded = np.pad(grid[axis], ((0, blocks_v * cell_px - height),
                                     (0, blocks_u * cell_px - width)), mode="edge")
        padded = padded.reshape(blocks_v, cell_px, blocks_u, cell_px)
        lo.append(padded.min(axis=(1, 3)).astype(np.float64) * focal + centre)
        hi.append(padded.max(axis=(1, 3)).astype(np.float64) * focal + centre)
    return np.stack(lo), np.stack(hi)
