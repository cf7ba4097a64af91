"""The diffuse albedo map's files: ALBEDO.exr, ALBEDO.json, ALBEDO.faces.npy (opt-in).

ALBEDO.exr: (H, W, 3) float32 linear RGB diffuse albedo A(x) in the flash photo's pixel grid, 0
off the object (slice_extract.albedo). ALBEDO.json: {"floors": [[r, g, b], ...] (f_k of material
k = 1..K, 1/sr), "method", "trusted_fraction"}. ALBEDO.faces.npy (mesh geometry): (F, 3)
float32, each face's mean albedo (the material's floor x pi for faces the flash does not see),
for views from other cameras. A render then uses rho = T_k + A/pi - f_k per point.
Written together through temporary files and renamed, so a failure leaves none of them.
"""

import contextlib
import json
from pathlib import Path

import numpy as np

from flashbrdf.files.atomic import atomic_path
from flashbrdf.files.errors import InputError
from flashbrdf.capture import load_mesh
from flashbrdf.pipeline.label_files import read_npy
from flashbrdf.render.albedo_map import table_floor
from flashbrdf.render.images import image_channel_names, read_image, write_exr
from flashbrdf.slice_extract.albedo import estimate_albedo_map, face_means


def albedo_sidecars(albedo_exr):
    """(ALBEDO.json, ALBEDO.faces.npy) beside ALBEDO.exr."""
    albedo_exr = Path(albedo_exr)
    return albedo_exr.with_suffix(".json"), albedo_exr.with_name(albedo_exr.stem + ".faces.npy")


def check_albedo_out(path, where="--albedo"):
    """InputError unless the albedo map's output path ends in .exr."""
    if Path(path).suffix.lower() != ".exr":
        raise InputError(where, f"the albedo map must be an .exr, got {path}")


def albedo_for_scene(samples, labels, face_labels=None):
    """(slice_extract.albedo.AlbedoMap, face albedo (F, 3) or None) of FlashSamples and a label
    image (H, W) 1..K; face_labels (F,) int 1..K (mesh geometry) gives unseen faces their
    material's floor."""
    result = estimate_albedo_map(samples, labels)
    faces = None
    if samples.face_image is not None and face_labels is not None:
        face_labels = np.asarray(face_labels)
        delta, _ = face_means(result.delta, np.where(labels > 0, samples.face_image, -1),
                              len(face_labels))
        faces = np.pi * (result.floors[np.clip(face_labels, 1, len(result.floors)) - 1] + delta)
    return result, faces


def write_albedo(out, result, faces=None):
    """Write ALBEDO.exr (+ ALBEDO.json, ALBEDO.faces.npy), all or none."""
    out = Path(out)
    js_path, npy_path = albedo_sidecars(out)
    on = np.any(result.albedo > 0, axis=2)
    report = {"floors": [[float(v) for v in f] for f in result.floors],
              "trusted_fraction": float(result.trusted[on].mean()) if on.any() else 0.0,
              "method": "rho = T_k + A/pi - f_k; A/pi - f_k = flash sample - material slice at "
                        "its theta_h (slice_extract.albedo)"}
    with contextlib.ExitStack() as stack:
        exr = stack.enter_context(atomic_path(out, suffix=".exr"))
        write_exr(exr, result.albedo)
        if faces is not None:
            npy = stack.enter_context(atomic_path(npy_path, suffix=".npy"))
            with open(npy, "wb") as f:
                np.save(f, np.asarray(faces, np.float32))
        js = stack.enter_context(atomic_path(js_path, suffix=".json"))
        Path(js).write_text(json.dumps(report, indent=1) + "\n")


def read_albedo(path, scene, camera, tables):
    """(albedo (H, W, 3), floors (K, 3), faces (F, 3) or None) for `render --albedo`.

    The map must be the flash camera's size, finite and >= 0. floors come from ALBEDO.json when
    it is there (one per table), else from each table (render.albedo_map.table_floor).
    InputError naming the file otherwise."""
    path = Path(path)
    if not path.is_file():
        raise InputError(path, "albedo map not found")
    albedo = read_image(path)
    channels = image_channel_names(path)
    if not (set("RGB") <= set(channels) or len(channels) == 3):  # grey or 2-channel: not colour
        raise InputError(path, f"has {len(channels)} channel(s) ({','.join(channels)}); an "
                               "albedo map is RGB")
    if albedo.shape[:2] != tuple(camera.shape):
        raise InputError(path, f"is {albedo.shape[1]}x{albedo.shape[0]} but the flash photo is "
                               f"{camera.shape[1]}x{camera.shape[0]}")
    if not np.all(np.isfinite(albedo)) or albedo.min() < 0:
        raise InputError(path, "albedo values must be finite and >= 0")
    js_path, npy_path = albedo_sidecars(path)
    if js_path.is_file():
        try:
            floors = np.asarray(json.loads(js_path.read_text())["floors"], float)
        except (ValueError, KeyError, TypeError, OverflowError) as err:
            raise InputError(js_path, f"needs \"floors\": [[r, g, b], ...] ({err})") from None
        if floors.shape != (len(tables), 3) or not np.all(np.isfinite(floors)):
            raise InputError(js_path, f"\"floors\" must be {len(tables)} finite [r, g, b] "
                                      "(one per table)")
    else:
        floors = np.stack([table_floor(t) for t in tables])
    faces = None
    if npy_path.is_file():
        faces = read_npy(npy_path)
        if faces.ndim != 2 or faces.shape[1] != 3 or faces.dtype.kind != "f" or not np.all(
                np.isfinite(faces)):
            raise InputError(npy_path, "must be one finite [r, g, b] albedo per face (F, 3)")
        if scene.geometry.mesh is not None:
            n_faces = len(load_mesh(scene.geometry.mesh)[0].faces)
            if len(faces) != n_faces:
                raise InputError(npy_path, f"has {len(faces)} rows but the mesh has {n_faces} "
                                           "faces")
    return albedo, floors, faces
