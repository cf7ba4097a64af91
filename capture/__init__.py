"""capture: from a capture folder on disk to calibrated, linear radiance.

Takes a `scene.json` folder (see ../shared/spec/INTERFACES.md): camera, geometry and photos.
Gives a validated scene description, float32 linear-RGB photos with per-pixel "usable" masks
(ambient already subtracted from flash photos), camera rays, and ray-geometry hits (Embree).

Public API (plain numpy arrays in and out; WORLD frame unless said otherwise):
  load_scene(scene_dir) -> Scene(folder, camera, geometry, photos, json_path)
  photo_labels(photos, folder) -> {photo.index: stem, or path where two photos share a stem}
  camera_rays(camera) -> origins (H, W, 3), directions (H, W, 3)
  pixel_rays(camera, rows, cols) -> origins (N, 3), directions (N, 3)
  view_directions(camera, points, rows=None, cols=None) -> (N, 3) toward the camera
  project_points(camera, points) -> uv (N, 2), depth (N,)
  load_mesh(path) -> (trimesh.Trimesh, has_vertex_normals)
  MeshIntersector(mesh, use_vertex_normals=None)   # Embree scene, build once
  scene_intersector(scene) -> MeshIntersector for the scene's mesh
  intersect(intersector_mesh_or_scene, origins, directions) -> Hits(hit, points, normals, face,
      distance)
  occluded(mesh_or_intersector, points, directions, max_dist=None) -> (...) bool
  is_convex(mesh_or_intersector) -> bool
  surface_from_mesh(mesh_or_intersector, camera, pixel_mask=None) -> Surface
  surface_at_pixels(mesh_or_intersector, camera, rows, cols) -> Surface (hits only)
  surface_sample(mesh_or_intersector, camera, count) -> Surface of up to count pixels' hits
  pixel_box(camera, bounds) -> (row0, row1, col0, col1): pixels that can see a world box
  mesh_pixels(camera, vertices, faces) -> rows, cols: the pixels whose ray can hit a face
  box_pixels(box) -> rows, cols: every pixel of a (row0, row1, col0, col1) box
  mask_box(mask, margin=0) -> (row0, row1, col0, col1) of its True pixels, or None
  surface_from_normal_map(geometry_or_scene, camera=None, pixel_mask=None) -> Surface (no points)
  load_normal_map(geometry, camera) -> normals_camera (H, W, 3), mask (H, W)
  load_photo(path, encoding=None, saturation=None, shape=None, return_clipped=False)
      -> rgb (H, W, 3) float32 linear, usable (H, W) bool[, clipped (H, W) bool]
  load_brackets(brackets, encoding=None, saturation=None, shape=None, return_clipped=False)
  load_photo_entry(photo, return_clipped=False) -> rgb, usable   # a photos[] entry, unscaled
  load_reference_entry(photo) -> rgb, measured   # what renders are compared against
  photo_exists(photo) -> bool   # a reference photo may be absent: rendered, not compared
  same_view(camera_a, camera_b) -> bool   # one pixel grid, intrinsics and pose
  camera_key(camera) -> hashable           # what same_view compares, exactly
  embree_rays(camera, rows, cols, shift) -> float32 origins - shift, directions (not unit)
  iter_flash_images(scene_or_dir) -> FlashImage(photo, radiance, usable, clipped), one at a time
    (the next decoded in a thread meanwhile)
  load_flash_images(scene_or_dir) -> [FlashImage, ...]
      # ambient removed, divided by scale
  read_float_image(path) -> (H, W, 3) float32 via OpenImageIO
  srgb_to_linear(values) -> linear
"""

from flashbrdf.capture.camera import (box_pixels, camera_rays, embree_rays, mask_box, mesh_pixels,
                                      pixel_box, pixel_rays, project_points, view_directions)
from flashbrdf.capture.geometry import (Hits, MeshIntersector, Surface, intersect, is_convex,
                                        load_mesh, occluded, scene_intersector,
                                        surface_at_pixels, surface_from_mesh, surface_sample)
from flashbrdf.capture.normal_map import load_normal_map, surface_from_normal_map
from flashbrdf.capture.load import (FlashImage, iter_flash_images, load_flash_images,
                                    load_photo_entry, load_reference_entry, photo_exists)
from flashbrdf.capture.photo import load_brackets, load_photo, read_float_image, srgb_to_linear
from flashbrdf.capture.scene import (Camera, Geometry, Light, Photo, Scene, camera_key,
                                     load_scene, photo_labels, same_view)


__all__ = [
    "Camera", "FlashImage", "Geometry", "Hits", "Light", "MeshIntersector", "Photo", "Scene",
    "Surface", "box_pixels", "camera_key", "camera_rays", "embree_rays", "intersect",
    "is_convex", "load_brackets", "iter_flash_images", "load_flash_images", "load_mesh",
    "load_normal_map", "load_photo", "load_photo_entry", "load_reference_entry", "load_scene",
    "mask_box", "mesh_pixels", "photo_exists", "photo_labels", "same_view", "occluded",
    "pixel_box",
    "pixel_rays", "project_points", "read_float_image", "scene_intersector", "srgb_to_linear",
    "surface_at_pixels", "surface_from_mesh", "surface_from_normal_map", "surface_sample",
    "view_directions",
]
