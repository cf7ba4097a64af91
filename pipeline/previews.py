"""Renders of the result under an environment map, for `run` on a capture with no reference photo
(flash photos only: nothing to compare with) or with `run --envmap FILE`: the object from the
first flash photo's camera, and a sphere of each material, per method. No error is computed.

The map is the user's (--envmap) or the project's own studio (render.envmap.procedural_envmap,
made in code and written into OUT_DIR, so nothing third-party ships). It is turned to the flash
camera: the map's up is the camera's up and its centre lies behind the camera, so the key light
of the studio falls on the side of the object that the camera sees.

OUT_DIR/envmap_studio.exr            the generated map (without --envmap)
OUT_DIR/<method>/preview_object.exr  the object under the map (linear; .png tone-mapped)
OUT_DIR/<method>/preview_sphere[_material_<k>].exr, .png
"""

from dataclasses import replace
from pathlib import Path

import numpy as np

from flashbrdf.capture.scene import Light, Photo
from flashbrdf.render.envmap import procedural_envmap
from flashbrdf.render.images import write_exr, write_preview
from flashbrdf.render.scene_render import SceneGeometry, render_scene, render_sphere

PREVIEW_LONG_SIDE = 640   # the object is rendered at most this wide (or tall), in pixels
SPHERE_SIZE = 160
STUDIO_HEIGHT = 256


def preview_envmap(envmap, out):
    """The map file to render under: `envmap` when given, else the studio written into out."""
    if envmap is not None:
        return Path(envmap)
    path = Path(out) / "envmap_studio.exr"
    write_exr(path, procedural_envmap("studio", STUDIO_HEIGHT))
    return path


def camera_facing_envmap(camera):
    """(3, 3) world_from_envmap: the map's +y along the camera's up (-y), its -z (the map's
    centre) behind the camera, right-handed."""
    rotation = np.asarray(camera.world_from_camera, float)[:3, :3]
    right, down, forward = rotation.T
    return np.stack([-right, -down, forward], axis=1)


def preview_camera(camera, long_side=PREVIEW_LONG_SIDE):
    """The camera scaled down so that its longer side is at most long_side pixels (same view)."""
    scale = min(1.0, long_side / max(camera.width, camera.height))
    if scale == 1.0:
        return camera
    width, height = max(1, round(camera.width * scale)), max(1, round(camera.height * scale))
    if camera.model == "orthographic":
        return replace(camera, width=width, height=height,
                       pixel_size=camera.pixel_size * camera.width / width)
    sx, sy = width / camera.width, height / camera.height
    return replace(camera, width=width, height=height, fx=camera.fx * sx, fy=camera.fy * sy,
                   cx=(camera.cx + 0.5) * sx - 0.5, cy=(camera.cy + 0.5) * sy - 0.5)


def render_previews(scene, geometry, brdfs, sphere_tables, envmap_path, out, spp=64):
    """Render the object and the spheres for every method.

    brdfs: {method: BRDF for render_scene (a model or a MaterialMap)}; sphere_tables: {method:
    {material k: 2D/3D table}}; envmap_path: the map; out: the (staged) output folder.
    Returns {method: {"object": relative path, "spheres": {k: relative path}}}."""
    # the first flash photo's view that sees the object (a turned-away first view is no preview)
    cameras = [p.camera for p in scene.photos_with_role("flash")]
    camera = preview_camera(next((c for c in cameras if geometry.sees_object(c)), cameras[0]))
    light = Light(type="envmap", file=Path(envmap_path),
                  world_from_envmap=camera_facing_envmap(camera), scale=1.0)
    view = Photo(index=-1, role="preview", camera=camera, where="run --envmap",
                 file=Path("preview_object"), light=light)
    found = {method: {"object": None, "spheres": {}} for method in brdfs}
    for method in brdfs:
        (Path(out) / method).mkdir(parents=True, exist_ok=True)
    # the object once for all methods (what does not depend on the BRDF rendered once)
    for _, images, _ in render_scene(scene, list(brdfs.values()), spp=spp, photos=[view],
                                     progress=False, geometry=geometry):
        for method, image in zip(brdfs, images):
            write_exr(Path(out) / method / "preview_object.exr", image)
            write_preview(Path(out) / method / "preview_object.png", image)
            found[method]["object"] = f"{method}/preview_object.png"
    for method, entry in found.items():
        folder = Path(out) / method
        tables = sphere_tables[method]
        for k, table in tables.items():
            name = "preview_sphere" if len(tables) == 1 else f"preview_sphere_material_{k}"
            image = render_sphere(table, envmap_path, size=SPHERE_SIZE, spp=spp)
            write_exr(folder / f"{name}.exr", image)
            write_preview(folder / f"{name}.png", image)
            entry["spheres"][k] = f"{method}/{name}.png"
    return found


def preview_section(previews, envmap_name):
    """report.md lines showing the previews, one row per method."""
    lines = ["## Renders under an environment map", "",
             f"Under `{envmap_name}`, from the flash camera (object) and of a unit sphere (each "
             "material); no reference photo measured this light, so no error is given.", ""]
    for method, entry in previews.items():
        images = [f"![{method} object]({entry['object']})"] if entry["object"] else []
        images += [f"![{method} sphere {k}]({path})" for k, path in entry["spheres"].items()]
        lines += [f"**{method}**", "", " ".join(images), ""]
    return lines


def previews_under_envmap(settings, scene, geometry, brdfs, sphere_tables, out):
    """(report.json's "previews", report.md lines) of a run (pipeline.run.RunSettings: its
    envmap and spp) with the methods' BRDFs; geometry: the scene's SceneGeometry, or None."""
    envmap = preview_envmap(settings.envmap, out)
    geometry = geometry or SceneGeometry(scene)
    previews = render_previews(scene, geometry, brdfs, sphere_tables, envmap, out, settings.spp)
    name = Path(settings.envmap).name if settings.envmap else "the studio map made in code"
    return ({"envmap": settings.envmap or "envmap_studio.exr", "renders": previews},
            preview_section(previews, name))
