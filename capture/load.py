"""From a Scene to calibrated flash photos in the contract's pixel units.

Pixel model (contract): pixel = (flash - ambient) / scale_flash. When the ambient photo sets its
own `scale` explicitly, it is taken to be in its own units, so the ambient in flash units is
ambient * scale_flash / scale_ambient; several ambient photos are averaged. Usability propagates:
a pixel is usable only if usable in the flash photo and measured in every ambient photo (not
clipped, finite: an ambient pixel at 0 is a dark room, not a lost measurement). Values are never
clamped: noise can make (flash - ambient) negative, which keeps per-bin estimates unbiased.
"""

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from flashbrdf.capture.photo import load_brackets, load_photo, load_photo_measured
from flashbrdf.capture.scene import Scene, load_scene, same_view
from flashbrdf.files.errors import InputError
from flashbrdf.files.threads import thread_budget


@dataclass(frozen=True, eq=False)
class FlashImage:
    """A flash photo ready for extraction: radiance (H, W, 3) float32 in pixel-model units,
    usable (H, W) bool, clipped (H, W) bool (too bright to measure: right-censored, never usable),
    and its Photo entry (light, camera, where)."""
    photo: object
    radiance: np.ndarray
    usable: np.ndarray
    clipped: np.ndarray


def photo_exists(photo):
    """Whether a photos[] entry's file (or every bracket) is on disk; a reference may be absent
    (then it is rendered, not compared)."""
    if photo.file is not None:
        return Path(photo.file).is_file()
    return bool(photo.brackets) and all(Path(p).is_file() for p, _ in photo.brackets)


def load_photo_entry(photo, return_clipped=False):
    """Load one scene.json photo entry (file or brackets) at its camera's size, without scale.

    Returns rgb (H, W, 3) float32 linear, usable (H, W) bool (and clipped, see load_photo).
    """
    shape = photo.camera.shape
    if photo.file is not None:
        return load_photo(photo.file, photo.encoding, photo.saturation, shape, return_clipped)
    return load_brackets(photo.brackets, photo.encoding, photo.saturation, shape, return_clipped)


def load_reference_entry(photo):
    """A photos[] entry as renders are compared against it, unscaled: rgb (H, W, 3) float32 and
    measured (H, W) bool (load_photo_measured; for brackets, the merged usable pixels)."""
    if photo.file is not None:
        return load_photo_measured(photo.file, photo.encoding, photo.saturation,
                                   photo.camera.shape)
    return load_photo_entry(photo)


def _ambient(scene, photo):
    """(rgb, usable, scale or None) of the ambient photo(s) of a flash photo's view, averaged, or
    (None, None, None) when the scene has none. The ambient photos taken from the flash photo's
    camera; when the flash photos are all of one view, every ambient photo (a single-view
    capture may give the ambient photo a camera of its own). A flash photo of a multi-view
    capture with no ambient photo from its view is refused: another view's ambient light falls
    on other pixels."""
    ambients = scene.photos_with_role("ambient")
    if not ambients:
        return None, None, None
    from_view = [a for a in ambients if same_view(a.camera, photo.camera)]
    flashes = scene.photos_with_role("flash")
    if from_view:
        ambients = from_view
    elif (any(not same_view(a.camera, ambients[0].camera) for a in ambients)
          or any(not same_view(f.camera, photo.camera) for f in flashes)):
        raise InputError(photo.where, "no ambient photo was taken from this flash photo's "
                                      "camera; give one ambient photo per view, or none")
    total, usable = None, None
    for a in ambients:
        if a.camera.shape != photo.camera.shape:
            raise InputError(a.where, "ambient photo's camera differs in size from the flash's")
        rgb, _, clipped = load_photo_entry(a, return_clipped=True)
        # An ambient pixel at 0 (below one code) is what a dark room gives: "no ambient light",
        # to half a code of the ambient photo (the flash photo's own rounding when both are taken
        # alike, as docs/capture.md asks), so only a clipped or non-finite ambient pixel makes
        # its flash pixel unusable.
        ok = ~clipped & np.isfinite(rgb).all(axis=-1)
        total = rgb if total is None else total + rgb
        usable = ok if usable is None else usable & ok
    scales = {a.scale if a.scale_given else None for a in ambients}
    if len(scales) > 1:
        raise InputError(ambients[1].where, "ambient photos must share one scale")
    if len(ambients) > 1:
        total /= np.float32(len(ambients))
    return total, usable, scales.pop()


def iter_flash_images(scene, prefetch=True):
    """The flash photos of a scene one at a time, ambient subtracted and divided by their scale:
    a FlashImage each, so that a capture of many full-resolution photos never holds more than
    two (and their views' ambient) in memory.

    With prefetch (and more than one flash photo), the next photo is decoded in a background
    thread while the caller works on this one: image decoding (OpenImageIO, OpenCV) and Embree
    release the GIL, so on two cores the ~1 s a 24-MP EXR takes to decode hides behind the
    tracing. An error in a photo is raised where that photo is asked for, as without prefetch.

    scene: capture.Scene or a scene folder. InputError when the scene has no flash photo.
    """
    if not isinstance(scene, Scene):
        scene = load_scene(scene)
    flashes = scene.flash_photos()
    ambient_of = _AmbientCache(scene)

    def prepared(photo):
        rgb, usable, clipped = load_photo_entry(photo, return_clipped=True)
        ambient = ambient_of(photo)
        if ambient is not None:
            amb, amb_ok, amb_scale = ambient
            factor = 1.0 if amb_scale is None else photo.scale / amb_scale
            rgb -= amb if factor == 1.0 else np.float32(factor) * amb  # rgb is our own copy
            usable &= amb_ok
            clipped &= amb_ok
        if photo.scale != 1.0:
            rgb /= np.float32(photo.scale)
        return FlashImage(photo, rgb, usable, clipped)

    # a batch worker given one thread ($FLASHBRDF_THREADS=1) gets no second one here
    if not prefetch or len(flashes) == 1 or thread_budget(2) == 1:
        for photo in flashes:
            yield prepared(photo)
        return
    from concurrent.futures import ThreadPoolExecutor
    # one worker: photos are prepared in order (the ambient cache follows the views)
    pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="flash-photo")
    try:
        pending = pool.submit(prepared, flashes[0])
        for following in flashes[1:] + [None]:
            image = pending.result()  # the previous image is let go here, before the next read
            pending = None if following is None else pool.submit(prepared, following)
            yield image
    finally:  # stopped early (an error, Ctrl-C): a decode under way is waited for, not more
        pool.shutdown(wait=True, cancel_futures=True)


class _AmbientCache:
    """The ambient (rgb, usable, scale) of a flash photo's view (_ambient), read again only when
    the view changes; None when the scene has no ambient photo."""

    def __init__(self, scene):
        self.scene, self.camera, self.ambient = scene, None, None

    def __call__(self, photo):
        if not self.scene.photos_with_role("ambient"):
            return None
        if self.camera is None or not same_view(self.camera, photo.camera):
            self.ambient, self.camera = _ambient(self.scene, photo), photo.camera
        return self.ambient


def load_flash_images(scene):
    """Every flash photo at once (iter_flash_images as a list): for captures of a few photos."""
    return list(iter_flash_images(scene))
