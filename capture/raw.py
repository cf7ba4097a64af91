"""Camera RAW through rawpy (LibRaw): linear, no gamma, no auto-brightness, camera white balance
(daylight when the file has none), black and white levels honoured, output in linear sRGB
primaries.

Only this module imports rawpy, and only when a RAW file is loaded.

Usable mask: a sensel at or above `saturation_fraction` of (white - black), or at or below its black
level, taints every output pixel whose demosaic neighbourhood (5x5) contains it; output values
clipped by LibRaw at 0 or 65535 are unusable too. The mask follows the same orientation flip
LibRaw applies to the image.
"""

import cv2
import numpy as np
import rawpy

from flashbrdf.files.errors import InputError

_DEMOSAIC_REACH = 2  # sensels: AHD interpolation reads a 5x5 neighbourhood


def _dilate(mask, reach):
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


def load_raw(path, saturation_fraction):
    """Decode a RAW file; a sensel at or above `saturation_fraction` of its range counts as clipped
    (capture.photo.SATURATION_FRACTION). Returns rgb (H, W, 3) float32 linear sRGB primaries,
    scaled so that the white level maps to 1 before white balance, usable (H, W) bool, clipped
    (H, W) bool."""
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
            high = sensels >= black + saturation_fraction * (white - black)
            low = sensels <= black
            flip = raw.sizes.flip
            multipliers = white_balance(raw)
            # LibRaw's default (clip) scales the weakest white-balance channel to 65535 at the
            # white level, so a channel with a larger multiplier clips in 16 bits before its
            # sensels saturate (red x2.5 under a warm as-shot balance: at 40% of the sensor's
            # range). "Ignore" scales the strongest channel there instead; the headroom is
            # multiplied back in float. The multipliers are passed in, so the headroom is theirs:
            # with use_camera_wb, a file without an as-shot balance gets LibRaw's grey-world
            # one (LibRaw >= 0.20), whose spread is known only inside LibRaw.
            headroom = float(multipliers.max() / multipliers.min())
            img = raw.postprocess(gamma=(1, 1), no_auto_bright=True, use_camera_wb=False,
                                  user_wb=[float(m) for m in multipliers],
                                  output_bps=16, output_color=rawpy.ColorSpace.sRGB,
                                  highlight_mode=rawpy.HighlightMode.Ignore, user_flip=None)
        except rawpy.LibRawError as err:
            raise InputError(path, f"cannot decode RAW file: {err}") from None
    high = _to_output(high, flip, img.shape) | np.any(img >= 65535, axis=-1)
    low = _to_output(low, flip, img.shape) | np.any(img == 0, axis=-1)
    rgb = img.astype(np.float32) * np.float32(headroom / 65535)
    return rgb, ~(high | low), high & ~low


def white_balance(raw):
    """The 4 white-balance multipliers (R, G, B, second G) (4,) float64 a decode applies, as
    LibRaw's scale_colors picks them for use_camera_wb: the camera's as-shot ones when its red
    and blue are set, else the daylight ones (LibRaw's fallback would be a grey-world balance
    of the photo, which takes the object's own colour out); a missing green is 1, a missing
    fourth is the green (a 4-colour sensor's: 1); all 1 when the file has neither."""
    camera = np.asarray(raw.camera_whitebalance, dtype=np.float64)
    daylight = np.asarray(raw.daylight_whitebalance, dtype=np.float64)
    wb = camera if camera[0] > 1e-5 and camera[2] > 1e-5 else daylight
    wb = wb.copy()
    if wb[1] == 0:
        wb[1] = 1.0
    if wb[3] == 0:
        wb[3] = wb[1] if raw.num_colors < 4 else 1.0
    if not (np.all(np.isfinite(wb)) and np.all(wb > 1e-5)):
        return np.ones(4)
    return wb


def _to_output(sensel_mask, flip, shape):
    """A sensel mask, dilated over the demosaic reach, in the output image's orientation."""
    mask = _apply_flip(_dilate(sensel_mask, _DEMOSAIC_REACH), flip)
    if mask.shape != shape[:2]:  # LibRaw cropped or padded differently: resize nearest
        mask = cv2.resize(mask.astype(np.uint8), (shape[1], shape[0]),
                          interpolation=cv2.INTER_NEAREST).astype(bool)
    return mask
