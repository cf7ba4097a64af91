"""Camera RAW through rawpy (LibRaw): linear, no gamma, no auto-brightness, camera white balance,
black and white levels honoured, output in linear sRGB primaries.

Only this module imports rawpy, and only when a RAW file is loaded.

Usable mask: a sensel at or above SATURATION_FRACTION of (white - black), or at or below its black
level, taints every output pixel whose demosaic neighbourhood (5x5) contains it; output values
clipped by LibRaw at 0 or 65535 are unusable too. The mask follows the same orientation flip
LibRaw applies to the image.
"""

import numpy as np

from brdf.errors import InputError
from capture.photo import SATURATION_FRACTION

_DEMOSAIC_REACH = 2  # sensels: AHD interpolation reads a 5x5 neighbourhood


def _dilate(mask, reach):
    import cv2
    kernel = np.ones((2 * reach + 1, 2 * reach + 1), np.uint8)
    return cv2.dilate(mask.astype(np.uint8), kernel).astype(bool)


def _apply_flip(mask, flip):
    """LibRaw's sizes.flip: 0 none, 3 = 180 deg, 5 = 90 deg CCW, 6 = 90 deg CW."""
    if flip == 3:
        return mask[::-1, ::-1]
    if flip == 5:
        return np.rot90(mask, 1)
    if flip == 6:
        return np.rot90(mask, -1)
    return mask


def load_raw(path):
    """Decode a RAW file. Returns rgb (H, W, 3) float32 linear sRGB primaries, scaled so that the
    white level maps to 1 before white balance, and usable (H, W) bool."""
    import rawpy
    try:
        raw = rawpy.imread(str(path))
    except (rawpy.LibRawError, OSError, ValueError) as err:
        raise InputError(path, f"cannot read RAW file: {err}") from None
    with raw:
        try:
            sensels = raw.raw_image_visible.astype(np.float64)
            colours = raw.raw_colors_visible
            black = np.asarray(raw.black_level_per_channel, dtype=np.float64)[colours]
            white = float(raw.white_level)
            bad = (sensels >= black + SATURATION_FRACTION * (white - black)) | (sensels <= black)
            flip = raw.sizes.flip
            img = raw.postprocess(gamma=(1, 1), no_auto_bright=True, use_camera_wb=True,
                                  output_bps=16, output_color=rawpy.ColorSpace.sRGB,
                                  user_flip=None)
        except rawpy.LibRawError as err:
            raise InputError(path, f"cannot decode RAW file: {err}") from None
    bad = _apply_flip(_dilate(bad, _DEMOSAIC_REACH), flip)
    if bad.shape != img.shape[:2]:  # LibRaw cropped or padded differently: resize nearest
        import cv2
        bad = cv2.resize(bad.astype(np.uint8), (img.shape[1], img.shape[0]),
                         interpolation=cv2.INTER_NEAREST).astype(bool)
    usable = ~bad & np.all(img > 0, axis=-1) & np.all(img < 65535, axis=-1)
    return img.astype(np.float32) / np.float32(65535), usable
