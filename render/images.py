"""Image files: HDR EXR in/out (OpenImageIO, float32) and tone-mapped PNG previews.

Every writer is atomic (files.atomic.atomic_path): no partial file is ever left behind.
"""

import os

import numpy as np
import OpenImageIO as oiio

from flashbrdf.capture.photo import object_mask
from flashbrdf.files.atomic import atomic_path
from flashbrdf.brdf.colour import srgb_encode
from flashbrdf.files.errors import InputError, library_error


def write_exr(path, rgb):
    """Write (H, W, 3) linear RGB as a float32 OpenEXR file."""
    rgb = np.ascontiguousarray(np.asarray(rgb, dtype=np.float32))
    if rgb.ndim != 3 or rgb.shape[2] != 3:
        raise ValueError(f"write_exr needs (H, W, 3), got {rgb.shape}")
    with atomic_path(path) as tmp:
        spec = oiio.ImageSpec(rgb.shape[1], rgb.shape[0], 3, oiio.FLOAT)
        spec.attribute("compression", "zip")  # lossless, and smaller for images mostly black
        out = oiio.ImageOutput.create(tmp)
        if out is None or not out.open(tmp, spec):
            raise OSError(f"{path}: cannot write EXR ({library_error(oiio)})")
        try:
            if not out.write_image(rgb):
                raise OSError(f"{path}: cannot write EXR ({library_error(out)})")
        finally:
            out.close()


def read_image(path):
    """Read a linear HDR image (.exr, .hdr, .pfm, ...) -> (H, W, 3) float32.

    capture's reader: channels by name, grey repeated to RGB, alpha dropped, an EXR data window
    placed in its display window (NaN outside). InputError when missing or unreadable.
    """
    # imported on first use: see render.envmap.read_envmap_pixels
    from flashbrdf.capture import read_float_image
    return read_float_image(path)


def image_channel_names(path):
    """The channel names of an image file, from its header (no pixels read), e.g. ["R", "G",
    "B"] or ["Y"]; [] when it cannot be opened (read_image then says why)."""
    inp = oiio.ImageInput.open(os.fspath(path))
    if inp is None:
        library_error(oiio)  # clear it: read_image reports the failure
        return []
    try:
        return [n.split(".")[-1].upper() for n in inp.spec().channelnames]
    finally:
        inp.close()


def tonemap(rgb, exposure=None):
    """(H, W, 3) linear -> (H, W, 3) uint8 sRGB preview.

    `exposure` multiplies the image first; by default the 99th percentile of the finite,
    positive luminances maps to 1 (so one hot pixel does not blacken the preview). Then
    Reinhard-style x / (1 + x/4) soft clip and the sRGB transfer curve.
    """
    # float32, in place, one row block at a time: a 24 MP preview took 3.6 GB in float64 copies
    # (an 8-bit code needs 3 digits)
    rgb = np.asarray(rgb)
    if exposure is None:
        lum = np.empty(rgb.shape[:2], np.float32)
        for rows in _row_blocks(rgb.shape[0]):
            block = _finite_positive(rgb[rows])
            lum[rows] = block @ np.array([0.2126, 0.7152, 0.0722], np.float32)
        positive = lum[lum > 0]
        exposure = 1.0 / np.percentile(positive, 99) if positive.size else 1.0
    out = np.empty(rgb.shape, np.uint8)
    for rows in _row_blocks(rgb.shape[0]):
        x = _finite_positive(rgb[rows])
        x *= np.float32(exposure)
        x /= 1.0 + x / 4.0
        x *= 1.25                            # maps 1 -> 1, compresses highlights smoothly
        np.clip(x, 0.0, 1.0, out=x)
        srgb = srgb_encode(x)
        out[rows] = (np.clip(srgb, 0, 1) * 255 + 0.5).astype(np.uint8)
    return out


def _row_blocks(height, rows=256):
    return [slice(r, min(r + rows, height)) for r in range(0, height, rows)]


def _finite_positive(block):
    """A float32 copy of an image block with NaN and inf at 0 and negatives at 0."""
    x = np.array(block, dtype=np.float32)
    np.nan_to_num(x, copy=False, nan=0.0, posinf=0.0, neginf=0.0)
    return np.maximum(x, 0.0, out=x)


def write_png(path, rgb8):
    """Write (H, W, 3) or (H, W, 4) uint8 as PNG, atomically."""
    rgb8 = np.ascontiguousarray(rgb8, dtype=np.uint8)
    with atomic_path(path) as tmp:
        spec = oiio.ImageSpec(rgb8.shape[1], rgb8.shape[0], rgb8.shape[2], oiio.UINT8)
        out = oiio.ImageOutput.create(tmp)
        if out is None or not out.open(tmp, spec):
            raise OSError(f"{path}: cannot write PNG ({library_error(oiio)})")
        try:
            out.write_image(rgb8)
        finally:
            out.close()


def write_preview(path, rgb, exposure=None):
    """Tone-mapped PNG preview of a linear image."""
    write_png(path, tonemap(rgb, exposure))


def read_mask(path, shape=None):
    """A PNG (or any image) mask -> (H, W) bool, nonzero = True. InputError if unreadable or
    (with `shape`) of the wrong size."""
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise InputError(path, "no such mask file")
    inp = oiio.ImageInput.open(path)
    if inp is None:
        raise InputError(path, f"cannot read mask ({library_error(oiio)})")
    try:
        spec = inp.spec()
        pixels = inp.read_image(0, 0, 0, spec.nchannels, oiio.FLOAT)
    finally:
        inp.close()
    if pixels is None:
        raise InputError(path, "cannot decode mask")
    pixels = np.asarray(pixels).reshape(spec.height, spec.width, spec.nchannels)
    mask = object_mask(pixels)
    if shape is not None and mask.shape != tuple(shape[:2]):
        raise InputError(path, f"mask is {mask.shape[1]}x{mask.shape[0]}, "
                               f"image is {shape[1]}x{shape[0]}")
    return mask
