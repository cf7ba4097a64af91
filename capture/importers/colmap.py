"""A photogrammetry reconstruction of flash photos -> a scene folder (the contract's import-colmap).

    import_colmap(model_dir, images_dir, mesh, out_dir, flash_offset=(0, 0, 0),
                  intensity=None, force=False, ...) -> ColmapImport (.lines(): the summary)

Each registered model image whose file stem matches a photo in `images_dir` becomes a `flash`
photo with its own camera (several COLMAP cameras per model are kept apart), lit by a point
light at `flash_offset` in its camera frame. SfM may have run on JPEGs while the flash photos are
RAW or EXR files of the same names; a model image named sub/x.jpg is looked for in images_dir/sub
when that folder exists, else in images_dir.

Nothing is copied and nothing is written inside `images_dir`: scene.json refers to the photos and
the mesh by paths relative to the scene folder (climbing out of it with `..` where needed, as the
contract's "relative to the folder" allows), so moving the scene folder together with the photos
keeps it working. The folder is built aside and renamed into place when complete.
"""

import os
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath

import numpy as np

from flashbrdf.capture.importers.colmap_model import camera_model_name, read_colmap_model
from flashbrdf.capture.importers.mesh_frame import (check_mesh_frame, require_mesh_in_frame,
                                                    require_target_facing_a_camera)
from flashbrdf.capture.importers.scene_json import dumps_scene
from flashbrdf.capture.photo import FLOAT_EXTENSIONS, PHOTO_EXTENSIONS, RAW_EXTENSIONS
from flashbrdf.capture.scene import TARGET_MIN_COS
from flashbrdf.capture.scene_fields import (
    MAX_COORDINATE,
    MAX_FACTOR,
    MIN_FACTOR,
    beyond_coordinates,
)
from flashbrdf.files.errors import InputError, library_error
from flashbrdf.files.outputs import check_outputs, path_inside, staged_output_dir

LISTED_NAMES = 8          # skipped images named on stdout; the rest are counted


@dataclass(eq=False)
class ColmapImport:
    """What import_colmap did: out_dir, the ColmapModel, matched [(ModelImage, photo Path)],
    skipped (registered images without a photo), cameras {camera_id: (COLMAP model name,
    contract camera dict of its first photo, photos)}, mean reprojection error (px or None),
    frame (mesh_frame.FrameCheck), the scene dict written, oriented (names of the photos whose
    EXIF orientation is not 1: used as stored, as COLMAP does)."""
    out_dir: Path
    model: object
    matched: list
    skipped: list
    cameras: dict
    reprojection_error: float
    frame: object
    scene: dict = field(default_factory=dict)
    oriented: list = field(default_factory=list)

    def lines(self):
        """The summary printed on stdout, one string per line."""
        m = self.model
        rigs = "with" if m.rigs_and_frames else "without"
        out = [f"read {m.format} model {m.folder} ({rigs} rigs and frames): "
               f"{len(m.reconstruction.cameras)} cameras, {len(m.images)} registered images"
               + (f" ({len(m.unregistered)} unregistered)" if m.unregistered else "")
               + f", {m.reconstruction.num_points3D()} 3D points"]
        out.append(f"matched {len(self.matched)} images to photos; skipped {len(self.skipped)} "
                   "with no photo" + _named(self.skipped))
        if self.oriented:
            out.append(f"{len(self.oriented)} photos carry an EXIF orientation other than 1 "
                       "(their pixels are used as stored, as COLMAP uses them; if SfM ran on "
                       "copies turned upright, give those)" + _named(self.oriented))
        for camera_id, (name, cam, count) in sorted(self.cameras.items()):
            dist = f", distortion {_short(cam['distortion'])}" if "distortion" in cam else ""
            out.append(f"camera {camera_id}: {name} {cam['width']}x{cam['height']}, fx "
                       f"{cam['fx']:.6g} fy {cam['fy']:.6g} cx {cam['cx']:.6g} cy "
                       f"{cam['cy']:.6g} (pixel centres at 0){dist}; {count} photos")
        if self.reprojection_error is not None:
            error = f"{self.reprojection_error:.3g} px"
        else:   # no points, or pycolmap failed on them (a non-finite result or an exception)
            error = "n/a (no 3D points)" if not self.frame.points else "n/a (not computable)"
        out.append(f"mean reprojection error: {error}")
        f = self.frame
        if f.points:
            sample = "" if f.points == m.reconstruction.num_points3D() else " sampled"
            out.append(f"3D points on the mesh: {100 * f.share_on_mesh:.1f}% ({f.on_mesh} of "
                       f"{f.points}{sample} points within {f.tolerance:.3g} model units); "
                       f"hidden by it: {f.hidden}; cameras seeing it: {f.views_seeing} of "
                       f"{f.views}")
        else:
            out.append(f"3D points on the mesh: n/a (the model has no 3D points); cameras "
                       f"seeing it: {f.views_seeing} of {f.views}")
        light = self.scene["photos"][0]["light"]
        out.append(f"wrote {self.out_dir}: {len(self.matched)} flash photos, point light at "
                   f"{_short(light['position'])} (camera frame, model units), intensity "
                   f"{_short(light['intensity_rgb'])}")
        return out


def _named(names):
    if not names:
        return ""
    shown = ", ".join(names[:LISTED_NAMES])
    more = f" and {len(names) - LISTED_NAMES} more" if len(names) > LISTED_NAMES else ""
    return f": {shown}{more}"


def _short(values):
    return "[" + ", ".join(f"{v:.4g}" for v in values) + "]"


def _triple(values, where, positive=False):
    """Three finite numbers (list of floats); positive: each in MIN_FACTOR..MAX_FACTOR, else
    each within ±MAX_COORDINATE (a position)."""
    try:
        out = [float(v) for v in values]
    except (TypeError, ValueError):
        raise InputError(where, f"expected 3 numbers, got {values!r}") from None
    if len(out) != 3 or not all(np.isfinite(out)):
        raise InputError(where, f"expected 3 finite numbers, got {values!r}")
    if positive and not all(MIN_FACTOR <= v <= MAX_FACTOR for v in out):
        raise InputError(where, f"expected 3 positive numbers within {MIN_FACTOR:g}.."
                                f"{MAX_FACTOR:g}, got {out}")
    odd = None if positive else beyond_coordinates(out)
    if odd is not None:
        raise InputError(where, f"{odd:.6g} is beyond ±{MAX_COORDINATE:g} (rays are 32-bit floats)")
    return out


class _PhotoFolders:
    """The photos of each folder under --images, by stem, read once per folder."""

    def __init__(self, root):
        self.root = Path(root)
        self.listed = {}

    def folder_for(self, name):
        """The folder where model image `name` (COLMAP's relative name) has its photo."""
        parts = PurePosixPath(name.replace("\\", "/")).parent.parts
        if parts and ".." not in parts and not parts[0].startswith("/"):
            sub = self.root.joinpath(*parts)
            if sub.is_dir():
                return sub
        return self.root

    def photos(self, folder, stem):
        if folder not in self.listed:
            found = {}
            try:
                names = sorted(e.name for e in os.scandir(folder) if e.is_file())
            except OSError as err:
                raise InputError(folder, f"cannot list the photos: {err}") from None
            for name in names:
                path = Path(name)
                if path.suffix.lower() in PHOTO_EXTENSIONS:
                    found.setdefault(path.stem, []).append(folder / name)
            self.listed[folder] = found
        return self.listed[folder].get(stem, [])


def match_photos(model, images_dir):
    """([(ModelImage, photo Path)], [names of registered images with no photo]) by file stem.

    InputError naming the photo when two photos share the stem of a model image, or when one
    photo would serve two model images."""
    folders = _PhotoFolders(images_dir)
    matched, skipped, claimed = [], [], {}
    for image in model.images:
        stem = PurePosixPath(image.name.replace("\\", "/")).stem
        found = folders.photos(folders.folder_for(image.name), stem)
        if not found:
            skipped.append(image.name)
            continue
        if len(found) > 1:
            raise InputError(found[1], f"{found[0].name} and {found[1].name} share the stem "
                                       f"{stem!r} of model image {image.name}: keep one photo "
                                       "per stem in --images (e.g. the flash RAW files in a "
                                       "folder of their own)")
        if found[0] in claimed:
            first = claimed[found[0]]
            if first.name == image.name:   # the model's own fault: no photo layout can fix it
                images_file = Path(model.folder) / ("images.txt" if model.format == "text"
                                                    else "images.bin")
                raise InputError(images_file, f"images {first.image_id} and {image.image_id} "
                                              f"are both named {image.name}: a damaged model "
                                              "(reconstruct, or remove one)")
            raise InputError(found[0], f"is the photo of two model images, {first.name} "
                                       f"and {image.name} (matched by stem): give each its own "
                                       "photo, in subfolders named as in the model")
        claimed[found[0]] = image
        matched.append((image, found[0]))
    return matched, skipped


def photo_size(path):
    """(width, height) of a photo as capture.load_photo decodes it, from its header only."""
    return photo_header(path)[:2]


def photo_header(path):
    """(width, height, EXIF orientation, stores floats) of a photo as capture.load_photo
    decodes it, from its header only. Pixels are used as stored, as COLMAP uses them (it
    ignores the EXIF orientation so that one camera serves photos held either way); the
    orientation (1 = as stored, 5-8 a quarter turn) is returned to name it when sizes disagree.
    RAW: LibRaw turns the image by its own flag on decoding, so the decoded size already holds
    it (orientation 1)."""
    path = Path(path)
    ext = path.suffix.lower()
    if ext in RAW_EXTENSIONS:
        import rawpy
        try:
            with rawpy.imread(str(path)) as raw:
                sizes = raw.sizes
        except (rawpy.LibRawError, OSError, ValueError) as err:
            raise InputError(path, f"cannot read RAW file: {err}") from None
        turned = sizes.flip in (5, 6)   # LibRaw turns the image a quarter on output
        return (sizes.height, sizes.width, 1, False) if turned else \
            (sizes.width, sizes.height, 1, False)
    if ext == ".pfm":
        from flashbrdf.capture.photo import read_pfm
        rgb = read_pfm(path)
        return rgb.shape[1], rgb.shape[0], 1, True
    import OpenImageIO as oiio
    image = oiio.ImageInput.open(str(path))
    if image is None:
        raise InputError(path, f"cannot read image: {library_error(oiio, 'unknown format')}")
    try:
        spec = image.spec()
    finally:
        image.close()
    orientation = spec.get_int_attribute("Orientation", 1)
    stored_float = ext in FLOAT_EXTENSIONS or spec.format.basetype in (
        oiio.FLOAT, oiio.HALF, oiio.DOUBLE)
    if ext in FLOAT_EXTENSIONS and spec.full_width > 0 and spec.full_height > 0:
        # capture places a data window in it
        return spec.full_width, spec.full_height, orientation, stored_float
    return spec.width, spec.height, orientation, stored_float


def _relative(path, scene_folder):
    """`path` relative to the (future) scene folder `scene_folder` (a real path). The folders
    are compared as real paths, as capture.load_scene resolves the scene folder before joining,
    so `..` climbs from where it really is; the file name is kept as given, so a photo that is a
    link stays the link (a folder of links picking some photos keeps working)."""
    path = Path(os.path.abspath(path))
    folder = os.path.relpath(os.path.realpath(path.parent), scene_folder)
    return (Path(folder) / path.name).as_posix()


def import_colmap(model_dir, images_dir, mesh, out_dir, flash_offset=(0.0, 0.0, 0.0),
                  intensity=None, force=False, target=None, reflectance=None,
                  calibrated=False, encoding=None):
    """Write the scene folder `out_dir` for a COLMAP sparse model, its flash photos in
    `images_dir` and a mesh in the model's frame. Returns a ColmapImport.

    flash_offset: the flash position in each camera's frame (model units); intensity: its
    intensity_rgb (None: 1, 1, 1, a relative level; calibrated needs it given); force: replace
    an out_dir that flashbrdf made. The level (scene.json "level", slice_extract.level):
    target, a mesh of a diffuse target in the model's frame, with its reflectance (3 numbers in
    (0, 1]); or calibrated, the intensity was measured before; neither: relative. encoding:
    every photo's scene.json "encoding" ("linear" or "srgb"; None: by bit depth, 8-bit sRGB and
    16-bit linear), for 16-bit TIFF/PNG a converter wrote with the sRGB curve. InputError (exit
    2) naming the file or field for bad input; then nothing is written.
    """
    from flashbrdf.capture.geometry import MeshIntersector, load_mesh
    offset = _triple(flash_offset, "--flash-offset")
    if calibrated and intensity is None:   # else the placeholder 1,1,1 passes as measured
        raise InputError("--calibrated", "needs --intensity R,G,B: the flash's intensity measured "
                                         "before (docs/capture.md, \"The absolute level\")")
    power = _triple((1.0, 1.0, 1.0) if intensity is None else intensity, "--intensity",
                    positive=True)
    level = _level(target, reflectance, calibrated)
    images_dir, mesh, out_dir = Path(images_dir), Path(mesh), Path(out_dir)
    if not images_dir.is_dir():
        raise InputError(images_dir, "not a folder (--images names the folder of the flash "
                                     "photos)")
    check_outputs(inputs=[model_dir, images_dir, mesh, target], outputs=[out_dir],
                  folders=[out_dir])
    if path_inside(os.path.realpath(out_dir), os.path.realpath(images_dir)):
        raise InputError(out_dir, f"is inside --images {images_dir}: import-colmap writes "
                                  "nothing there; give a folder beside it")
    model = read_colmap_model(model_dir)
    matched, skipped = match_photos(model, images_dir)
    if not matched:
        example = model.images[0].name
        raise InputError(images_dir, f"holds no photo for any of the model's {len(model.images)} "
                                     f"registered images (matched by file stem: {example} needs "
                                     f"{PurePosixPath(example).stem}.exr, .dng, .jpg, ...)")
    check_outputs(inputs=[p for _, p in matched], outputs=[out_dir], folders=[out_dir])
    scene_folder = os.path.realpath(out_dir)
    cameras, photos, oriented = {}, [], []
    for image, photo in matched:
        cam = model.contract_camera(image.camera_id, image.world_from_camera)
        *size, orientation, stored_float = photo_header(photo)
        if tuple(size) != (cam["width"], cam["height"]):
            turned = (f"; its EXIF orientation {orientation} asks viewers to turn it a quarter, "
                      "which COLMAP does not do and flashbrdf neither: give the pixels SfM saw"
                      if orientation in (5, 6, 7, 8) else "")
            raise InputError(photo, f"image is {size[0]}x{size[1]} but its camera "
                                    f"{image.camera_id} in {model.files['cameras'].name} is "
                                    f"{cam['width']}x{cam['height']} (photos must be the "
                                    f"images the model was made from, uncropped and unturned"
                                    f"{turned})")
        if orientation != 1:
            oriented.append(photo.name)
        if encoding == "srgb" and (stored_float or photo.suffix.lower() in RAW_EXTENSIONS):
            raise InputError("--encoding", f"srgb is for 8- and 16-bit PNG/TIFF/JPEG; {photo.name} "
                                           "is linear by its format (floats or RAW)")
        kind, first, count = cameras.get(image.camera_id, (
            camera_model_name(model.reconstruction.camera(image.camera_id)), cam, 0))
        cameras[image.camera_id] = (kind, first, count + 1)
        photos.append({"file": _relative(photo, scene_folder), "role": "flash", "camera": cam,
                       **({"encoding": encoding} if encoding else {}),
                       "light": {"type": "point", "position": offset, "intensity_rgb": power},
                       "source": {"model_image": image.name, "image_id": image.image_id,
                                  "camera_id": image.camera_id}})
    loaded, has_normals = load_mesh(mesh)
    points, observed, observers = model.sight_lines()
    object_rays = MeshIntersector(loaded, has_normals)
    frame = check_mesh_frame(object_rays, points, observed, observers,
                             [p["camera"] for p in photos])
    require_mesh_in_frame(frame, mesh)
    error = model.mean_reprojection_error()
    scene = {"camera": photos[0]["camera"], "geometry": {"mesh": _relative(mesh, scene_folder)},
             "photos": photos,
             "provenance": _provenance(model, images_dir, mesh, skipped, error, frame)}
    if level is not None:
        if "target" in level:
            card, card_normals = load_mesh(target)
            require_target_facing_a_camera(card, card_normals, [p["camera"] for p in photos],
                                           TARGET_MIN_COS, target, occluder=object_rays)
            level["target"]["mesh"] = _relative(Path(target), scene_folder)
        scene["level"] = level
    with staged_output_dir(out_dir, force=force, command="import-colmap") as staged:
        Path(staged, "scene.json").write_text(dumps_scene(scene), encoding="utf-8")
    return ColmapImport(out_dir, model, matched, skipped, cameras, error, frame, scene, oriented)


def _level(target, reflectance, calibrated):
    """scene.json's "level" from the importer's options, or None (a relative level)."""
    if target is not None and calibrated:
        raise InputError("--calibrated", "give either --target (a diffuse target in the photos) "
                                         "or --calibrated (a flash measured before), not both")
    if calibrated:
        return {"calibrated": True}
    if target is None:
        if reflectance is not None:
            raise InputError("--reflectance", "is the reflectance of --target: give both")
        return None
    if not Path(target).is_file():
        raise InputError(target, "target mesh not found")
    if reflectance is None:
        raise InputError("--reflectance", "--target needs the target's reflectance (e.g. "
                                          "--reflectance 0.18 for a grey card)")
    values = _triple(reflectance, "--reflectance")
    if not all(0 < v <= 1 for v in values):
        raise InputError("--reflectance", f"expected 3 values in (0, 1], got {values}")
    return {"target": {"mesh": None, "reflectance": values}}


def _provenance(model, images_dir, mesh, skipped, error, frame):
    import pycolmap
    return {
        "importer": "flashbrdf import-colmap",
        "model": os.path.abspath(model.folder), "model_format": model.format,
        "rigs_and_frames": model.rigs_and_frames,
        "pycolmap": getattr(pycolmap, "__version__", "unknown"),
        "images": os.path.abspath(images_dir), "mesh": os.path.abspath(mesh),
        "conventions": "cx, cy = COLMAP's minus 0.5 (pixel centres at 0); world_from_camera = "
                       "inverse of COLMAP's cam_from_world; distortion = OpenCV's [k1, k2, p1, "
                       "p2, k3] (FULL_OPENCV: [k1, k2, p1, p2, k3, k4, k5, k6])",
        "registered_images": len(model.images), "unregistered_images": len(model.unregistered),
        "skipped_images": len(skipped), "skipped_names": skipped[:100],
        "mean_reprojection_error_px": error,
        "points_on_mesh": {"checked": frame.points, "on_mesh": frame.on_mesh,
                           "hidden": frame.hidden, "tolerance": frame.tolerance,
                           "sight_lines": frame.observations,
                           "sight_lines_on_mesh": frame.on_observations,
                           "sight_lines_hidden": frame.hidden_observations},
    }
