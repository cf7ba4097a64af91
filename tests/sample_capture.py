"""Make the synthetic sample capture in sample_data/: a sphere beside a vase, photographed with a
flash 3 cm off the lens, plus reference photos under two environment maps.

    python tests/sample_capture.py --table MATERIAL.binary --out sample_data/capture

The photos are rendered by flashbrdf's own renderer from a known MERL table (the ground truth),
through the contract's pixel model. Scene frame (world): metres, +y up, objects on the plane
y = 0; the camera sits 1 m in front (+z), looking along -z. The environment maps are referenced
from ../shared (never copied), by a path relative to the scene folder.
"""

import argparse
import json
import os
import sys
from pathlib import Path

import numpy as np

from flashbrdf.files.atomic import write_text

SHARED_ENVMAPS = Path(__file__).resolve().parents[2] / "shared" / "data" / "envmaps"
ENVMAPS = {"ref_pisa": "pisa_latlong_256x128.hdr", "ref_uffizi": "uffizi_latlong_256x128.hdr"}
FLASH_OFFSET_M = [0.03, 0.0, 0.0]  # flash 3 cm right of the lens, camera frame
AMBIENT_RADIANCE = 0.004           # a dim, uniform room light in the flash-off photo
PHOTONS_PER_UNIT = 2.0e5           # shot noise: a pixel of value v collects v * this photons


def vase_and_sphere():
    """A closed vase (a non-convex surface of revolution) beside a sphere, one trimesh."""
    import trimesh
    from scipy.interpolate import CubicSpline
    # Profile radius(height) in metres through a few control points, closed on the axis.
    knots = CubicSpline([0.0, 0.05, 0.09, 0.16, 0.19, 0.22], [0.055, 0.085, 0.09, 0.05, 0.035, 0.05])
    height = np.linspace(0.0, 0.22, 64)
    profile = np.concatenate([[[0.0, 0.0]], np.stack([knots(height), height], 1), [[0.0, 0.22]]])
    vase = trimesh.creation.revolve(profile, sections=128)
    vase.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0]))  # z -> y
    vase.apply_translation([0.12, 0.0, 0.0])
    sphere = trimesh.creation.icosphere(subdivisions=5, radius=0.08)
    sphere.apply_translation([-0.11, 0.08, 0.0])
    mesh = trimesh.util.concatenate([vase, sphere])
    mesh.merge_vertices()
    mesh.fix_normals()
    return mesh


def sphere_only():
    """A lone sphere of radius 0.1 m resting on y = 0 (convex: no shadow rays)."""
    import trimesh
    sphere = trimesh.creation.icosphere(subdivisions=5, radius=0.1)
    sphere.apply_translation([0.0, 0.1, 0.0])
    return sphere


SHAPES = {"vase_and_sphere": vase_and_sphere, "sphere": sphere_only}


def scene_description(folder, size, envmaps=ENVMAPS):
    camera = {"model": "pinhole", "width": size, "height": size, "fx": size * 2.2,
              "fy": size * 2.2, "cx": (size - 1) / 2, "cy": (size - 1) / 2,
              # OpenCV camera axes (x right, y down, z forward) in the +y-up world:
              "world_from_camera": [[1, 0, 0, 0], [0, -1, 0, 0.09], [0, 0, -1, 1.0],
                                    [0, 0, 0, 1]]}
    photos = [{"file": "flash.exr", "role": "flash",
               "light": {"type": "point", "position": FLASH_OFFSET_M,
                         "intensity_rgb": [1.0, 1.0, 1.0]}},
              {"file": "ambient.exr", "role": "ambient"}]
    for stem, name in envmaps.items():
        envmap = os.path.relpath(SHARED_ENVMAPS / name, folder)
        photos.append({"file": f"{stem}.exr", "role": "reference",
                       "light": {"type": "envmap", "file": envmap,
                                 "world_from_envmap": np.eye(3).tolist(), "scale": 1.0}})
    return {"camera": camera, "geometry": {"mesh": "object.ply"}, "photos": photos}


def _noisy(image, rng):
    photons = rng.poisson(np.maximum(image, 0) * PHOTONS_PER_UNIT)
    return (photons / PHOTONS_PER_UNIT).astype(np.float32)


def make_sample_capture(table_path, out, size=256, spp=1024, seed=0, shape="vase_and_sphere",
                        envmaps=ENVMAPS):
    """Render the capture folder `out` from the ground-truth MERL table at `table_path`.

    shape: a key of SHAPES; envmaps: {reference photo stem: file in ../shared/data/envmaps}.
    """
    from flashbrdf import capture
    from flashbrdf.brdf.merl import read_merl
    from flashbrdf.brdf.models import TabulatedBRDF
    from flashbrdf.render import EnvMap, render_envmap, render_scene, write_exr
    from flashbrdf.render.scene_render import SceneGeometry

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    SHAPES[shape]().export(out / "object.ply", vertex_normal=True)
    write_text(out / "scene.json",
               json.dumps(scene_description(out.resolve(), size, envmaps), indent=2))
    scene = capture.load_scene(out)
    brdf = TabulatedBRDF(read_merl(table_path), interpolate=True)
    geometry = SceneGeometry(scene)

    surface = geometry.surface(scene.camera)
    ambient = np.zeros((size, size, 3), np.float32)
    room = EnvMap(np.full((8, 16, 3), AMBIENT_RADIANCE))
    ambient[surface.rows, surface.cols] = render_envmap(
        surface.points, surface.normals, surface.view_dirs, brdf, room, spp=64, seed=seed,
        occluded=geometry.occluder())
    ambient = _noisy(ambient, rng)
    write_exr(out / "ambient.exr", ambient)
    flash_photo = scene.photos_with_role("flash")
    for photo, image, _ in render_scene(scene, brdf, photos=flash_photo, geometry=geometry):
        write_exr(out / "flash.exr", _noisy(image + ambient, rng))
    references = scene.photos_with_role("reference")
    for photo, image, _ in render_scene(scene, brdf, spp=spp, seed=seed + 1, photos=references,
                                        geometry=geometry):
        write_exr(out / f"{photo.stem}.exr", image)
    return out


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--table", required=True, help="ground-truth MERL .binary")
    p.add_argument("--out", required=True)
    p.add_argument("--size", type=int, default=256)
    p.add_argument("--spp", type=int, default=1024)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--shape", choices=sorted(SHAPES), default="vase_and_sphere")
    a = p.parse_args(argv)
    folder = make_sample_capture(a.table, a.out, a.size, a.spp, a.seed, a.shape)
    print(f"wrote {folder}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
