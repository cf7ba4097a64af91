"""render: re-render a capture's geometry with a tabulated or analytic BRDF.

Takes a scene (camera, geometry, lights: point, directional, environment map) and a BRDF.
Gives HDR images in the photos' pixel units (Monte Carlo with MIS for environment maps) and image
comparisons (log-CIELAB Delta E, relative RMSE).

Public API (plain numpy arrays; WORLD frame; directions unit (..., 3)):
  EnvMap(pixels, world_from_envmap=None, scale=1.0, compensate=True); EnvMap.from_file(path, ...)
      .radiance(dirs) -> (..., 3); .sample(u (..., 2)) -> dirs, pdf; .pdf(dirs) -> (...)
  read_envmap_pixels(path) -> (H, 2H, 3) float32
  BRDFs: any flashbrdf.brdf.models model (TabulatedBRDF, Lambert, GGX: evaluate/sample/pdf)
  render_point_light(points, normals, view, brdf, light_position, intensity_rgb, occluded=None)
  render_directional_light(points, normals, view, brdf, direction, irradiance_rgb, occluded=None)
  render_envmap(points, normals, view, brdf, envmap, spp=64, seed=0, occluded=None, ...) -> (P, 3)
  (the three renderers take a list of models too: one output each, equal to its render alone,
  the BRDF-independent work done once)
  DiffuseAlbedoMap(base, albedo (H, W, 3), floors (K, 3), camera, faces=None): a per-point
      diffuse albedo on a model or MaterialMap (rho = T_k + A/pi - f_k), for render_scene
  render_scene(scene, brdf, spp=64, seed=0, photos=None, progress=True, geometry=None)
      -> iterator of (photo, image (H, W, 3) float32 in photo units, mask (H, W)); brdf a list:
      a list of images, one per BRDF, each photo rendered once for all
  render_sphere(table, envmap_path, size=128, spp=64, seed=0, ...) -> (size, size, 3) float32
  compare_images(pred, ref, mask=None) -> (metrics dict, delta_e (H, W))
  write_comparison(out_dir, pred, ref, mask=None, ...) -> metrics (compare.json + delta_e.png)
  level_ratio(pred, ref, mask=None) -> (3,) sum(ref) / sum(pred) per channel (a level check)
  write_exr(path, rgb), read_image(path), read_mask(path, shape=None), write_preview(path, rgb)
"""

from flashbrdf.render.albedo_map import DiffuseAlbedoMap
from flashbrdf.render.compare import compare_images, level_ratio, write_comparison, write_delta_e_png
from flashbrdf.render.envmap import EnvMap, read_envmap_pixels
from flashbrdf.render.images import read_image, read_mask, tonemap, write_exr, write_preview
from flashbrdf.render.integrator import render_directional_light, render_envmap, render_point_light
from flashbrdf.render.material_map import MaterialMap
from flashbrdf.render.scene_render import (SceneGeometry, render_scene, render_sphere,
                                 sphere_view)

__all__ = [
    "DiffuseAlbedoMap", "EnvMap", "SceneGeometry",
    "compare_images", "level_ratio", "read_envmap_pixels", "read_image", "read_mask",
    "render_directional_light", "render_envmap",
    "MaterialMap", "render_point_light", "render_scene", "render_sphere", "sphere_view", "tonemap",
    "write_comparison", "write_delta_e_png", "write_exr", "write_preview",
]
