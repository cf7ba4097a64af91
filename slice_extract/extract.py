"""extract_slice: from a capture folder (flash photos + geometry) to rho(theta_h) at theta_d ~ 0.

Steps: load and validate the scene; load the flash photos (ambient removed, divided by scale);
trace one Embree ray per pixel that can see the mesh's bounding box (once per camera, shared by
its photos); mark the object's outline; per usable pixel compute omega_o, omega_i, theta_h,
theta_d and rho from the pixel model (slice_extract.samples); pool the samples of all flash
photos; bin them into the 90 MERL theta_h bins with a robust estimate (slice_extract.binning).

Default thresholds:
- silhouette_px = 1: pixels touching the outline mix object and background (lens blur,
  demosaicing, a renderer's pixel filter) and they are exactly the grazing-angle samples, so a
  one-pixel ring is dropped; 0 keeps it (exact synthetic images).
- min_cos = 0.1: below it (84 deg) tiny normal errors swing cos(theta) by large factors.
- max_theta_d_deg = 5: a real flash sits a few cm from the lens (3 cm at 1 m is theta_d = 0.86 deg;
  DiLiGenT's nearest lights give 2.2 to 2.9 deg). Within 5 deg Fresnel is flat ((1 - cos 5 deg)^5
  ~ 1e-12) and the slice stays the theta_d ~ 0 slice of the paper; raise it only knowingly.
"""

import time
from dataclasses import dataclass, field

import cv2
import numpy as np

from flashbrdf import capture
from flashbrdf.brdf.angles import merl_bin_index
from flashbrdf.files.errors import InputError
from flashbrdf.brdf.merl import N_THETA_H
from flashbrdf.brdf.views import MAX_SLICE_VALUE, slice_coverage
from flashbrdf.slice_extract.binning import robust_bins
from flashbrdf.slice_extract.samples import REASONS, light_setup, photo_samples
from flashbrdf.slice_extract.segment import (BORDER_MIN_BIN, border_width_px, check_labels,
                                   material_interior)


@dataclass(frozen=True)
class ExtractOptions:
    max_theta_d_deg: float = 5.0
    min_cos: float = 0.1
    outlier_k: float = 3.0
    estimator: str = "trimmed_mean"  # or "median"
    shadow_rays: bool = True  # False only to diagnose (or to show what shadows would cost)
    silhouette_px: int = 1  # reject pixels this close to the object's outline (0: keep them)
    chunk_pixels: int = 1 << 20  # pixels traced per batch: bounds memory, keeps arrays in cache


@dataclass(eq=False)
class SliceResult:
    """rho (90, 3) 1/sr NaN where empty; n (90,) int; spread (90, 3) robust sigma per bin;
    report: JSON-ready dict (coverage, rejected, theta_d_deg, timings_s, options, photos)."""
    rho: np.ndarray
    n: np.ndarray
    spread: np.ndarray
    report: dict = field(default_factory=dict)

    @property
    def coverage(self):
        return self.report["coverage"]

    @property
    def rejected(self):
        return self.report["rejected"]

    @property
    def timings(self):
        return self.report["timings_s"]


class NotABRDFError(InputError):
    """The photos give values no BRDF has (above MAX_SLICE_VALUE): bad input for the whole
    capture, never one material's missing coverage."""


def _stats_deg(values):
    if len(values) == 0:
        return None
    d = np.degrees(values)
    return {"min": float(d.min()), "median": float(np.median(d)), "mean": float(d.mean()),
            "p95": float(np.percentile(d, 95)), "max": float(d.max())}


class _Clock:
    def __init__(self):
        self.t = {}

    def add(self, key, start):
        self.t[key] = self.t.get(key, 0.0) + time.perf_counter() - start
        return time.perf_counter()


def _trace(scene, camera, intersector, chunk):
    """capture.Surface batches of the pixels of `camera` that see the object (every pixel that
    can: usability is each photo's business), and the object mask (H, W) bool."""
    mask = np.zeros(camera.shape, dtype=bool)
    if intersector is None:
        surfaces = [capture.surface_from_normal_map(scene.geometry, camera)]
    else:
        r0, r1, c0, c1 = capture.pixel_box(camera, intersector.mesh.bounds)
        rows, cols = (a.ravel() for a in np.indices((r1 - r0, c1 - c0)))
        rows += r0
        cols += c0
        surfaces = [capture.surface_at_pixels(intersector, camera, rows[s:s + chunk],
                                              cols[s:s + chunk], dtype=np.float32)
                    for s in range(0, len(rows), chunk)]
    for surface in surfaces:
        mask.ravel()[surface.rows * camera.width + surface.cols] = True
    return surfaces, mask


def _camera_normals(scene, camera, intersector):
    """normals_at(pixels (M,) flat indices) -> (M, 3) float32 shading normals in `camera`'s frame,
    0 where the pixel's ray misses the object. Segmentation asks where the surface can see itself
    (slice_extract.segment.nonconvex_mask) at a subsample of pixels: tracing those again costs
    milliseconds, where a 12-MP normal image kept from the trace cost ~0.7 s and 144 MB on every
    extraction."""
    def normals_at(pixels):
        pixels = np.asarray(pixels, np.int64)
        if intersector is None:
            surface = capture.surface_from_normal_map(scene.geometry, camera)
            image = np.zeros((camera.height * camera.width, 3), np.float32)
            image[surface.rows * camera.width + surface.cols] = surface.normals @ camera.rotation
            return image[pixels]
        unique, back = np.unique(pixels, return_inverse=True)
        rows, cols = np.divmod(unique, camera.width)
        surface = capture.surface_at_pixels(intersector, camera, rows, cols, dtype=np.float32)
        found = np.zeros((len(unique), 3), np.float32)
        found[np.searchsorted(unique, surface.rows * camera.width + surface.cols)] = \
            surface.normals @ camera.rotation
        return found[back]
    return normals_at


def silhouette_mask(object_mask, width_px):
    """(H, W) bool: object pixels within width_px (Chebyshev) of a pixel that sees no object.

    Such pixels mix object and background in any real or filtered image (optics, demosaicing,
    a renderer's reconstruction filter: Mitsuba's default Gaussian puts ~13% of a neighbour's
    light into a pixel, and < 0.1% from two pixels away). The image frame is not an edge.
    """
    if width_px <= 0:
        return np.zeros_like(object_mask)
    kernel = np.ones((2 * width_px + 1, 2 * width_px + 1), np.uint8)
    inner = cv2.erode(object_mask.astype(np.uint8), kernel, borderType=cv2.BORDER_REPLICATE)
    return object_mask & ~inner.astype(bool)


def _no_sample_error(scene, per_photo):
    totals = {k: sum(p[k] for p in per_photo) for k in per_photo[0] if k != "photo"}
    photo = scene.photos_with_role("flash")[0]
    if totals["usable"] == 0:
        where = photo.file or photo.brackets[0][0]
        clipped = f" ({totals['clipped']} clipped, over-exposed)" if totals["clipped"] else ""
        return InputError(where, f"no usable pixel: the photo is black, clipped or non-finite"
                                 f"{clipped}")
    if totals["on_surface"] == 0:
        return InputError(f"{scene.json_path}: geometry", "no usable pixel sees the object: the "
                          "camera does not see the geometry (check world_from_camera and units)")
    worst = max(REASONS, key=lambda k: totals[k])
    return InputError(f"{scene.json_path}: photos", f"no pixel passed the tests (rejected: "
                      f"{', '.join(f'{k} {totals[k]}' for k in REASONS)}; mostly '{worst}')")


def _check_above_ambient(scene, rho):
    """InputError naming the ambient photo when flash - ambient is <= 0 at 99% or more of the
    object's usable pixels (rho (N, 3) 1/sr, +inf where censored): the ambient photo is as bright
    as the flash photo (the same file, or the two swapped), and the slice would be 0 everywhere.
    Not at "most": off its highlights a chrome object holds only noise, half of it below 0.
    One pass over the samples (up to 12 million): a censored sample is clipped, so lit (> 0)."""
    ambient = scene.photos_with_role("ambient")
    if not ambient or len(rho) == 0:
        return
    above = np.count_nonzero(rho[:, 0] + rho[:, 1] + rho[:, 2] > 0)
    if above < 0.01 * len(rho):
        where = ambient[0].file or ambient[0].where
        raise InputError(where, f"the flash photo minus this ambient photo is <= 0 at "
                                f"{1 - above / len(rho):.0%} of the object's usable pixels: the "
                                "ambient photo is as bright as the flash photo (the same photo, "
                                "or the two swapped?)")


@dataclass(eq=False)
class FlashSamples:
    """Every flash photo's samples, pooled, before binning (what extraction and segmentation share).

    theta_h, theta_d (N,) radians; rho (N, 3) 1/sr (+inf where censored); censored (N,) bool;
    pixels (N,) int flat index row * width + col in its photo; photo (N,) int index into
    scene.photos_with_role("flash"); shape (H, W) of the first flash photo's camera;
    object_mask (H, W) bool: pixels of that camera whose ray meets the object; face_image (H, W)
    int64 face hit per pixel (-1 none), or None for normal-map geometry; radiance (H, W, 3) of the
    first flash photo; per_photo, timings: for the extraction report; normals_at: a callable,
    flat pixel indices (M,) of that camera -> (M, 3) float32 unit shading normals in its frame
    (0 off the object), traced when asked (segmentation's concavity test asks for a subsample),
    or None.
    """
    scene: object
    options: object
    theta_h: np.ndarray
    theta_d: np.ndarray
    rho: np.ndarray
    censored: np.ndarray
    pixels: np.ndarray
    photo: np.ndarray
    shape: tuple
    object_mask: np.ndarray
    face_image: np.ndarray
    radiance: np.ndarray
    per_photo: list
    timings: dict
    started: float
    normals_at: object = None

    def no_sample_error(self):
        """The InputError (naming the flash photo, the geometry or the photos' tests) for
        samples of which none is usable."""
        return _no_sample_error(self.scene, self.per_photo)

    def subset(self, keep):
        """The same samples restricted to keep (N,) bool (e.g. one material)."""
        pick = {k: getattr(self, k)[keep] for k in ("theta_h", "theta_d", "rho", "censored",
                                                     "pixels", "photo")}
        return FlashSamples(**{**self.__dict__, **pick})


def collect_samples(scene, options=None):
    """Trace the flash photos and compute every usable pixel's sample; returns FlashSamples.

    scene: scene folder path or capture.Scene; options: ExtractOptions. InputError (exit 2) for
    bad input.
    """
    options = options or ExtractOptions()
    clock, start, t0 = _Clock(), time.perf_counter(), time.perf_counter()
    if not isinstance(scene, capture.Scene):
        scene = capture.load_scene(scene)
    normal_map = scene.geometry.mesh is None
    for photo in scene.photos_with_role("flash"):
        if normal_map and photo.light.type == "point":
            raise InputError(f"{photo.where}.light.type", "a point light needs surface depth, "
                             "which normal-map geometry lacks: use a mesh or a directional light")
    t = clock.add("load_scene", t0)
    images = capture.load_flash_images(scene)
    t = clock.add("load_photos", t)
    intersector = None if normal_map else capture.scene_intersector(scene)
    needs_shadows = options.shadow_rays and not normal_map and not all(
        light_setup(img.photo).at_viewpoint for img in images)
    # convexity costs a face-adjacency pass: only ask when a shadow ray could be needed
    convex = needs_shadows and capture.is_convex(intersector)
    t = clock.add("load_mesh", t)

    parts, per_photo, photo_of_part = [], [], []
    first_mask, face_image, normals_at = None, None, None
    groups = {}
    for k, img in enumerate(images):
        groups.setdefault(id(img.photo.camera), []).append(k)
    for members in groups.values():
        camera = images[members[0]].photo.camera
        lights = {k: light_setup(images[k].photo) for k in members}
        stats = {k: dict(photo=images[k].photo.stem, usable=int(images[k].usable.sum()),
                         clipped=int(images[k].clipped.sum()), on_surface=0,
                         **dict.fromkeys(REASONS, 0)) for k in members}
        surfaces, object_mask = _trace(scene, camera, intersector, options.chunk_pixels)
        if first_mask is None:
            first_mask = object_mask
            normals_at = _camera_normals(scene, camera, intersector)
            if not normal_map:
                face_image = np.full(camera.shape, -1, dtype=np.int64)
                for surface in surfaces:
                    face_image[surface.rows, surface.cols] = surface.face
        edge = silhouette_mask(object_mask, options.silhouette_px)
        t = clock.add("trace", t)
        for surface in surfaces:
            for k in members:
                skip = not needs_shadows or convex or lights[k].at_viewpoint
                shadow = None if skip else intersector
                got = photo_samples(images[k].radiance, images[k].usable, surface, lights[k],
                                    options, shadow, images[k].clipped, edge)
                stats[k]["on_surface"] += got.n_usable
                for reason, count in got.rejected.items():
                    stats[k][reason] += count
                parts.append(got)
                photo_of_part.append(k)
            t = clock.add("samples", t)
        per_photo.extend(stats[k] for k in members)

    def pooled(name, empty):
        return np.concatenate([getattr(p, name) for p in parts]) if parts else empty

    photo = (np.concatenate([np.full(len(p.theta_h), k) for p, k in zip(parts, photo_of_part)])
             if parts else np.zeros(0, int))
    rho = pooled("rho", np.zeros((0, 3)))
    _check_above_ambient(scene, rho)
    return FlashSamples(scene, options, pooled("theta_h", np.zeros(0)),
                        pooled("theta_d", np.zeros(0)), rho,
                        pooled("censored", np.zeros(0, bool)), pooled("pixels", np.zeros(0, int)),
                        photo, images[0].photo.camera.shape, first_mask, face_image,
                        images[0].radiance, per_photo, clock.t, start, normals_at)


def bin_samples(samples):
    """The slice (SliceResult) of FlashSamples: robust binning over the 90 theta_h bins.

    InputError (exit 2) when no sample is usable or every bin is mostly clipped.
    """
    scene, options = samples.scene, samples.options
    clock = _Clock()
    clock.t = dict(samples.timings)
    t = time.perf_counter()
    theta_h, theta_d, rho, censored = (samples.theta_h, samples.theta_d, samples.rho,
                                       samples.censored)
    if not np.any(~censored):
        raise samples.no_sample_error()
    bins = merl_bin_index(theta_h, 0.0, 0.0)[0]
    estimate, n, spread, inlier = robust_bins(bins, rho, censored, theta_h, k=options.outlier_k,
                                              estimator=options.estimator)
    if not np.any(n):
        raise InputError(f"{scene.json_path}: photos", "every observed theta_h bin is more than "
                         "half clipped (over-exposed): no bin can be estimated")
    # A robust estimate of a near-black bin can dip below 0 through noise; a BRDF cannot (and
    # slice.csv readers reject it), so such bins become 0 here, and the report counts them.
    negative = np.isfinite(estimate) & (estimate < 0)
    estimate = np.where(negative, 0.0, estimate)
    known = estimate[~np.isnan(estimate)]
    if known.size and not known.max() <= MAX_SLICE_VALUE:  # slice.csv readers refuse it
        raise NotABRDFError(f"{scene.json_path}: photos", "the flash photos give BRDF values up "
                            f"to {known.max():.3g} 1/sr, above {MAX_SLICE_VALUE:g}: not a BRDF "
                            "(check their pixel values, scale and the light's intensity)")
    clock.add("binning", t)
    clock.t["total"] = time.perf_counter() - samples.started
    report = _report(scene, options, samples.per_photo, theta_h, theta_d, inlier, n, clock.t,
                     np.bincount(bins[censored], minlength=N_THETA_H), censored)
    report["clamped_negative_bins"] = int(negative.any(axis=1).sum())
    return SliceResult(estimate, n, spread, report)


def extract_slice(scene, options=None):
    """The flash slice of a capture folder.

    scene: scene folder path or capture.Scene; options: ExtractOptions (defaults above).
    Returns SliceResult. InputError (exit 2) for bad input or when no pixel gives a sample.
    """
    return bin_samples(collect_samples(scene, options))


def extract_material_slices(samples, labels, where="--labels"):
    """One SliceResult per material: {k: SliceResult} for k = 1..labels.max().

    samples: FlashSamples; labels (H, W) int in the first flash photo's pixel grid (0 = not the
    object). Every flash photo must share that grid. A material's slice leaves out its samples
    within segment.border_width_px of another material (label borders are the least sure),
    except in theta_h bins the interior alone would leave with < BORDER_MIN_BIN samples. A material whose pixels give no usable
    sample gets None (the caller reports it). InputError for a wrong-sized label image or a
    label in 1..K with no pixel.
    """
    labels = np.asarray(labels)
    check_labels(labels, samples.shape, where)
    flash = samples.scene.photos_with_role("flash")
    if any(p.camera.shape != tuple(samples.shape) for p in flash):
        raise InputError(where, "the flash photos have different pixel grids: one label image "
                                "cannot cover them")
    count = int(labels.max())
    of_sample = np.take(labels.ravel(), samples.pixels)
    width = border_width_px(np.count_nonzero(labels))
    interior = np.take(material_interior(labels, width).ravel(), samples.pixels)
    bins = merl_bin_index(samples.theta_h, 0.0, 0.0)[0]
    slices = {}
    for k in range(1, count + 1):
        mine = of_sample == k
        keep = _interior_samples(mine, interior, bins)
        try:
            slices[k] = bin_samples(samples.subset(keep))
        except NotABRDFError:  # the photos' fault, not this material's coverage
            raise
        except InputError:  # no usable sample for this material: the others go on
            slices[k] = None
            continue
        slices[k].report["material_border"] = {
            "width_px": width, "samples": int(mine.sum()),
            "border_samples_dropped": int(np.count_nonzero(mine & ~keep))}
    return slices


def _interior_samples(mine, interior, bins, min_bin=BORDER_MIN_BIN):
    """(N,) bool: a material's samples (mine (N,) bool) away from its borders with other
    materials (interior (N,) bool), except in the theta_h bins (bins (N,) int) where the
    interior keeps fewer than min_bin samples: there every sample of the material stays, so
    dropping the border never costs the slice a bin (nor thins a bin below min_bin)."""
    inner = mine & interior
    thin = np.bincount(bins[inner], minlength=N_THETA_H) < min_bin
    return inner | (mine & thin[bins])


def _report(scene, options, per_photo, theta_h, theta_d, inlier, n, timings, bin_clipped,
            censored):
    total_pixels = sum(p.camera.width * p.camera.height for p in scene.photos_with_role("flash"))
    rejected = {"unusable": total_pixels - sum(p["usable"] + p["clipped"] for p in per_photo),
                "clipped": sum(p["clipped"] for p in per_photo),
                "miss": sum(p["usable"] - p["on_surface"] for p in per_photo)}
    rejected.update({k: sum(p[k] for p in per_photo) for k in REASONS})
    rejected["outlier"] = int(np.count_nonzero(~inlier & ~censored))
    used = theta_h[inlier]
    filled = slice_coverage(n > 0)
    coverage = {
        "theta_h_deg_observed": [float(np.degrees(used.min())), float(np.degrees(used.max()))],
        **{k: filled[k] for k in ("bins_filled", "first_bin", "last_bin", "theta_h_deg_filled",
                                  "empty_bins")},
        "clipped_per_bin": {int(i): int(bin_clipped[i]) for i in np.flatnonzero(bin_clipped)},
        "pixels_total": int(total_pixels), "pixels_used": int(inlier.sum()),
    }
    return {"scene": str(scene.json_path),
            "options": {k: getattr(options, k) for k in ("max_theta_d_deg", "min_cos",
                                                         "silhouette_px", "outlier_k",
                                                         "estimator")},
            "coverage": coverage, "rejected": {k: int(v) for k, v in rejected.items()},
            "theta_d_deg": _stats_deg(theta_d[inlier]), "photos": per_photo,
            "n": [int(v) for v in n], "timings_s": {k: round(v, 4) for k, v in timings.items()}}



