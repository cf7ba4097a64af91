"""Extraction of a full-resolution multi-view capture: 30 flash photos of 6000 x 4000 px (24 MP),
each with its own OPENCV camera (distortion, principal point off centre), of a ~600k-face mesh.

    nice -n 10 python -m benchmarks.full_resolution --work WORK [--views 30] [--width 6000]

Renders the capture once into WORK (kept: ~5 GB of EXR), then measures `flashbrdf extract` as a
separate process: wall seconds and peak RSS (/usr/bin/time -v), against Embree's own time for
the photos' pixels (one embreex first-hit query per pixel that can see the mesh's bounding box,
in every view, and a shadow ray to the flash from every hit), and against Embree's time for the
rays extraction actually casts (capture.mesh_pixels: it skips what can only miss).
Targets (issue "Your own object"): peak RSS <= 4 GB, extraction <= 2x Embree's ray time. Writes
benchmarks/results/full_resolution.{json,md}.
"""

import argparse
import json
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from tests.colmap_synthetic import view_poses
from tests.synthetic import combine, sphere_mesh, torus_mesh

RESULTS = Path(__file__).resolve().parent / "results"
FLASH_OFFSET = [0.03, -0.02, 0.0]


def dense_mesh():
    """A tilted torus (720 x 360 sections) around a sphere (6 subdivisions): ~600k faces."""
    return combine(torus_mesh(centre=(0, 0, 0), sections=(720, 360)),
                   sphere_mesh(radius=0.045, centre=(0, 0, 0), subdivisions=6))


def camera(pose, width, height):
    """An OPENCV-like contract camera: the object fills about half the frame."""
    focal = 7200.0 * width / 6000
    return {"model": "pinhole", "width": width, "height": height, "fx": focal, "fy": focal * 1.002,
            "cx": (width - 1) / 2 + 0.013 * width, "cy": (height - 1) / 2 - 0.011 * height,
            "distortion": [-0.05, 0.01, 0.0005, -0.0003, 0.0],
            "world_from_camera": np.asarray(pose).tolist()}


def make_capture(work, views, width, height):
    """scene.json, object.ply and views x EXR flash photos in `work` (skipped when present)."""
    from flashbrdf import capture
    from flashbrdf.brdf.models import GGX
    from flashbrdf.render import SceneGeometry, render_scene, write_exr
    work = Path(work)
    if (work / "scene.json").is_file():
        return work
    work.mkdir(parents=True, exist_ok=True)
    mesh = dense_mesh()
    mesh.export(work / "object.ply", vertex_normal=True)
    cams = [camera(pose, width, height) for pose in view_poses(views)]
    photos = [{"file": f"view_{k:02d}.exr", "role": "flash", "camera": cam,
               "light": {"type": "point", "position": FLASH_OFFSET, "intensity_rgb": [1, 1, 1]}}
              for k, cam in enumerate(cams)]
    (work / "scene.json").write_text(json.dumps(
        {"camera": cams[0], "geometry": {"mesh": "object.ply"}, "photos": photos}, indent=1))
    scene = capture.load_scene(work)
    geometry = SceneGeometry(scene)
    brdf = GGX(alpha=0.18, specular=(0.5, 0.5, 0.5), diffuse=(0.55, 0.3, 0.15), fresnel=False)
    for photo in scene.photos_with_role("flash"):  # one at a time: bounded memory
        for _, image, _ in render_scene(scene, brdf, photos=[photo], progress=False,
                                        geometry=geometry):
            write_exr(work / photo.file.name, image)
        print(f"rendered {photo.file.name}", flush=True)
    return work


def box_pixels(camera, mesh):
    """Every pixel whose centre can see the mesh's bounding box (capture.pixel_box)."""
    from flashbrdf import capture
    return capture.box_pixels(capture.pixel_box(camera, mesh.bounds))


def traced_pixels(camera, mesh):
    """The pixels extraction casts rays for (capture.mesh_pixels)."""
    from flashbrdf import capture
    return capture.mesh_pixels(camera, mesh.vertices, mesh.faces)


def embree_seconds(work, pixels, shadows=True):
    """Seconds of the Embree queries for the rays of `pixels(camera, mesh)` in every view: first
    hits, and (the mesh is not convex, the flash is off the lens) a shadow ray to the flash from
    every hit (capture.occluded, its float64 set-up included). Returns (first-hit s, shadow s,
    rays, shadow rays)."""
    from flashbrdf import capture
    scene = capture.load_scene(work)
    intersector = capture.scene_intersector(scene)
    first_hit, shadow, rays, shadow_rays = 0.0, 0.0, 0, 0
    for photo in scene.photos_with_role("flash"):
        cam = photo.camera
        flash = cam.to_world(np.asarray(FLASH_OFFSET))
        rows, cols = pixels(cam, intersector.mesh)
        for s in range(0, len(rows), 1 << 20):
            origins, directions = capture.embree_rays(cam, rows[s:s + (1 << 20)],
                                                      cols[s:s + (1 << 20)], intersector.centre)
            start = time.perf_counter()
            hit = intersector.embree_first_hit(origins, directions)
            first_hit += time.perf_counter() - start
            if not shadows:
                continue
            found = hit["primID"] >= 0
            points = (origins[found] + hit["tfar"][found, None] * directions[found]
                      ).astype(np.float64) + intersector.centre
            to_flash = flash - points
            distance = np.linalg.norm(to_flash, axis=1)
            start = time.perf_counter()
            capture.occluded(intersector, points, to_flash / distance[:, None], distance)
            shadow += time.perf_counter() - start
            shadow_rays += int(found.sum())
        rays += len(rows)
    return first_hit, shadow, rays, shadow_rays


def timed_extract(work, out):
    done = subprocess.run(["/usr/bin/time", "-v", sys.executable, "-m", "flashbrdf", "extract",
                           str(work), "--out", str(out)], capture_output=True, text=True)
    if done.returncode != 0:
        raise SystemExit(done.stderr)
    wall = re.search(r"Elapsed \(wall clock\) time.*: (?:(\d+):)?(\d+):([\d.]+)", done.stderr)
    seconds = int(wall.group(1) or 0) * 3600 + int(wall.group(2)) * 60 + float(wall.group(3))
    rss = int(re.search(r"Maximum resident set size \(kbytes\): (\d+)", done.stderr).group(1))
    return seconds, rss / 1024 / 1024


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--work", required=True)
    p.add_argument("--views", type=int, default=30)
    p.add_argument("--width", type=int, default=6000)
    p.add_argument("--height", type=int, default=4000)
    args = p.parse_args(argv)
    work = make_capture(args.work, args.views, args.width, args.height)
    load = os.getloadavg()[0]
    extract_s, rss_gb = timed_extract(work, Path(args.work) / "slice.csv")
    report = json.loads((Path(args.work) / "slice.json").read_text())
    first_hit_s, shadow_s, rays, shadow_rays = embree_seconds(work, box_pixels)
    embree_s = first_hit_s + shadow_s
    traced_first_hit_s, _, traced_rays, _ = embree_seconds(work, traced_pixels, shadows=False)
    traced_embree_s = traced_first_hit_s + shadow_s
    result = {"command": "nice -n 10 python -m benchmarks.full_resolution " +
                         " ".join(argv or sys.argv[1:]),
              "views": args.views, "pixels_per_photo": args.width * args.height,
              "faces": int(len(dense_mesh().faces)), "load_average_at_start": load,
              "extract_s": round(extract_s, 1), "peak_rss_gb": round(rss_gb, 2),
              "embree_s": round(embree_s, 1), "embree_first_hit_s": round(first_hit_s, 1),
              "embree_shadow_s": round(shadow_s, 1), "box_rays": rays,
              "shadow_rays": shadow_rays,
              "ratio_to_embree": round(extract_s / embree_s, 2),
              "traced_rays": traced_rays, "traced_embree_s": round(traced_embree_s, 1),
              "traced_embree_first_hit_s": round(traced_first_hit_s, 1),
              "ratio_to_traced_embree": round(extract_s / traced_embree_s, 2),
              "timings_s": report["timings_s"], "pixels_used": report["coverage"]["pixels_used"],
              "bins_filled": report["coverage"]["bins_filled"]}
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "full_resolution.json").write_text(json.dumps(result, indent=1) + "\n")
    lines = ["# Full-resolution multi-view extraction", "", f"Command: `{result['command']}`",
             "", f"{args.views} views of {args.width}x{args.height} px, {result['faces']} faces, "
             f"load average {load:.1f} on {os.cpu_count()} cores.", "",
             "| extract s | peak RSS GB | Embree s, box pixels (first hit + shadow) | ratio | "
             "box rays | shadow rays | pixels used |",
             "|---|---|---|---|---|---|---|",
             f"| {result['extract_s']} | {result['peak_rss_gb']} | {result['embree_s']} "
             f"({result['embree_first_hit_s']} + {result['embree_shadow_s']}) | "
             f"{result['ratio_to_embree']} | {rays} | {shadow_rays} | {result['pixels_used']} |",
             "",
             "Box pixels: every pixel whose centre can see the mesh's bounding box, what a "
             "per-pixel ray caster traces. Extraction casts rays only where a face can project "
             f"(capture.mesh_pixels): {traced_rays} rays, whose first hits take Embree "
             f"{result['traced_embree_first_hit_s']} s; with the same shadow rays that is "
             f"{result['traced_embree_s']} s, and extraction is {result['ratio_to_traced_embree']}x "
             "that. The next photo is decoded in a second thread while the current one is traced.",
             "",
             "Stage seconds inside extract: " + ", ".join(f"{k} {v}" for k, v in
                                                           report["timings_s"].items())]
    (RESULTS / "full_resolution.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
