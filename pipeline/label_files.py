"""Label files: LABELS.png (16-bit, the first flash photo's pixel grid, 0 = background or unused,
1..K the material), LABELS.faces.npy beside it (int32 per mesh face; unseen faces take the nearest
seen face's label, of their own connected part when it has one) and LABELS.json (K and why).
Written together through temporary files and renamed, so a failure leaves none of them; read back
with every check `render --labels` and `extract --labels` need (a lossy format is refused: its
compression changes labels at borders).
"""

import contextlib
import json
from pathlib import Path

import cv2
import numpy as np

from flashbrdf.capture import load_mesh, scene_intersector, surface_sample
from flashbrdf.capture.photo import imread_unchanged
from flashbrdf.files.atomic import atomic_path
from flashbrdf.files.errors import DECODE_ERRORS, InputError
from flashbrdf.slice_extract.segment import check_labels, face_label_agreement

FACES_AGREE = 0.5  # share of labelled pixels whose face carries their label, at least
FACES_SAMPLE = 20_000  # pixels traced to measure it (the whole flash view at 24 MP: seconds)


def flash_photo_camera(scene, where):
    """The first flash photo's camera (the pixel grid of labels and albedo maps)."""
    flash = scene.photos_with_role("flash")
    if not flash:
        raise InputError(f"{scene.json_path}: photos", f"{where} needs the flash photo's camera: "
                                                       "no photo has role 'flash'")
    return flash[0].camera


def faces_path(labels_png):
    """LABELS.faces.npy beside LABELS.png."""
    labels_png = Path(labels_png)
    return labels_png.with_name(labels_png.stem + ".faces.npy")


def write_labels(out, segmentation, faces, extra=None):
    """Write LABELS.png (+ LABELS.faces.npy, LABELS.json), all or none."""
    out = Path(out)
    report = {"materials": segmentation.k, "criterion": segmentation.criterion,
              "pixels": {str(k): int(np.count_nonzero(segmentation.labels == k))
                         for k in range(1, segmentation.k + 1)}, **(extra or {})}
    with contextlib.ExitStack() as stack:
        png = stack.enter_context(atomic_path(out, suffix=".png"))
        if not cv2.imwrite(png, segmentation.labels.astype(np.uint16)):
            raise InputError(out, "cannot write a PNG there")
        if faces is not None:
            npy = stack.enter_context(atomic_path(faces_path(out), suffix=".npy"))
            with open(npy, "wb") as f:
                np.save(f, faces.astype(np.int32))
        js = stack.enter_context(atomic_path(out.with_suffix(".json"), suffix=".json"))
        Path(js).write_text(json.dumps(report, indent=1) + "\n")


def _webp_image_chunk(f):
    """The fourcc of a WebP file's image chunk ("VP8 " lossy, "VP8L" lossless) or None; f is open
    at byte 12, past the RIFF header. An extended file (VP8X) holds it after other chunks."""
    for _ in range(64):  # VP8X, ICCP, ANIM, ALPH, ... precede it
        head = f.read(8)
        if len(head) < 8:
            return None
        fourcc, size = head[:4], int.from_bytes(head[4:], "little")
        if fourcc in (b"VP8 ", b"VP8L", b"ANMF"):
            return fourcc.decode()
        f.seek(size + (size & 1), 1)
    return None


# TIFF Compression (tag 259) values of lossy codecs: old-style and new JPEG, DNG's lossy JPEG,
# JPEG 2000, WebP, JPEG XL (the last three refused whole, as a .jp2 is)
_TIFF_LOSSY = {6: "JPEG", 7: "JPEG", 34892: "JPEG", 34712: "JPEG 2000", 50001: "WebP",
               50002: "JPEG XL"}


def _tiff_compression(f, head):
    """The Compression tag (259) of a TIFF's first image (the one OpenCV reads) or None; head is
    the file's first 12 bytes, f open past them. Classic TIFF and BigTIFF, either byte order."""
    order = {b"II": "little", b"MM": "big"}.get(head[:2])
    magic = int.from_bytes(head[2:4], order or "little")
    if order is None or magic not in (42, 43):
        return None
    big = magic == 43
    if big:  # the first directory's offset: 8 bytes at byte 8 (BigTIFF), else 4 at byte 4
        f.seek(8)
        offset = int.from_bytes(f.read(8), order)
    else:
        offset = int.from_bytes(head[4:8], order)
    if offset >= 1 << 62:  # past any file (and past what seek takes)
        return None
    f.seek(offset)
    count = int.from_bytes(f.read(8 if big else 2), order)
    size = 20 if big else 12
    for _ in range(min(count, 4096)):
        entry = f.read(size)
        if len(entry) < size:
            return None
        if int.from_bytes(entry[:2], order) == 259:
            kind = int.from_bytes(entry[2:4], order)  # SHORT (3) or LONG (4), in the entry
            value = entry[12:] if big else entry[8:]
            return int.from_bytes(value[:2] if kind == 3 else value[:4], order)
    return None


def lossy_format(path):
    """"JPEG", "JPEG 2000", "lossy WebP" or "TIFF compressed as ..." (a lossy TIFF codec) when the
    file's first bytes say so, else None (the name's suffix is not asked: a JPEG named .png is
    still a JPEG). InputError when the file cannot be read. JPEG 2000 is refused whole: its
    lossless mode is rare and not told by the header."""
    try:
        with open(path, "rb") as f:
            head = f.read(12)
            if head[:3] == b"\xff\xd8\xff":
                return "JPEG"
            if head[:4] == b"\xff\x4f\xff\x51" or head == b"\x00\x00\x00\x0cjP  \r\n\x87\n":
                return "JPEG 2000"
            if (head[:4] == b"RIFF" and head[8:12] == b"WEBP"
                    and _webp_image_chunk(f) in ("VP8 ", "ANMF")):
                return "lossy WebP"  # VP8L is WebP's lossless form; an animation is no label image
            lossy = _TIFF_LOSSY.get(_tiff_compression(f, head))
            if lossy:  # a TIFF of JPEG tiles decodes to one channel too
                return f"TIFF compressed as {lossy}"
    except OSError as err:
        raise InputError(path, f"cannot be read ({err.strerror or err})") from None
    return None


def read_labels(path, shape):
    """A label image (H, W) int from LABELS.png; InputError if unreadable, not `shape`, or a
    label in 1..K has no pixel."""
    path = Path(path)
    if not path.is_file():
        raise InputError(path, "is a folder, not a label image" if path.is_dir() else
                         "label image not found")
    lossy = lossy_format(path)
    if lossy:  # its compression moves values at every border: a label becomes another
        raise InputError(path, f"is a {lossy}, whose lossy compression changes labels at the "
                               "borders between materials: write labels as a PNG")
    labels = imread_unchanged(path)
    if labels is None or labels.ndim != 2:
        raise InputError(path, "is not a single-channel (16-bit) label PNG")
    if labels.dtype.kind not in "iu":  # a float TIFF: 1.5 or NaN is no label
        raise InputError(path, f"holds {labels.dtype} values; labels are integers (a 16-bit PNG)")
    labels = labels.astype(np.int64)
    check_labels(labels, shape, path)
    return labels


def read_npy(path):
    """The array of a .npy file; InputError naming it when it is damaged or an .npz archive."""
    try:
        array = np.load(path, allow_pickle=False)
    except DECODE_ERRORS as err:  # EOFError for an empty file
        raise InputError(path, f"cannot be read as a .npy array ({err})") from None
    if not isinstance(array, np.ndarray):  # np.load opened a .npz archive
        raise InputError(path, "is a .npz archive, not a .npy array")
    return array


def read_face_labels(labels_png, count, scene, labels, intersector=None):
    """LABELS.faces.npy beside LABELS.png: (F,) int labels 1..count, one per mesh face, or None
    when there is no such file. InputError when it is not that (or not the mesh's face count),
    or when it disagrees with the label image `labels` (H, W) on most of the object's labelled
    pixels (faces_agree; intersector: the scene mesh's, when the caller has one)."""
    npy = faces_path(labels_png)
    if not npy.is_file():
        return None
    faces = read_npy(npy)
    if faces.ndim != 1 or faces.dtype.kind not in "iu" or (
            len(faces) and (faces.min() < 1 or faces.max() > count)):
        raise InputError(npy, f"must be one label 1..{count} per face (int)")
    if scene.geometry.mesh is not None:
        n_faces = len(load_mesh(scene.geometry.mesh)[0].faces)
        if len(faces) != n_faces:
            raise InputError(npy, f"has {len(faces)} labels but the mesh has {n_faces} faces")
        faces_agree(npy, faces, labels, scene, Path(labels_png).name, intersector)
    return faces


def faces_agree(npy, faces, labels, scene, png_name, intersector=None):
    """InputError naming the faces file when the faces the flash camera sees carry another label
    than their pixels in LABELS.png on over half of the object's labelled pixels: a faces file
    left from another label image (relabelled, or renumbered) would put each material on the
    other's faces in every other view. Faces straddling a border disagree on a few percent.
    intersector: the scene mesh's, when the caller has built one (else built here)."""
    camera = flash_photo_camera(scene, "--labels")
    # a share that close to 0 or 1 needs no more than a sample of the view
    surface = surface_sample(intersector or scene_intersector(scene), camera, FACES_SAMPLE)
    share = face_label_agreement(labels[surface.rows, surface.cols], surface.face, faces)
    if share is not None and share < FACES_AGREE:
        raise InputError(npy, f"disagrees with {png_name} on "
                              f"{1 - share:.0%} of the object's labelled pixels in the "
                              "flash view: it belongs to another label image (write both with "
                              "`segment`, or delete it to label only the flash view)")


def material_map_inputs(scene, labels_png, count):
    """(labels (H, W), face labels (F,) or None, flash camera) for rendering `count` tables
    with LABELS.png (+ LABELS.faces.npy when present); InputError for a wrong size, an unused
    label, a label count that is not `count`, or a faces file that does not fit the mesh."""
    camera = flash_photo_camera(scene, "--labels")
    labels = read_labels(labels_png, camera.shape)
    check_labels(labels, camera.shape, labels_png, count)
    return labels, read_face_labels(labels_png, count, scene, labels), camera
