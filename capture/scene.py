"""Read and validate a capture folder's `scene.json` (contract: ../shared/spec/INTERFACES.md).

Every bad field raises InputError naming the file and the field, e.g.
"…/scene.json: photos[2].light.position: expected 3 numbers". Nothing here reads images or meshes;
paths are resolved against the scene folder and checked only for presence when used.

Additive fields (beyond the contract) accepted here:
- photos[].camera: a per-photo camera (same schema as the top-level one); defaults to the scene's.
- photos[].saturation: a linear value at or above which a pixel counts as clipped (float images
  carry no code-value ceiling of their own).
"""

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from flashbrdf.capture.scene_fields import (
    Fields,
    check_finite,
    no_repeats,
    principal_point_problem,
    scaled_norm,
)
from flashbrdf.files.errors import InputError

CAMERA_MODELS = ("pinhole", "orthographic")
ROLES = ("flash", "ambient", "reference")
LIGHT_TYPES = ("point", "directional", "envmap")
ENCODINGS = ("linear", "srgb")
MAX_IMAGE_SIDE = 1 << 16  # pixels; larger is a typo (or an attack), not a camera


@dataclass(frozen=True, eq=False)
class Camera:
    """A camera. Pinhole: OpenCV axes and intrinsics (pixels); orthographic: pixel_size (m/px).

    world_from_camera: (4, 4) float64 pose, camera frame -> world frame.
    distortion: (5,) OpenCV [k1, k2, p1, p2, k3] (or OpenCV's 4/8/12/14 forms) or None.
    """
    model: str
    width: int
    height: int
    world_from_camera: np.ndarray
    fx: float = None
    fy: float = None
    cx: float = None
    cy: float = None
    distortion: np.ndarray = None
    pixel_size: float = None

    @property
    def shape(self):
        """(height, width): the numpy shape of one image channel."""
        return (self.height, self.width)

    @property
    def intrinsics(self):
        """(3, 3) OpenCV camera matrix K (pinhole only)."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def centre_world(self):
        """(3,) camera-frame origin in world coordinates (pinhole, or ortho plane centre)."""
        return self.world_from_camera[:3, 3].copy()

    @property
    def rotation(self):
        """(3, 3) world_from_camera rotation part (columns: camera x, y, z axes in world)."""
        return self.world_from_camera[:3, :3].copy()

    @property
    def forward(self):
        """(3,) unit WORLD direction of the optical axis (camera +z), away from the camera."""
        return self.world_from_camera[:3, 2].copy()

    def to_world(self, v, point=True):
        """CAMERA-frame points (point=True) or directions (…, 3) -> WORLD frame, float64."""
        out = np.asarray(v, dtype=np.float64) @ self.world_from_camera[:3, :3].T
        return out + self.world_from_camera[:3, 3] if point else out

    def to_camera(self, v, point=True):
        """WORLD-frame points (point=True) or directions (…, 3) -> CAMERA frame, float64."""
        camera_from_world = np.linalg.inv(self.world_from_camera)
        out = np.asarray(v, dtype=np.float64) @ camera_from_world[:3, :3].T
        return out + camera_from_world[:3, 3] if point else out


@dataclass(frozen=True, eq=False)
class Light:
    """A photo's light. Point: position (3,) in the CAMERA frame, intensity_rgb (3,) (W/sr units
    of the photo). Directional: direction (3,) unit WORLD vector toward the light, irradiance_rgb
    (3,). Envmap: file (Path), world_from_envmap (3, 3), scale."""
    type: str
    position: np.ndarray = None
    intensity_rgb: np.ndarray = None
    direction: np.ndarray = None
    irradiance_rgb: np.ndarray = None
    file: Path = None
    world_from_envmap: np.ndarray = None
    scale: float = 1.0


@dataclass(frozen=True, eq=False)
class Photo:
    """One entry of photos[]: either `file` or `brackets` ((path, exposure_s) pairs) is set.

    `where` is the field path used in error messages ("…/scene.json: photos[2]").
    `scale_given` says whether scene.json set `scale` explicitly (ambient subtraction uses it).
    """
    index: int
    role: str
    camera: Camera
    where: str
    file: Path = None
    brackets: tuple = None
    scale: float = 1.0
    scale_given: bool = False
    light: Light = None
    encoding: str = None
    saturation: float = None

    @property
    def stem(self):
        """Name used for per-photo outputs: the file stem (first bracket's stem for brackets)."""
        path = self.file if self.file is not None else self.brackets[0][0]
        return Path(path).stem


def photo_labels(photos, folder):
    """{photo.index: name} for per-photo records (slice.json's photos[], pose shifts): the file
    stem, or, where two of `photos` share a stem (views in subfolders, ringA/img_0.jpg and
    ringB/img_0.jpg), the file relative to the scene `folder`, so that no record hides another."""
    stems = [p.stem for p in photos]
    labels = {}
    for p in photos:
        if stems.count(p.stem) == 1:
            labels[p.index] = p.stem
            continue
        path = Path(p.file if p.file is not None else p.brackets[0][0])
        try:
            labels[p.index] = path.relative_to(folder).as_posix()
        except ValueError:
            labels[p.index] = path.as_posix()
    return labels


def camera_key(camera):
    """What identifies a camera's pixel grid, intrinsics, distortion and pose, exactly: photos
    with equal keys are one view (they share primary rays, label and albedo images, ambient)."""
    return (camera.model, camera.width, camera.height, camera.fx, camera.fy, camera.cx,
            camera.cy, camera.pixel_size, np.asarray(camera.world_from_camera).tobytes(),
            None if camera.distortion is None else np.asarray(camera.distortion).tobytes())


def same_view(a, b):
    """Whether two cameras are one view (camera_key)."""
    return a is b or camera_key(a) == camera_key(b)


# OpenCV's distortion vector lengths; the contract's is 5, [k1, k2, p1, p2, k3]
DISTORTION_LENGTHS = (4, 5, 8, 12, 14)


@dataclass(frozen=True, eq=False)
class Geometry:
    """Either mesh (Path) or normal_map + mask (Paths)."""
    mesh: Path = None
    normal_map: Path = None
    mask: Path = None


# a target's pixels count when it faces the camera within 60°: a grey card is Lambertian near
# normal incidence, less so at grazing
TARGET_MIN_COS = 0.5


@dataclass(frozen=True, eq=False)
class Level:
    """How the flash's absolute level is known (scene.json "level", our extension). target_mesh:
    a diffuse target of known reflectance (a grey card, a Spectralon patch), its own mesh in the
    scene's frame and units, seen in some flash photos; reflectance (3,) in (0, 1]. calibrated:
    the flash's intensity_rgb was measured before, in the scene's units. Neither (no "level"):
    rho is known up to one factor (the flash's intensity and the scene's scale)."""
    target_mesh: Path = None
    reflectance: np.ndarray = None
    calibrated: bool = False


@dataclass(frozen=True, eq=False)
class Scene:
    folder: Path
    camera: Camera
    geometry: Geometry
    photos: list = field(default_factory=list)
    json_path: Path = None
    level: Level = None

    def photos_with_role(self, role):
        """The photos whose role is `role`, in file order."""
        return [p for p in self.photos if p.role == role]

    def flash_photos(self):
        """The `flash` photos, in file order; InputError naming photos when there is none (a
        scene of ambient or reference photos alone can be rendered, not measured)."""
        flashes = self.photos_with_role("flash")
        if not flashes:
            raise InputError(f"{self.json_path}: photos", "no photo has role 'flash'")
        return flashes

    def references(self, outputs=lambda stem: [f"{stem}.exr"]):
        """The `reference` photos, in file order, for the commands that write files per photo
        under its stem (render, run: OUT_DIR/<stem>.exr, <stem>_compare.json, ...).

        outputs(stem): the names written for one photo. InputError naming the photo's field when
        two photos would write one name (ref.exr and ref.hdr, a/ref.exr and b/ref.exr, or x and
        x_delta_e with outputs x_delta_e.png and x_delta_e.png): one would silently replace the
        other.
        """
        photos = self.photos_with_role("reference")
        written = {}
        for photo in photos:
            for name in outputs(photo.stem):
                if name in written:
                    other = written[name]
                    field = "file" if photo.file is not None else "brackets[0].file"
                    raise InputError(f"{photo.where}.{field}",
                                     f"reference photo stem {photo.stem!r} would write {name}, "
                                     f"as photos[{other.index}] ({other.stem!r}) does; give the "
                                     "reference photos distinct names")
            written.update(dict.fromkeys(outputs(photo.stem), photo))
        return photos

    def input_files(self):
        """Every file this scene reads (resolved Paths): scene.json, geometry, photos, brackets and
        environment maps, in that order without repeats. Outputs must never replace one."""
        files = [self.json_path, self.geometry.mesh, self.geometry.normal_map, self.geometry.mask,
                 None if self.level is None else self.level.target_mesh]
        for photo in self.photos:
            files.append(photo.file)
            files += [path for path, _ in photo.brackets or ()]
            if photo.light is not None:
                files.append(photo.light.file)
        return list(dict.fromkeys(f for f in files if f is not None))


def _camera(f):
    model = f.choice("model", CAMERA_MODELS)
    width = f.integer("width", maximum=MAX_IMAGE_SIDE)
    height = f.integer("height", maximum=MAX_IMAGE_SIDE)
    pose = f.array("world_from_camera", (4, 4))
    if not np.allclose(pose[3], [0, 0, 0, 1], atol=1e-9):
        f.fail("world_from_camera", "last row must be [0, 0, 0, 1]")
    f.rotation("world_from_camera", pose[:3, :3])
    f.check_coordinates("world_from_camera", pose[:3, 3].tolist())
    if model == "orthographic":
        return Camera(model, width, height, pose,
                      pixel_size=f.number("pixel_size", positive=True, factor=True))
    distortion = None
    if f.has("distortion"):
        # the contract's [k1, k2, p1, p2, k3]; OpenCV's other lengths are accepted too
        raw = f.get("distortion")
        size = len(raw) if isinstance(raw, list) else 0
        if isinstance(raw, list) and size not in DISTORTION_LENGTHS:
            f.fail("distortion", f"expected [k1, k2, p1, p2, k3] (OpenCV's 4, 8, 12 or 14 "
                                 f"coefficients are read too), got {size} numbers")
        distortion = f.array("distortion", (size if size in DISTORTION_LENGTHS else 5,))
        if not np.any(distortion):
            distortion = None
    fx, fy = (f.number(k, positive=True, factor=True) for k in ("fx", "fy"))
    cx, cy = (f.number(k) for k in ("cx", "cy"))
    for key, centre, size, focal in (("cx", cx, width, fx), ("cy", cy, height, fy)):
        problem = principal_point_problem(centre, size, focal)
        if problem:
            f.fail(key, problem)
    return Camera(model, width, height, pose, fx=fx, fy=fy, cx=cx, cy=cy, distortion=distortion)


def _light(f, folder):
    kind = f.choice("type", LIGHT_TYPES)
    if kind == "point":
        return Light(kind, position=f.array("position", (3,), coordinate=True),
                     intensity_rgb=f.array("intensity_rgb", (3,), nonnegative=True, factor=True))
    if kind == "directional":
        d = f.array("direction", (3,))
        norm = scaled_norm(d)
        if norm < 1e-9:
            f.fail("direction", "must not be the zero vector")
        return Light(kind, direction=d / norm,
                     irradiance_rgb=f.array("irradiance_rgb", (3,), nonnegative=True,
                                            factor=True))
    return Light(kind, file=f.path("file", folder),
                 world_from_envmap=f.rotation("world_from_envmap", f.array(
                     "world_from_envmap", (3, 3), default=np.eye(3))),
                 scale=f.number("scale", default=1.0, nonnegative=True, factor=True))


def _photo(f, index, folder, camera):
    role = f.choice("role", ROLES)
    if f.has("file") == f.has("brackets"):
        f.fail("", "needs exactly one of 'file' or 'brackets'")
    file = brackets = None
    if f.has("file"):
        file = f.path("file", folder)
    else:
        items = f.get("brackets")
        if not isinstance(items, list) or not items:
            f.fail("brackets", "expected a non-empty list of {file, exposure_s}")
        brackets = []
        for k, item in enumerate(items):
            b = Fields(f.json_path, f.name(f"brackets[{k}]"), item)
            brackets.append((b.path("file", folder),
                             b.number("exposure_s", positive=True, factor=True)))
        files = [path for path, _ in brackets]
        twice = next((k for k, path in enumerate(files) if path in files[:k]), None)
        if twice is not None:
            f.fail(f"brackets[{twice}].file", "the same file as an earlier bracket: each exposure "
                                              "is its own photo")
        brackets = tuple(brackets)
    light = _light(f.sub("light"), folder) if f.has("light") else None
    if role == "flash" and (light is None or light.type == "envmap"):
        f.fail("light", "a flash photo needs a point or directional light")
    encoding = f.choice("encoding", ENCODINGS) if f.has("encoding") else None
    cam = _camera(f.sub("camera")) if f.has("camera") else camera
    saturation = f.number("saturation", positive=True) if f.has("saturation") \
        else None
    return Photo(index=index, role=role, camera=cam, where=f"{f.json_path}: {f.prefix}",
                 file=file, brackets=brackets,
                 scale=f.number("scale", 1.0, positive=True, factor=True),
                 scale_given=f.has("scale"), light=light, encoding=encoding,
                 saturation=saturation)


def load_scene(scene_dir):
    """Read `scene_dir/scene.json` into a validated Scene (no images or meshes are read).

    scene_dir: folder path (or the scene.json path itself). Raises InputError on any bad field.
    """
    scene_dir = Path(scene_dir)
    json_path = scene_dir if scene_dir.suffix.lower() == ".json" else scene_dir / "scene.json"
    folder = json_path.parent.resolve()
    if not json_path.is_file():
        raise InputError(json_path, "not found (a scene folder needs a scene.json)")
    try:
        # utf-8-sig: a byte-order mark (Windows editors write one) is no JSON text
        doc = json.loads(json_path.read_text(encoding="utf-8-sig"), object_pairs_hook=no_repeats)
        check_finite(doc, str(json_path), "")
    except InputError:
        raise
    except (OSError, UnicodeDecodeError, ValueError, RecursionError) as err:
        # ValueError: json.JSONDecodeError, or an integer literal of over 4300 digits
        raise InputError(json_path, f"not valid JSON: {err}") from None
    root = Fields(str(json_path), "", doc)
    camera = _camera(root.sub("camera"))
    g = root.sub("geometry")
    if g.has("mesh") and (g.has("normal_map") or g.has("mask")):
        g.fail("", "give either 'mesh' or 'normal_map' + 'mask', not both")
    if g.has("mesh"):
        geometry = Geometry(mesh=g.path("mesh", folder))
    elif g.has("normal_map"):
        geometry = Geometry(normal_map=g.path("normal_map", folder), mask=g.path("mask", folder))
    else:
        g.fail("", "needs 'mesh' or 'normal_map' + 'mask'")
    items = root.get("photos")
    if not isinstance(items, list) or not items:
        root.fail("photos", "expected a non-empty list")
    photos = [_photo(Fields(str(json_path), f"photos[{i}]", p), i, folder, camera)
              for i, p in enumerate(items)]
    if geometry.normal_map is not None:
        for photo in photos:
            if not same_view(photo.camera, camera):
                # its normals and mask are the scene camera's pixels: another view would be
                # rendered through them, rotated by the other pose (a torus: ΔE-log 16 where the
                # true BRDF gives 1.2)
                Fields(str(json_path), f"photos[{photo.index}]", {}).fail(
                    "camera", "differs from the scene's camera, and a normal map gives the "
                              "surface seen from the scene's camera only: give a mesh for "
                              "several views")
    level = _level(root.sub("level"), folder, geometry) if root.has("level") else None
    return Scene(folder=folder, camera=camera, geometry=geometry, photos=photos,
                 json_path=json_path.resolve(), level=level)


def _level(f, folder, geometry):
    """scene.json "level": {"target": {"mesh": FILE, "reflectance": r | [r, g, b]}} or
    {"calibrated": true}."""
    if f.has("target") == f.has("calibrated"):
        f.fail("", "give either 'target' (a diffuse target of known reflectance) or "
                   "'calibrated': true (a flash measured before)")
    if f.has("calibrated"):
        if f.get("calibrated") is not True:
            f.fail("calibrated", "expected true (leave \"level\" out for a relative level)")
        return Level(calibrated=True)
    t = f.sub("target")
    if geometry.mesh is None:
        t.fail("", "a target needs mesh geometry (a normal map has no depth to place it)")
    value = t.get("reflectance")
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        reflectance = np.full(3, float(value))
    else:
        reflectance = t.array("reflectance", (3,))
    if not np.all((reflectance > 0) & (reflectance <= 1)):
        got = ", ".join(f"{v:.6g}" for v in reflectance)   # np.round overflows on 1e308
        t.fail("reflectance", f"expected values in (0, 1], got [{got}]")
    return Level(target_mesh=t.path("mesh", folder), reflectance=reflectance)
