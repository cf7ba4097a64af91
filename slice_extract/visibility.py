"""What a camera sees of the object: its pixels' traced surface (once per camera), the object's
outline and inner occluding contours (left out of the slice: a pose a pixel off puts the
background, or the surface behind, there), and normals at chosen pixels for segmentation.
"""

import cv2
import numpy as np

from flashbrdf import capture


def trace_camera(scene, camera, intersector, chunk):
    """capture.Surface batches of the pixels of `camera` that see the object (every pixel that
    can: usability is each photo's business), the object mask (H, W) bool, and the depth of each
    hit (H, W) float32 (inf off the object; None for normal-map geometry)."""
    mask = np.zeros(camera.shape, dtype=bool)
    if intersector is None:
        surfaces = [capture.surface_from_normal_map(scene.geometry, camera)]
    else:
        surfaces = list(pixel_surfaces(camera, intersector, chunk))
    depth = None if intersector is None else np.full(camera.shape, np.inf, np.float32)
    for surface in surfaces:
        flat = surface.rows * camera.width + surface.cols
        mask.ravel()[flat] = True
        if depth is not None:
            depth.ravel()[flat] = hit_depth(camera, surface.points)
    return surfaces, mask, depth


def pixel_surfaces(camera, intersector, chunk):
    """capture.Surface of the hits, batch by batch of `chunk` pixels, over every pixel of
    `camera` whose ray can hit the mesh (capture.mesh_pixels); float32 directions."""
    rows, cols = capture.mesh_pixels(camera, intersector.mesh.vertices, intersector.mesh.faces)
    for s in range(0, len(rows), chunk):
        yield capture.surface_at_pixels(intersector, camera, rows[s:s + chunk],
                                        cols[s:s + chunk], dtype=np.float32)


def hit_depth(camera, points):
    """Distance (N,) float32 of world points from a pinhole camera's centre, or along an
    orthographic camera's forward axis."""
    offset = points - camera.centre_world
    if camera.model == "orthographic":
        return (offset @ camera.forward).astype(np.float32)
    return np.sqrt(np.einsum("ij,ij->i", offset, offset)).astype(np.float32)


def depth_edge_mask(depth, camera, slope, width_px):
    """(H, W) bool: object pixels within width_px of an inner occluding contour, where the depth
    of neighbouring hits (depth (H, W), inf off the object) jumps more steeply than `slope`
    (depth change per pixel footprint: 20 ~ 87 deg from the view). The outline against the
    background is silhouette_mask's."""
    edge = np.zeros(camera.shape, bool)
    if depth is None or slope <= 0 or width_px <= 0:
        return edge
    box = object_box(np.isfinite(depth), width_px)  # the work is the object's, not the frame's
    if box is None:
        return edge
    depth = depth[box]
    hit = np.isfinite(depth)
    # a pixel's footprint at its depth: depth / f for a pinhole, the pixel size orthographic
    footprint = (np.full(depth.shape, camera.pixel_size, np.float32)
                 if camera.model == "orthographic"
                 else depth / np.float32(max(camera.fx, camera.fy)))
    inner = np.zeros(depth.shape, bool)
    for first, second in (((slice(0, -1), slice(None)), (slice(1, None), slice(None))),
                          ((slice(None), slice(0, -1)), (slice(None), slice(1, None)))):
        with np.errstate(invalid="ignore"):  # inf - inf off the object
            jump = (hit[first] & hit[second]
                    & (np.abs(depth[first] - depth[second])
                       > slope * np.minimum(footprint[first], footprint[second])))
        inner[first] |= jump
        inner[second] |= jump
    if inner.any():
        kernel = np.ones((2 * width_px - 1, 2 * width_px - 1), np.uint8)
        edge[box] = cv2.dilate(inner.view(np.uint8), kernel).astype(bool) & hit
    return edge


def object_box(mask, margin):
    """(rows, cols) slices of capture.mask_box(mask, margin), or None when mask is empty: a
    24-MP photo's object often fills a third of it, and per-pixel work on the box costs a third."""
    box = capture.mask_box(mask, margin)
    return None if box is None else (slice(box[0], box[1]), slice(box[2], box[3]))


def camera_normals(scene, camera, intersector):
    """normals_at(pixels (M,) flat indices) -> (M, 3) float32 shading normals in `camera`'s frame,
    0 where the pixel's ray misses the object. Segmentation asks where the surface can see itself
    (slice_extract.segment.nonconvex_mask) at a subsample of pixels: tracing those again costs
    milliseconds, where a 12-MP normal image kept from the trace cost ~0.7 s and 144 MB on every
    extraction."""
    def normals_at(pixels):
        pixels = np.asarray(pixels, np.int64)
        if intersector is None:
            surface = capture.surface_from_normal_map(scene.geometry, camera)
            image = np.zeros((camera.height * camera.width, 3), np.float32)
            image[surface.rows * camera.width + surface.cols] = surface.normals @ camera.rotation
            return image[pixels]
        unique, back = np.unique(pixels, return_inverse=True)
        rows, cols = np.divmod(unique, camera.width)
        surface = capture.surface_at_pixels(intersector, camera, rows, cols, dtype=np.float32)
        found = np.zeros((len(unique), 3), np.float32)
        found[np.searchsorted(unique, surface.rows * camera.width + surface.cols)] = \
            surface.normals @ camera.rotation
        return found[back]
    return normals_at


def silhouette_mask(object_mask, width_px):
    """(H, W) bool: object pixels within width_px (Chebyshev) of a pixel that sees no object.

    Such pixels mix object and background in any real or filtered image (optics, demosaicing,
    a renderer's reconstruction filter: Mitsuba's default Gaussian puts ~13% of a neighbour's
    light into a pixel, and < 0.1% from two pixels away). The image frame is not an edge.
    """
    edge = np.zeros_like(object_mask)
    box = None if width_px <= 0 else object_box(object_mask, width_px + 1)
    if box is None:
        return edge
    mask = object_mask[box]
    kernel = np.ones((2 * width_px + 1, 2 * width_px + 1), np.uint8)
    inner = cv2.erode(mask.astype(np.uint8), kernel, borderType=cv2.BORDER_REPLICATE)
    edge[box] = mask & ~inner.astype(bool)
    return edge
