"""Photo loading: every photo becomes float32 linear RGB (H, W, 3) plus a "usable" mask (H, W).

Formats (chosen by extension, then by the stored bit depth):
- .exr .hdr (and float TIFF): OpenImageIO, values as stored; .pfm: parsed here (rows flipped to
  top-first, which OpenImageIO does not do).
- 16-bit .png/.tif: OpenCV IMREAD_UNCHANGED (imageio/Pillow silently drop to 8 bits), BGR->RGB,
  code / 65535, linear unless encoding == "srgb".
- 8-bit .png/.jpg/.tif: code / 255 through the inverse sRGB EOTF unless encoding == "linear".
- camera RAW (.dng .cr2 .nef ...): rawpy (imported only here, lazily), see capture.raw.

A pixel is unusable (never clamped, just flagged) when any channel is NaN/Inf, when any channel is
at or above the clipping level (integer codes >= SATURATION_FRACTION x max code: sensors turn
non-linear in the top few percent, and 12/14-bit data rescaled to 16 bits tops out below 65535;
float images: photos[].saturation if given), or when it carries no signal: any channel at code 0
for integer images (at the black level, so the true value is unknown), or every channel exactly 0
for float images (a float image has no code floor: one dark channel, and negative noise about a
dim level, are data).
"""

import os
from pathlib import Path

import cv2
import numpy as np
import OpenImageIO as oiio

from flashbrdf.files.errors import InputError, library_error, no_file

SATURATION_FRACTION = 0.98
FLOAT32_MAX = float(np.finfo(np.float32).max)
MAX_IMAGE_PIXELS = 1 << 28  # 268 M: above any camera's sensor or a 16K x 8K envmap
FLOAT_EXTENSIONS = (".exr", ".hdr", ".pfm")
CV_EXTENSIONS = (".png", ".tif", ".tiff", ".jpg", ".jpeg")
RAW_EXTENSIONS = (".dng", ".cr2", ".cr3", ".crw", ".nef", ".nrw", ".arw", ".srf", ".sr2", ".orf",
                  ".rw2", ".raf", ".pef", ".srw", ".raw", ".rwl", ".3fr", ".erf", ".kdc", ".dcr",
                  ".mrw", ".mos", ".iiq", ".x3f")
PHOTO_EXTENSIONS = FLOAT_EXTENSIONS + CV_EXTENSIONS + RAW_EXTENSIONS


def srgb_to_linear(values):
    """Inverse sRGB EOTF (IEC 61966-2-1), exact piecewise form. values in [0, 1] -> linear."""
    v = np.asarray(values, dtype=np.float32)
    return np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4).astype(np.float32)


def _to_rgb(img, path):
    """(H, W) / (H, W, C) channel-last image -> (H, W, 3) RGB (grey replicated, alpha dropped)."""
    if img.ndim == 2:
        img = img[..., None]
    if img.ndim != 3 or img.shape[2] == 0:
        raise InputError(path, f"unexpected image shape {img.shape}")
    if img.shape[2] in (1, 2):
        return np.repeat(img[..., :1], 3, axis=2)
    return img[..., :3]


def read_float_image(path, require_float=False):
    """Read an image through OpenImageIO as float32 (H, W, 3) RGB: channels R, G, B by name, or
    a grey Y replicated; a .pfm through read_pfm, top row first. InputError naming the file when
    missing, unreadable, of other channels (A alone, R and G, X Y Z), or, with require_float,
    when it stores integer codes (an 8-bit PNG named .exr), whose scale and curve are unknown."""
    path = Path(path)
    if not path.is_file():
        raise no_file(path)
    if path.suffix.lower() == ".pfm":  # OpenImageIO gives PFM rows bottom first
        return read_pfm(path)
    inp = oiio.ImageInput.open(str(path))
    if inp is None:
        raise InputError(path, f"cannot read image: {library_error(oiio, 'unknown format')}")
    try:
        spec = inp.spec()
        for what, width, height in (("image", spec.width, spec.height),
                                    ("display window", spec.full_width, spec.full_height)):
            if width * height > MAX_IMAGE_PIXELS:
                raise InputError(path, f"{what} of {width}x{height} pixels is larger than any "
                                       f"photo or map read here ({MAX_IMAGE_PIXELS} pixels)")
        data = inp.read_image(0, 0, 0, spec.nchannels, oiio.FLOAT)
        if data is None:
            raise InputError(path, f"cannot read image: {library_error(inp, 'corrupt data')}")
        names = [n.split(".")[-1].upper() for n in spec.channelnames]
        stored = spec.format.basetype
        if require_float and stored not in (oiio.BASETYPE.FLOAT, oiio.BASETYPE.HALF,
                                            oiio.BASETYPE.DOUBLE):
            raise InputError(path, f"holds {inp.format_name()} integer codes "
                                   f"({stored.name.lower()}), not floats: name it for what it is "
                                   "(.png, .tif, ...)")
    finally:
        inp.close()
    data = np.asarray(data, dtype=np.float32).reshape(spec.height, spec.width, spec.nchannels)
    if names[:3] == ["R", "G", "B"]:
        data = data[..., :3]
    elif all(c in names for c in "RGB"):
        data = data[..., [names.index(c) for c in "RGB"]]
    elif "Y" in names and set(names) <= {"Y", "A"}:   # grey, maybe with alpha; not X, Y, Z
        data = np.repeat(data[..., names.index("Y"):names.index("Y") + 1], 3, axis=2)
    else:
        raise InputError(path, f"channels {', '.join(names) or 'none'}: expected R, G and B, or "
                               "a grey Y")
    data = np.ascontiguousarray(_to_rgb(data, path))
    window = (spec.x, spec.y, spec.width, spec.height)
    full = (spec.full_x, spec.full_y, spec.full_width, spec.full_height)
    if window != full and spec.full_width > 0 and spec.full_height > 0:
        # a cropped data window (EXR): place it in the display window; outside is no data
        canvas = np.full((spec.full_height, spec.full_width, 3), np.nan, dtype=np.float32)
        x0, y0 = spec.x - spec.full_x, spec.y - spec.full_y
        xs, ys = max(x0, 0), max(y0, 0)
        xe, ye = min(x0 + spec.width, spec.full_width), min(y0 + spec.height, spec.full_height)
        if xe > xs and ye > ys:
            canvas[ys:ye, xs:xe] = data[ys - y0:ye - y0, xs - x0:xe - x0]
        data = canvas
    return data


def read_pfm(path):
    """Read a PFM (Portable Float Map) as float32 (H, W, 3), top row first.

    Parsed here rather than through OpenImageIO, whose reader returns PFM rows in stored order
    (the format stores them bottom to top). The scale's sign gives the byte order.
    """
    path = Path(path)
    try:
        with open(path, "rb") as f:
            kind = f.readline().strip()
            dims = f.readline().split()
            while dims and dims[0].startswith(b"#"):
                dims = f.readline().split()
            width, height = int(dims[0]), int(dims[1])
            scale = float(f.readline().strip())
            data = np.fromfile(f, dtype="<f4" if scale < 0 else ">f4")
    except (OSError, ValueError, IndexError) as err:
        raise InputError(path, f"cannot read PFM image: {err}") from None
    channels = {b"PF": 3, b"Pf": 1}.get(kind)
    if width < 1 or height < 1 or width * height > MAX_IMAGE_PIXELS:
        raise InputError(path, f"cannot read PFM image: size {width}x{height}")
    if channels is None or data.size < width * height * channels:
        raise InputError(path, "cannot read PFM image: bad header or truncated data")
    image = data[:width * height * channels].reshape(height, width, channels)[::-1]
    return _to_rgb(np.ascontiguousarray(image, dtype=np.float32), path)


def _float_masks(rgb, saturation):
    """(usable, clipped) of a float image: +Inf or >= saturation is clipped, NaN is invalid.

    Two reductions over the channels (NaN propagates through min/max), then per-pixel tests.
    """
    # elementwise over channel views: much faster than a reduction along a length-3 axis
    low = np.minimum(np.minimum(rgb[..., 0], rgb[..., 1]), rgb[..., 2])
    high = np.maximum(np.maximum(rgb[..., 0], rgb[..., 1]), rgb[..., 2])
    # past float32's largest value no pixel reaches the ceiling (and casting it would overflow)
    ceiling = np.inf if saturation is None or saturation > FLOAT32_MAX else saturation
    with np.errstate(invalid="ignore"):
        clipped = (high >= ceiling) & ~np.isnan(low)
        # a negative value is noise about a dim level (a flash − ambient difference saved as a
        # float image): dropping it keeps only the upward noise and biases dim bins high, up to
        # ×4.5 at grazing θh; a pixel whose channels are all 0 is a float image's black (no value)
        usable = (low > -np.inf) & (high < ceiling) & ((low != 0) | (high != 0))
    return usable, clipped


# OpenCV's size limits (imgcodecs/loadsave.cpp): the name its failed assertion shows -> the
# environment variable that sets the limit, the default, and what it counts
OPENCV_SIZE_LIMITS = {"CV_IO_MAX_IMAGE_PIXELS": ("OPENCV_IO_MAX_IMAGE_PIXELS", 1 << 30, "pixels"),
                      "CV_IO_MAX_IMAGE_WIDTH": ("OPENCV_IO_MAX_IMAGE_WIDTH", 1 << 20,
                                                "pixels wide"),
                      "CV_IO_MAX_IMAGE_HEIGHT": ("OPENCV_IO_MAX_IMAGE_HEIGHT", 1 << 20,
                                                 "pixels high")}


def opencv_size_limit(message, environ=None):
    """The limit an OpenCV error message says an image exceeds, as words ("1073741824 pixels
    (OPENCV_IO_MAX_IMAGE_PIXELS)"), or None when the error is about something else."""
    environ = os.environ if environ is None else environ
    for assertion, (variable, default, unit) in OPENCV_SIZE_LIMITS.items():
        if assertion in message:
            value = environ.get(variable, "")
            limit = int(value) if value.isdigit() else default
            return f"{limit} {unit} ({variable})"
    return None


def imread_unchanged(path):
    """cv2.imread(path, IMREAD_UNCHANGED), or None when OpenCV cannot read the file. An image
    over OpenCV's size limits, where cv2 raises rather than returning None, is an InputError
    naming the file and the limit (every caller would only say "cannot read"). The size itself
    is not told: OpenImageIO refuses to open such a header too (a "corrupt or malicious" PNG)."""
    try:
        return cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    except cv2.error as err:
        limit = opencv_size_limit(str(err))
        if limit is None:
            return None
        raise InputError(path, f"image is over OpenCV's limit of {limit}") from None


def object_mask(pixels):
    """(H, W) bool of a mask image's pixels (H, W) or (H, W, C): nonzero in any colour channel
    means object (the contract's masks). An alpha channel (the last of 2 or 4) is not colour: a
    black-and-white mask saved with opaque alpha would otherwise mark every pixel as object."""
    pixels = np.asarray(pixels)
    if pixels.ndim == 2:
        return pixels > 0
    colour = pixels[..., :3] if pixels.shape[2] >= 3 else pixels[..., :1]
    return np.any(colour > 0, axis=-1)


def read_object_mask(path):
    """object_mask of the image at `path` (PNG or any format OpenCV reads); InputError naming
    the file when it cannot be read."""
    pixels = imread_unchanged(path)
    if pixels is None:
        raise InputError(path, "cannot read mask image")
    return object_mask(pixels)


def _linear_from_cv(img, path, encoding, saturation):
    """An image as cv2.imread decoded it (BGR(A), 8/16-bit or float) -> (rgb, usable, clipped)
    as load_photo returns them; path only names the file in errors. Pure, so that brackets
    already decoded are linearised without reading their files again."""
    if img.ndim == 3 and img.shape[2] >= 3:
        img = img[..., [2, 1, 0]]  # BGR(A) -> RGB
    img = np.ascontiguousarray(_to_rgb(img, path))
    if img.dtype in (np.uint8, np.uint16):
        top = float(np.iinfo(img.dtype).max)
        clipped = np.any(img >= SATURATION_FRACTION * top, axis=-1)
        usable = np.all(img > 0, axis=-1) & ~clipped
        rgb = img.astype(np.float32) / np.float32(top)
        if encoding is None:
            encoding = "srgb" if img.dtype == np.uint8 else "linear"
        if encoding == "srgb":
            rgb = srgb_to_linear(rgb)
        return rgb, usable, clipped
    if img.dtype in (np.float32, np.float64):
        _check_float_encoding(path, encoding)
        rgb = img.astype(np.float32)
        return (rgb, *_float_masks(rgb, saturation))
    raise InputError(path, f"unsupported pixel type {img.dtype} (expected 8/16-bit or float)")


def _check_float_encoding(path, encoding):
    """InputError naming a float image given "encoding": "srgb": floats are linear radiance, and
    the sRGB curve is defined on 0..1 display codes."""
    if encoding == "srgb":
        raise InputError(path, 'stores floats, which are linear: "encoding": "srgb" is for 8- and '
                               "16-bit codes (leave it out, or give \"linear\")")


def _check_shape(rgb, path, shape):
    """InputError naming the file when the image is not `shape` (height, width); None: any."""
    if shape is not None and rgb.shape[:2] != tuple(shape):
        raise InputError(path, f"image is {rgb.shape[1]}x{rgb.shape[0]} but the camera is "
                               f"{shape[1]}x{shape[0]}")


def load_photo(path, encoding=None, saturation=None, shape=None, return_clipped=False):
    """Load one photo as linear RGB.

    path: image file; encoding: "linear" | "srgb" | None (by format: 8-bit -> srgb, else linear);
    saturation: clipping level for float images (linear units), None = no ceiling;
    shape: expected (height, width), InputError naming the file when different.
    Returns rgb (H, W, 3) float32 linear (unusable pixels keep their values), usable (H, W) bool,
    and with return_clipped also clipped (H, W) bool: the unusable pixels that are unusable
    because they are too bright (their true value is above the stored one: right-censored).
    """
    rgb, usable, clipped, _ = _load_photo(path, encoding, saturation, shape)
    return (rgb, usable, clipped) if return_clipped else (rgb, usable)


def load_photo_measured(path, encoding=None, saturation=None, shape=None):
    """Load one photo as linear RGB with the pixels whose stored value measures the scene,
    what a render is compared against.

    A float image (EXR, HDR, PFM, float TIFF) stores 0 and negative noise as they are: only NaN
    and clipped pixels (+Inf, at or above `saturation`) are not measurements. Integer codes
    (8/16-bit, RAW) are censored at both ends, so there the measured pixels are load_photo's
    usable ones (no channel at code 0, none saturated). Returns rgb (H, W, 3) float32, measured
    (H, W) bool.
    """
    rgb, usable, clipped, stored_float = _load_photo(path, encoding, saturation, shape)
    if not stored_float:
        return rgb, usable
    return rgb, ~clipped & np.all(np.isfinite(rgb), axis=-1)


def _load_photo(path, encoding, saturation, shape):
    """load_photo's work: -> rgb, usable, clipped, and whether the file stores floats."""
    path = Path(path)
    if not path.is_file():
        raise no_file(path)
    ext = path.suffix.lower()
    stored_float = False
    if ext in RAW_EXTENSIONS:
        from flashbrdf.capture.raw import load_raw  # rawpy is imported for RAW files only
        rgb, usable, clipped = load_raw(path, SATURATION_FRACTION)
    elif ext in CV_EXTENSIONS:
        img = imread_unchanged(path)
        if img is None:
            raise InputError(path, "cannot read image (corrupt or unsupported)")
        stored_float = img.dtype in (np.float32, np.float64)
        rgb, usable, clipped = _linear_from_cv(img, path, encoding, saturation)
    elif ext in FLOAT_EXTENSIONS:
        _check_float_encoding(path, encoding)
        rgb = read_pfm(path) if ext == ".pfm" else read_float_image(path, require_float=True)
        stored_float = True
        usable, clipped = _float_masks(rgb, saturation)
    else:   # .bmp, .gif, .webp...: 8-bit codes whose curve and clipping nobody states
        raise InputError(path, f"unsupported photo format {ext or '(no extension)'}: photos are "
                               f"{', '.join(FLOAT_EXTENSIONS + CV_EXTENSIONS)} or camera RAW")
    _check_shape(rgb, path, shape)
    return rgb, usable, clipped, stored_float


def _load_bracket(path, encoding, saturation, shape):
    """One bracket linearised as load_photo does: (rgb float32, usable, clipped)."""
    if path.suffix.lower() in CV_EXTENSIONS:
        img = imread_unchanged(path) if path.is_file() else None
        if img is None:
            raise no_file(path) if not path.is_file() else InputError(path, "cannot read image")
        rgb, usable, clip = _linear_from_cv(img, path, encoding, saturation)
        _check_shape(rgb, path, shape)
    else:
        rgb, usable, clip = load_photo(path, encoding, saturation, shape, return_clipped=True)
    return np.asarray(rgb, np.float32), usable, clip


def load_brackets(brackets, encoding=None, saturation=None, shape=None, return_clipped=False):
    """Merge an exposure bracket [(path, exposure_s), ...] into one HDR photo.

    Each bracket is linearised as load_photo does (8-bit without an `encoding` as sRGB, 16-bit
    as linear), then per pixel the maximum-likelihood radiance for Poisson counts,
    sum(value) / sum(exposure) over the brackets where the pixel is usable. (A calibrated camera
    response, Debevec's, is known only up to a scale, another one for each photo: no absolute
    level.) A merged pixel is usable when at least one bracket saw
    it usable, clipped when every bracket saw it clipped.
    Returns rgb (H, W, 3) float32 in units per second of exposure, usable (H, W) bool (and
    clipped (H, W) bool with return_clipped).
    """
    paths = [Path(p) for p, _ in brackets]
    times = np.array([t for _, t in brackets], dtype=np.float32)
    shortest_index = int(np.argmin(times))
    # one bracket decoded at a time, summed in float32: all of them at once, merged in float64,
    # took 6.4 times one photo's memory (3.8 GB for three 24 MP brackets)
    total = exposure = clipped = shortest = None
    for index, (path, t) in enumerate(zip(paths, times)):
        rgb, usable, clip = _load_bracket(path, encoding, saturation, shape)
        if total is None:
            total = np.zeros(rgb.shape, np.float32)
            exposure = np.zeros(usable.shape, np.float32)
            clipped = np.ones(usable.shape, dtype=bool)
        elif rgb.shape != total.shape:
            raise InputError(paths[0], "bracket images differ in size")
        if index == shortest_index:  # what a pixel unusable in every bracket keeps
            shortest = rgb / np.float32(t)
        rgb[~usable] = 0
        total += rgb
        exposure += usable * np.float32(t)
        clipped &= clip
        del rgb
    usable = exposure > 0
    total /= np.where(usable, exposure, np.float32(1))[..., None]
    rgb = np.where(usable[..., None], total, shortest).astype(np.float32, copy=False)
    return (rgb, usable, clipped) if return_clipped else (rgb, usable)
