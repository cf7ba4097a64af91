"""Photo loading: every photo becomes float32 linear RGB (H, W, 3) plus a "usable" mask (H, W).

Formats (chosen by extension, then by the stored bit depth):
- .exr .hdr .pfm (and float TIFF): OpenImageIO, values as stored.
- 16-bit .png/.tif: OpenCV IMREAD_UNCHANGED (imageio/Pillow silently drop to 8 bits), BGR->RGB,
  code / 65535, linear unless encoding == "srgb".
- 8-bit .png/.jpg/.tif: code / 255 through the inverse sRGB EOTF unless encoding == "linear".
- camera RAW (.dng .cr2 .nef ...): rawpy (imported only here, lazily), see capture.raw.

A pixel is unusable (never clamped, just flagged) when any channel is NaN/Inf, when any channel is
at or above the clipping level (integer codes >= SATURATION_FRACTION x max code: sensors turn
non-linear in the top few percent, and 12/14-bit data rescaled to 16 bits tops out below 65535;
float images: photos[].saturation if given), or when it carries no signal: any channel at code 0
for integer images (at the black level, so the true value is unknown), or no channel > 0 / any
channel < 0 for float images (a float image has no code floor, so one dark channel is still data).
"""

from pathlib import Path

import numpy as np

from brdf.errors import InputError

SATURATION_FRACTION = 0.98
FLOAT_EXTENSIONS = (".exr", ".hdr", ".pfm")
CV_EXTENSIONS = (".png", ".tif", ".tiff", ".jpg", ".jpeg")
RAW_EXTENSIONS = (".dng", ".cr2", ".cr3", ".crw", ".nef", ".nrw", ".arw", ".srf", ".sr2", ".orf",
                  ".rw2", ".raf", ".pef", ".srw", ".raw", ".rwl", ".3fr", ".erf", ".kdc", ".dcr",
                  ".mrw", ".mos", ".iiq", ".x3f")


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


def read_float_image(path):
    """Read an image through OpenImageIO as float32 (H, W, 3) RGB (channels R, G, B by name when
    present). InputError naming the file when missing or unreadable."""
    import OpenImageIO as oiio
    path = Path(path)
    if not path.is_file():
        raise InputError(path, "file not found")
    inp = oiio.ImageInput.open(str(path))
    if inp is None:
        raise InputError(path, f"cannot read image: {oiio.geterror() or 'unknown format'}")
    try:
        spec = inp.spec()
        data = inp.read_image(0, 0, 0, spec.nchannels, oiio.FLOAT)
        if data is None:
            raise InputError(path, f"cannot read image: {inp.geterror() or 'corrupt data'}")
        names = [n.split(".")[-1].upper() for n in spec.channelnames]
    finally:
        inp.close()
    data = np.asarray(data, dtype=np.float32).reshape(spec.height, spec.width, spec.nchannels)
    if all(c in names for c in "RGB"):
        data = data[..., [names.index(c) for c in "RGB"]]
    return _to_rgb(data, path)


def _float_usable(rgb, saturation):
    finite = np.all(np.isfinite(rgb), axis=-1)
    with np.errstate(invalid="ignore"):
        usable = finite & np.all(rgb >= 0, axis=-1) & np.any(rgb > 0, axis=-1)
        if saturation is not None:
            usable &= np.all(rgb < saturation, axis=-1)
    return usable


def _read_cv(path, encoding):
    import cv2
    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise InputError(path, "cannot read image (corrupt or unsupported)")
    if img.ndim == 3 and img.shape[2] >= 3:
        img = img[..., [2, 1, 0]]  # BGR(A) -> RGB
    img = _to_rgb(img, path)
    if img.dtype in (np.uint8, np.uint16):
        top = float(np.iinfo(img.dtype).max)
        usable = np.all(img > 0, axis=-1) & np.all(img < SATURATION_FRACTION * top, axis=-1)
        rgb = img.astype(np.float32) / np.float32(top)
        if encoding is None:
            encoding = "srgb" if img.dtype == np.uint8 else "linear"
        if encoding == "srgb":
            rgb = srgb_to_linear(rgb)
        return rgb, usable
    if img.dtype in (np.float32, np.float64):
        return img.astype(np.float32), None
    raise InputError(path, f"unsupported pixel type {img.dtype} (expected 8/16-bit or float)")


def load_photo(path, encoding=None, saturation=None, shape=None):
    """Load one photo as linear RGB.

    path: image file; encoding: "linear" | "srgb" | None (by format: 8-bit -> srgb, else linear);
    saturation: clipping level for float images (linear units), None = no ceiling;
    shape: expected (height, width), InputError naming the file when different.
    Returns rgb (H, W, 3) float32 linear (unusable pixels keep their values), usable (H, W) bool.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(path, "file not found")
    ext = path.suffix.lower()
    if ext in RAW_EXTENSIONS:
        from capture.raw import load_raw
        rgb, usable = load_raw(path)
    elif ext in CV_EXTENSIONS:
        rgb, usable = _read_cv(path, encoding)
        if usable is None:
            usable = _float_usable(rgb, saturation)
    else:
        rgb = read_float_image(path)
        if encoding == "srgb":
            rgb = srgb_to_linear(rgb)
        usable = _float_usable(rgb, saturation)
    if shape is not None and rgb.shape[:2] != tuple(shape):
        raise InputError(path, f"image is {rgb.shape[1]}x{rgb.shape[0]} but the camera is "
                               f"{shape[1]}x{shape[0]}")
    return rgb, usable


def load_brackets(brackets, encoding=None, saturation=None, shape=None):
    """Merge an exposure bracket [(path, exposure_s), ...] into one HDR photo.

    8-bit brackets: OpenCV's Debevec camera-response calibration and merge (relative radiance,
    response normalised by OpenCV). Other (linear) brackets: per pixel, the maximum-likelihood
    radiance for Poisson counts, sum(value) / sum(exposure) over the brackets where the pixel is
    usable. A merged pixel is usable when at least one bracket saw it usable.
    Returns rgb (H, W, 3) float32 in units per second of exposure, usable (H, W) bool.
    """
    paths = [Path(p) for p, _ in brackets]
    times = np.array([t for _, t in brackets], dtype=np.float32)
    if all(p.suffix.lower() in CV_EXTENSIONS for p in paths):
        import cv2
        raw = [cv2.imread(str(p), cv2.IMREAD_UNCHANGED) if p.is_file() else None for p in paths]
        for p, img in zip(paths, raw):
            if img is None:
                raise InputError(p, "file not found" if not p.is_file() else "cannot read image")
        if all(img.dtype == np.uint8 for img in raw):
            return _merge_debevec(paths, raw, times, shape)
    loaded = [load_photo(p, encoding, saturation, shape) for p in paths]
    total = np.zeros(loaded[0][0].shape, dtype=np.float64)
    exposure = np.zeros(loaded[0][1].shape, dtype=np.float64)
    for (rgb, usable), t in zip(loaded, times):
        if rgb.shape != total.shape:
            raise InputError(paths[0], "bracket images differ in size")
        total += np.where(usable[..., None], rgb, 0)
        exposure += usable * float(t)
    usable = exposure > 0
    rgb = total / np.where(usable, exposure, 1)[..., None]
    # pixels unusable in every bracket keep the shortest exposure's value, flagged unusable
    shortest = loaded[int(np.argmin(times))][0] / times.min()
    rgb = np.where(usable[..., None], rgb, shortest)
    return rgb.astype(np.float32), usable


def _merge_debevec(paths, images, times, shape):
    import cv2
    for p, img in zip(paths, images):
        if img.ndim != 3 or img.shape[2] != 3:
            raise InputError(p, "8-bit brackets must be 3-channel colour images")
        if img.shape != images[0].shape:
            raise InputError(p, "bracket images differ in size")
        if shape is not None and img.shape[:2] != tuple(shape):
            raise InputError(p, f"image is {img.shape[1]}x{img.shape[0]} but the camera is "
                                f"{shape[1]}x{shape[0]}")
    response = cv2.createCalibrateDebevec().process(images, times)
    hdr = cv2.createMergeDebevec().process(images, times, response)[..., ::-1]
    stack = np.stack(images)
    top = SATURATION_FRACTION * 255
    # usable if some bracket has the pixel unclipped at both ends
    usable = np.any(np.all(stack > 0, axis=-1) & np.all(stack < top, axis=-1), axis=0)
    usable &= np.all(np.isfinite(hdr), axis=-1)
    return np.ascontiguousarray(hdr, dtype=np.float32), usable
