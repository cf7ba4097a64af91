"""A COLMAP sparse model, read through pycolmap and checked, with its cameras in contract form.

Conventions (contract: ../shared/spec/INTERFACES.md, "Your own capture"):
- COLMAP puts the centre of the top-left pixel at (0.5, 0.5), the contract at (0, 0): the
  contract's cx, cy are COLMAP's minus 0.5. Focal lengths and distortion are the same numbers
  (COLMAP's OPENCV and FULL_OPENCV models are OpenCV's own formulas).
- COLMAP stores cam_from_world (world -> camera, OpenCV axes); the contract's world_from_camera
  is its inverse.

Every problem is an InputError naming the model file (or the camera or image in it). pycolmap is
a C++ library reading untrusted files: any exception it raises is bad input, never a traceback.
"""

import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from flashbrdf.capture.scene import MAX_IMAGE_SIDE
from flashbrdf.capture.scene_fields import (
    MAX_COORDINATE,
    MAX_FACTOR,
    MIN_FACTOR,
    beyond_coordinates,
    principal_point_problem,
    scaled_norm,
)
from flashbrdf.files.errors import InputError

MODEL_FILES = {"binary": ("cameras.bin", "images.bin", "points3D.bin"),
               "text": ("cameras.txt", "images.txt", "points3D.txt")}
RIG_FILES = {"binary": ("rigs.bin", "frames.bin"), "text": ("rigs.txt", "frames.txt")}
# COLMAP camera model -> (its parameter names, the contract's distortion from them). OpenCV's
# distortion vector is [k1, k2, p1, p2, k3] or, with the rational terms, [k1 .. k3, k4, k5, k6].
CAMERA_MODELS = {
    "SIMPLE_PINHOLE": (("f", "cx", "cy"), lambda p: []),
    "PINHOLE": (("fx", "fy", "cx", "cy"), lambda p: []),
    "SIMPLE_RADIAL": (("f", "cx", "cy", "k"), lambda p: [p["k"], 0, 0, 0, 0]),
    "RADIAL": (("f", "cx", "cy", "k1", "k2"), lambda p: [p["k1"], p["k2"], 0, 0, 0]),
    "OPENCV": (("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2"),
               lambda p: [p["k1"], p["k2"], p["p1"], p["p2"], 0]),
    "FULL_OPENCV": (("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6"),
                    lambda p: [p[k] for k in ("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6")]),
}
# |q| may differ from 1 by float rounding of a file written with few digits (6 digits: 1e-6);
# beyond this the file is damaged, and normalising it would hide that.
QUATERNION_NORM_TOLERANCE = 1e-3


@dataclass(frozen=True, eq=False)
class ModelImage:
    """A registered model image: world_from_camera (4, 4) float64, the contract's pose."""
    image_id: int
    name: str
    camera_id: int
    world_from_camera: np.ndarray

    @property
    def centre(self):
        return self.world_from_camera[:3, 3]


@dataclass(eq=False)
class ColmapModel:
    """A checked COLMAP model.

    folder: Path; format: "text" | "binary"; rigs_and_frames: whether the COLMAP 3.12+ rigs and
    frames files are there; files: {"cameras"|"images"|"points3D"|"rigs"|"frames": Path};
    reconstruction: the pycolmap.Reconstruction; images: registered ModelImage list, by name;
    unregistered: names of the images without a pose.
    """
    folder: Path
    format: str
    rigs_and_frames: bool
    files: dict
    reconstruction: object
    images: list = field(default_factory=list)
    unregistered: list = field(default_factory=list)

    def camera_field(self, camera_id):
        return f"{self.files['cameras']}: camera {camera_id}"

    def pose_file(self):
        """The file that holds the images' poses: frames (COLMAP 3.12+) or images."""
        return self.files["frames" if self.rigs_and_frames else "images"]

    def contract_camera(self, camera_id, world_from_camera):
        """The contract's camera dict (scene.json) of COLMAP camera `camera_id` at a pose."""
        return contract_camera(self.reconstruction.camera(camera_id),
                               self.camera_field(camera_id), world_from_camera)

    def mean_reprojection_error(self):
        """Mean reprojection error in pixels over the model's observations, or None (no
        points). Recomputed from the poses, cameras and 2D points: a file's stored errors may
        be -1 (unknown) or stale."""
        rec = self.reconstruction
        if rec.num_points3D() == 0:
            return None
        try:
            if hasattr(rec, "update_point_3d_errors"):
                rec.update_point_3d_errors()
            value = float(rec.compute_mean_reprojection_error())
        except Exception:  # noqa: BLE001  a summary figure, not worth failing the import for
            return None
        return value if math.isfinite(value) else None

    def sight_lines(self, max_points=50000, per_point=8, seed=0):
        """The model's 3D points and the cameras that saw them, for the mesh frame check.

        Returns points (P, 3), observed_point (M,) int and observer_centre (M, 3): at most
        max_points points (a seeded sample when more; a sample's shares are estimates within
        ~0.5%) and per point up to per_point registered images of its track, as sight lines.
        InputError naming the points file for a point not finite or past ±MAX_COORDINATE.
        """
        rec = self.reconstruction
        # COLMAP's point ids are uint64: a damaged file may hold any of them, 2^64 − 1 too
        ids = np.fromiter(rec.points3D.keys(), dtype=np.uint64, count=len(rec.points3D))
        if len(ids) > max_points:
            ids = np.sort(np.random.default_rng(seed).choice(ids, max_points, replace=False))
        centres = {im.image_id: im.centre for im in self.images}
        points = np.empty((len(ids), 3))
        observed, observers = [], []
        for k, point_id in enumerate(ids.tolist()):
            point = rec.points3D[point_id]
            points[k] = np.asarray(point.xyz, dtype=np.float64).ravel()
            seen = [centres[e.image_id] for e in point.track.elements if e.image_id in centres]
            if len(seen) > per_point:    # spread over the track: its cameras, all around
                seen = [seen[j] for j in np.linspace(0, len(seen) - 1, per_point).astype(int)]
            for centre in seen:
                observed.append(k)
                observers.append(centre)
        placed = np.all(np.abs(points) <= MAX_COORDINATE, axis=1)     # NaN and inf fail too
        if not placed.all():
            bad = int(ids[np.flatnonzero(~placed)[0]])
            raise InputError(f"{self.files['points3D']}: point {bad}",
                             f"position is not finite or beyond ±{MAX_COORDINATE:g}")
        return (points, np.asarray(observed, dtype=np.int64),
                np.asarray(observers, dtype=np.float64).reshape(-1, 3))


def _model_format(folder):
    """"text" or "binary", and whether the rigs and frames files are there; InputError naming
    a missing file."""
    present = {fmt: [n for n in names if (folder / n).is_file()]
               for fmt, names in MODEL_FILES.items()}
    complete = [fmt for fmt, names in MODEL_FILES.items() if len(present[fmt]) == len(names)]
    if complete:
        fmt = complete[0]    # binary first, as COLMAP reads a folder that holds both
    elif present["binary"] or present["text"]:
        fmt = max(("binary", "text"), key=lambda f: len(present[f]))
        missing = next(n for n in MODEL_FILES[fmt] if n not in present[fmt])
        raise InputError(folder / missing, f"missing: a COLMAP {fmt} model needs "
                                           f"{', '.join(MODEL_FILES[fmt])}")
    else:
        raise InputError(folder, "holds no COLMAP sparse model (cameras, images and points3D, "
                                 ".bin or .txt; MODEL_DIR is e.g. sparse/0)")
    rigs = [(folder / n).is_file() for n in RIG_FILES[fmt]]
    if any(rigs) and not all(rigs):
        missing = RIG_FILES[fmt][rigs.index(False)]
        raise InputError(folder / missing, "missing: COLMAP 3.12 and later write the rigs and "
                                           "frames files together")
    return fmt, all(rigs)


def _text_camera_diagnosis(files):
    """For a text model pycolmap refused: (where, problem) for the first image whose camera id
    cameras.txt does not define, or None. Read only to explain pycolmap's error."""
    def lines(path):
        return path.read_text(encoding="utf-8", errors="replace").splitlines()

    try:
        cameras = {ln.split()[0] for ln in lines(files["cameras"])
                   if ln.strip() and not ln.lstrip().startswith("#")}
        text = iter(lines(files["images"]))
        for line in text:
            row = line.split()
            if not row or row[0].startswith("#"):
                continue
            next(text, None)   # as COLMAP reads it: the 2D points line follows, even if empty
            if len(row) >= 10 and row[0].isdigit() and row[8].isdigit() and \
                    row[8] not in cameras:
                return (f"{files['images']}: image {row[0]} ({row[9]})",
                        f"camera id {row[8]} is not defined in {files['cameras'].name}")
    except (OSError, IndexError):
        return None
    return None


def _blame(files, fmt, message):
    """(where, problem) of a pycolmap read error: the model file it is about, by its words."""
    text = message.splitlines()[0] if message else "unknown error"
    text = re.sub(r"^\[[\w./]+:\d+\]\s*", "", text)        # drop pycolmap's [file.cc:123]
    if "line_stream" in text:    # a C++ stream expression: say what it means
        text = "a line has too few fields, or one that is not a number"
    problem = f"pycolmap cannot read this {fmt} model: {text}"
    if fmt == "text":
        found = _text_camera_diagnosis(files)
        if found is not None:
            return found
    rig = re.search(r"Rig with ID (-?\d+) does not exist", message)
    if rig and "rigs" not in files:   # without rigs files, each camera is its own trivial rig
        return files["images"], f"an image refers to camera id {rig.group(1)}, which " \
                                f"{files['cameras'].name} does not define"
    lowered = message.lower()
    for key, words in (("points3D", ("point3d", "point2d", "track")),
                       ("frames", ("frame",)), ("rigs", ("rig",)),
                       ("images", ("image", "cam_from_world")),
                       ("cameras", ("camera", "verifyparams"))):
        if key in files and any(w in lowered for w in words):
            return files[key], problem
    return files["images"].parent, problem


# pycolmap reads a binary model without checking its stream: a truncated frames.bin or
# points3D.bin made it loop or allocate without end (tests/test_import_colmap_bad_input.py). So a
# binary model is first read in a child process, with a time and memory limit; text parsing
# checks every field and needs none of this.
READ_TIMEOUT_S, READ_TIMEOUT_S_PER_GB = 20.0, 60.0
READ_MEMORY_BYTES, READ_MEMORY_PER_FILE_BYTE = 8 << 30, 20
_CHILD_READ = """
import resource, sys
resource.setrlimit(resource.RLIMIT_AS, (int(sys.argv[2]), int(sys.argv[2])))
import pycolmap
try:
    pycolmap.Reconstruction().read_binary(sys.argv[1])
except BaseException as err:
    sys.stderr.write("\\nREAD-ERROR " + " ".join(str(err).split()) + "\\n")
    sys.exit(3)
"""


class _Unreadable(Exception):
    """pycolmap failed, crashed or did not finish reading a model (the message says which);
    ended_badly: it crashed or did not finish (nothing more can be learnt by reading again)."""

    def __init__(self, message, ended_badly=True):
        super().__init__(message)
        self.ended_badly = ended_badly


def _read_in_child(folder):
    """Read a binary model in a child process; _Unreadable when that fails or ends badly."""
    import subprocess
    import sys
    size = sum(f.stat().st_size for f in Path(folder).iterdir() if f.is_file())
    timeout = READ_TIMEOUT_S + READ_TIMEOUT_S_PER_GB * size / 1e9
    memory = READ_MEMORY_BYTES + READ_MEMORY_PER_FILE_BYTE * size
    try:
        done = subprocess.run([sys.executable, "-c", _CHILD_READ, str(folder), str(memory)],
                              capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        raise _Unreadable(f"reading it did not end within {timeout:.0f} s (a truncated or "
                          "damaged file?)") from None
    if done.returncode == 0:
        return
    marker = done.stderr.rfind("READ-ERROR ")
    if marker >= 0:
        raise _Unreadable(done.stderr[marker + len("READ-ERROR "):].splitlines()[0], False)
    raise _Unreadable(f"pycolmap stopped (status {done.returncode}) reading it (a truncated or "
                      "damaged file?)")


def _read(folder, fmt):
    import pycolmap  # 0.3 s to import, paid by import-colmap only
    if fmt == "binary":
        _read_in_child(folder)
    rec = pycolmap.Reconstruction()
    (rec.read_binary if fmt == "binary" else rec.read_text)(str(folder))
    return rec


def _without_rigs(files, fmt):
    """For a model with rigs and frames that pycolmap refused: read its cameras, images and
    points alone (linked into a temporary folder), as COLMAP before 3.12 would. Returns the
    error message of that read, or None when it succeeds (then rigs or frames are at fault)."""
    import tempfile
    with tempfile.TemporaryDirectory(prefix="flashbrdf-colmap-") as folder:
        for key in ("cameras", "images", "points3D"):
            os.symlink(os.path.abspath(files[key]), os.path.join(folder, files[key].name))
        try:
            _read(folder, fmt)
        except Exception as err:  # noqa: BLE001  (see _reconstruction)
            return str(err)
    return None


def _reconstruction(folder, fmt, files):
    try:
        return _read(folder, fmt)
    except Exception as err:  # noqa: BLE001  pybind11 maps C++ errors to many types
        if getattr(err, "ended_badly", False):
            raise InputError(folder, f"pycolmap cannot read this {fmt} model: {err}") from None
        message = str(err)
    if "rigs" in files:
        # an image's camera id that cameras.* lacks reads as "Image 1 does not exist in frame 1"
        # with rigs and frames, and as a missing trivial rig without them: ask the second way
        alone = _without_rigs(files, fmt)
        if alone is None:
            rig = re.search(r"Rig with ID (-?\d+) does not exist", message)
            if rig:
                raise InputError(files["frames"], f"a frame refers to rig {rig.group(1)}, which "
                                                  f"{files['rigs'].name} does not define")
            where, problem = _blame(files, fmt, message)
            raise InputError(where if where in (files["rigs"], files["frames"])
                             else files["frames"], problem)
        if re.search(r"Rig with ID (-?\d+) does not exist", alone):
            message = alone
            files = {k: v for k, v in files.items() if k not in ("rigs", "frames")}
    raise InputError(*_blame(files, fmt, message)) from None


def _is_registered(image):
    flag = getattr(image, "has_pose", None)
    if flag is None:
        flag = getattr(image, "registered", True)   # pycolmap before 3.12
    return bool(flag() if callable(flag) else flag)


def cam_from_world(image):
    """(quaternion (4,) x, y, z, w; translation (3,)) of a pycolmap Image, as stored.

    pycolmap 3.12+ has Image.cam_from_world() (a method since 3.12, a property in 0.5 to 3.11);
    older versions have qvec (w, x, y, z) and tvec."""
    pose = getattr(image, "cam_from_world", None)
    if pose is not None:
        pose = pose() if callable(pose) else pose
        return (np.asarray(pose.rotation.quat, dtype=np.float64),
                np.asarray(pose.translation, dtype=np.float64).ravel())
    q = np.asarray(image.qvec, dtype=np.float64)
    return q[[1, 2, 3, 0]], np.asarray(image.tvec, dtype=np.float64).ravel()


def world_from_camera(quaternion_xyzw, translation, where):
    """The contract's 4x4 world_from_camera from COLMAP's cam_from_world; InputError naming
    `where` for a non-finite or non-unit quaternion, a non-finite translation, or a camera
    centre past ±MAX_COORDINATE."""
    q = np.asarray(quaternion_xyzw, dtype=np.float64)
    t = np.asarray(translation, dtype=np.float64)
    if not (np.all(np.isfinite(q)) and np.all(np.isfinite(t))):
        raise InputError(where, f"pose is not finite (quaternion {_listed(q[[3, 0, 1, 2]])}, "
                                f"translation {_listed(t)})")
    norm = scaled_norm(q)   # a damaged file may hold 1e308
    if abs(norm - 1.0) > QUATERNION_NORM_TOLERANCE:
        raise InputError(where, f"quaternion (qw, qx, qy, qz) {_listed(q[[3, 0, 1, 2]])} has norm "
                                f"{norm:.6g}, not 1: not a rotation (a damaged model file?)")
    x, y, z, w = q / norm
    rotation = np.array([   # cam_from_world rotation of the unit quaternion
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
    pose = np.eye(4)
    pose[:3, :3] = rotation.T
    with np.errstate(over="ignore", invalid="ignore"):   # |t| near 1e308: checked below
        pose[:3, 3] = -rotation.T @ t
    if beyond_coordinates(pose[:3, 3]) is not None:      # inf too
        raise InputError(where, f"translation {_listed(t)} places the camera beyond "
                                f"±{MAX_COORDINATE:g} model units (rays are 32-bit floats): a "
                                "damaged model file?")
    return pose


def _listed(values):
    return "[" + ", ".join(f"{v:.6g}" for v in np.ravel(values)) + "]"


def camera_model_name(camera):
    name = getattr(camera, "model_name", None)
    return str(name if name is not None else camera.model.name)


def contract_camera(camera, where, pose):
    """scene.json camera dict of a pycolmap Camera at pose (4, 4) world_from_camera.

    InputError naming `where` for a model other than CAMERA_MODELS (with its id and name), or
    a size, focal length or parameter no camera has."""
    name = camera_model_name(camera)
    if name not in CAMERA_MODELS:
        raise InputError(where, f"camera model {name} is not supported: flashbrdf maps "
                                f"{', '.join(CAMERA_MODELS)} (reconstruct with one of them, e.g. "
                                "colmap feature_extractor --ImageReader.camera_model OPENCV)")
    names, distortion_of = CAMERA_MODELS[name]
    params = np.asarray(camera.params, dtype=np.float64).ravel()
    if len(params) != len(names):
        raise InputError(where, f"{name} has {len(names)} parameters ({', '.join(names)}), "
                                f"got {len(params)}")
    if not np.all(np.isfinite(params)):
        raise InputError(where, f"parameters {_listed(params)} are not all finite")
    # COLMAP keeps sizes unsigned: a negative one in the file comes back as 2^64 minus it
    width, height = (int(v) - (1 << 64) if int(v) >= 1 << 63 else int(v)
                     for v in (camera.width, camera.height))
    if not (1 <= width <= MAX_IMAGE_SIDE and 1 <= height <= MAX_IMAGE_SIDE):
        raise InputError(where, f"size {width}x{height} is not a camera's (1..{MAX_IMAGE_SIDE})")
    p = dict(zip(names, params.tolist()))
    fx, fy = p.get("fx", p.get("f")), p.get("fy", p.get("f"))
    for key, value in (("fx", fx), ("fy", fy)):
        if not MIN_FACTOR <= value <= MAX_FACTOR:
            raise InputError(where, f"focal length {key} = {value:g} is not a positive number "
                                    f"within {MIN_FACTOR:g}..{MAX_FACTOR:g}")
    for key, size, focal in (("cx", width, fx), ("cy", height, fy)):
        problem = principal_point_problem(p[key] - 0.5, size, focal)
        if problem:
            raise InputError(where, f"principal point {key} = {problem}")
    cam = {"model": "pinhole", "width": width, "height": height, "fx": fx, "fy": fy,
           "cx": p["cx"] - 0.5, "cy": p["cy"] - 0.5,   # COLMAP's pixel centres at +0.5
           "world_from_camera": np.asarray(pose, dtype=np.float64).tolist()}
    distortion = [float(v) for v in distortion_of(p)]
    if len(distortion) == 8 and not any(distortion[5:]):
        distortion = distortion[:5]     # FULL_OPENCV without rational terms: the contract's five
    if any(distortion):
        cam["distortion"] = distortion
    return cam


def read_colmap_model(model_dir):
    """Read and check a COLMAP sparse model folder (text or binary, with or without the rigs
    and frames files of COLMAP 3.12+) -> ColmapModel. InputError naming the file, camera or
    image: a missing file, a file pycolmap cannot read, no registered image, an image name that
    is not UTF-8, a non-finite or non-unit pose quaternion, a camera centre past ±1e30."""
    folder = Path(model_dir)
    if not folder.is_dir():
        raise InputError(folder, "not a folder (MODEL_DIR is a COLMAP sparse model folder, e.g. "
                                 "sparse/0)")
    fmt, rigs = _model_format(folder)
    keys = ("cameras", "images", "points3D")
    files = {k: folder / n for k, n in zip(keys, MODEL_FILES[fmt])}
    if rigs:
        files.update(zip(("rigs", "frames"), (folder / n for n in RIG_FILES[fmt])))
    rec = _reconstruction(folder, fmt, files)
    model = ColmapModel(folder, fmt, rigs, files, rec)
    pose_file = model.pose_file()
    try:
        entries = sorted(rec.images.items())
    except Exception as err:  # noqa: BLE001
        raise InputError(files["images"], f"pycolmap cannot list the images: {err}") from None
    for image_id, image in entries:
        try:
            name = str(image.name)
        except UnicodeDecodeError:   # pycolmap decodes the stored bytes on each access
            name = None
        if not _is_registered(image):   # listed in the summary only
            model.unregistered.append(name or f"image {image_id} (its name is not UTF-8)")
            continue
        if name is None:
            raise InputError(f"{files['images']}: image {image_id}",
                             "its name is not UTF-8 text, which pycolmap cannot read (a damaged "
                             "file, or a photo named in another encoding: rename it and rerun "
                             "COLMAP)")
        where = f"{pose_file}: image {image_id} ({name})"
        try:
            quaternion, translation = cam_from_world(image)
        except Exception as err:  # noqa: BLE001  a frame or rig pycolmap cannot compose
            raise InputError(where, f"pycolmap cannot give its pose: {err}") from None
        model.images.append(ModelImage(int(image_id), name, int(image.camera_id),
                                       world_from_camera(quaternion, translation, where)))
    if not model.images:
        raise InputError(pose_file, "holds no registered image (an empty reconstruction: did "
                                    "COLMAP's mapper succeed?)")
    model.images.sort(key=lambda im: im.name)
    return model
