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
from dataclasses import dataclass, field, replace
from types import SimpleNamespace

import numpy as np

from flashbrdf import capture
from flashbrdf.brdf.angles import merl_bin_index
from flashbrdf.files.errors import InputError
from flashbrdf.brdf.merl import N_THETA_H
from flashbrdf.brdf.views import MAX_SLICE_VALUE
from flashbrdf.slice_extract.binning import robust_bins
from flashbrdf.slice_extract.options import ExtractOptions
from flashbrdf.slice_extract.sample_store import SAMPLE_FIELDS, SampleStore
from flashbrdf.slice_extract.visibility import (camera_normals, depth_edge_mask, silhouette_mask,
                                               trace_camera)
from flashbrdf.slice_extract.level import (TARGET_MIN_COS, calibrated_record, relative_record,
                                          target_level, trace_target)
from flashbrdf.slice_extract.pose_refine import log_gradient, refine_flash_cameras
from flashbrdf.slice_extract.samples import REASONS, light_setup, photo_samples
from flashbrdf.slice_extract.slice_files import extraction_report, photo_levels as photo_level_check
from flashbrdf.slice_extract.segment import (BORDER_MIN_BIN, border_width_px, check_labels,
                                   material_interior)
from flashbrdf.files.progress import photo_progress


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


class _Clock:
    def __init__(self):
        self.t = {}

    def add(self, key, start):
        self.t[key] = self.t.get(key, 0.0) + time.perf_counter() - start
        return time.perf_counter()


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
    object's usable pixels (rho (N, 3) 1/sr, a lower bound where censored): the ambient photo is
    as bright as the flash photo (the same file, or the two swapped), and the slice would be 0
    everywhere.
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

    theta_h, theta_d (N,) radians; rho (N, 3) 1/sr (a lower bound where censored); censored
    (N,) bool; pixels (N,) int flat index row * width + col in its photo; photo (N,) int index into
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
    # the first photo's samples whole ({field: array}) when the pooled ones were subsampled
    # (SampleStore); None otherwise, as the pooled arrays then hold them all
    first_photo_samples: dict = None
    face: np.ndarray = None  # (N,) int32 mesh face of each sample, -1 for normal-map geometry
    level: dict = None       # slice.json's "level": absolute (target, calibrated) or relative
    mesh: object = None      # the scene's trimesh as traced (None for normal-map geometry):
    #                          segmentation and material borders read it, not the file again
    log_gradient: np.ndarray = None  # (N, 2) grad ln I per sample, with options.log_gradients
    intersector: object = None  # capture.MeshIntersector of that mesh: render reuses its BVH

    def first_photo(self):
        """(rho (M, 3), theta_h (M,), pixels (M,), censored (M,)) of every sample of the first
        flash photo, as segmentation reads it."""
        if self.first_photo_samples is not None:
            part = self.first_photo_samples
            return part["rho"], part["theta_h"], part["pixels"], part["censored"]
        first = self.photo == 0
        if first.all():
            return self.rho, self.theta_h, self.pixels, self.censored
        return self.rho[first], self.theta_h[first], self.pixels[first], self.censored[first]

    def no_sample_error(self):
        """The InputError (naming the flash photo, the geometry or the photos' tests) for
        samples of which none is usable."""
        return _no_sample_error(self.scene, self.per_photo)

    def subset(self, keep):
        """The same samples restricted to keep (N,) bool (e.g. one material)."""
        pick = {k: getattr(self, k)[keep] for k in ("theta_h", "theta_d", "rho", "censored",
                                                     "pixels", "photo", "face", "log_gradient")
                if getattr(self, k) is not None}
        return FlashSamples(**{**self.__dict__, **pick})


def collect_samples(scene, options=None):
    """Trace the flash photos and compute every usable pixel's sample; returns FlashSamples.

    Photos are read one at a time (capture.iter_flash_images decodes the next meanwhile) and each
    camera is traced once: memory holds three photos (the first, for segmentation, this one and
    the next), one camera's traced surface and the pooled samples (SampleStore).
    scene: scene folder path or capture.Scene; options: ExtractOptions. InputError (exit 2) for
    bad input.
    """
    options = options or ExtractOptions()
    clock, start, t0 = _Clock(), time.perf_counter(), time.perf_counter()
    if not isinstance(scene, capture.Scene):
        scene = capture.load_scene(scene)
    poses = None
    if options.refine_poses:  # its passes are timed apart, not as load_scene
        plain = replace(options, refine_poses=False, log_gradients=True)
        scene, poses = refine_flash_cameras(scene, lambda s: _measured(s, plain))
        t0 = clock.add("refine_poses", t0)
    normal_map = scene.geometry.mesh is None
    flashes = scene.flash_photos()
    for photo in flashes:
        if normal_map and photo.light.type == "point":
            raise InputError(f"{photo.where}.light.type", "a point light needs surface depth, "
                             "which normal-map geometry lacks: use a mesh or a directional light")
    lights = [light_setup(photo) for photo in flashes]
    t = clock.add("load_scene", t0)
    intersector = None if normal_map else capture.scene_intersector(scene)
    level = scene.level
    target = None
    if level is not None and level.target_mesh is not None:
        target_mesh, has_normals = capture.load_mesh(level.target_mesh)
        target = capture.MeshIntersector(target_mesh, use_vertex_normals=has_normals)
    target_rho, target_options = [], replace(options, min_cos=max(options.min_cos,
                                                                  TARGET_MIN_COS))
    needs_shadows = options.shadow_rays and not normal_map and not all(
        light.at_viewpoint for light in lights)
    # convexity costs a face-adjacency pass: only ask when a shadow ray could be needed
    convex = needs_shadows and capture.is_convex(intersector)
    t = clock.add("load_mesh", t)

    store, per_photo, first = SampleStore(options), [], None
    names = capture.photo_labels(flashes, scene.json_path.parent)
    traced_camera, surfaces, object_mask, edge = None, None, None, None
    images = capture.iter_flash_images(scene)
    for k in photo_progress(range(len(flashes)), "extract"):
        image = next(images)
        t = clock.add("load_photos", t)
        camera = image.photo.camera
        if traced_camera is not camera:  # one trace per camera (photos sharing it reuse it)
            surfaces = None  # let the previous camera's go before tracing the next
            surfaces, object_mask, depth = trace_camera(scene, camera, intersector,
                                                  options.chunk_pixels)
            edge = silhouette_mask(object_mask, options.silhouette_px) | depth_edge_mask(
                depth, camera, options.depth_edge_slope, options.silhouette_px)
            if target is not None:  # the target's pixels, in front of the object, are not its
                # distance sets the level only under a point light, seen through a pinhole
                distance_matters = (camera.model == "pinhole"
                                    and image.photo.light.type == "point")
                target_surfaces, target_mask = trace_target(
                    target, camera, depth, options.chunk_pixels,
                    f"{scene.json_path}: level.target" if distance_matters else None)
                target_edge = silhouette_mask(target_mask, options.silhouette_px)
                edge |= target_mask
            del depth
            traced_camera = camera
        name = names[image.photo.index]
        stats = dict(photo=name, usable=int(image.usable.sum()),
                     clipped=int(image.clipped.sum()), on_surface=0, **dict.fromkeys(REASONS, 0),
                     not_needed=0, **({} if poses is None else {"pose": poses[name]}))
        if stats["clipped"]:  # clipped pixels whose value is no bound (slice_files' warning)
            stats["clipped_unbounded"] = int(np.count_nonzero(
                image.clipped & ~np.isfinite(image.radiance).all(axis=-1)))
        t = clock.add("trace", t)
        skip = not needs_shadows or convex or lights[k].at_viewpoint
        parts = []
        for surface in surfaces:
            got = photo_samples(image.radiance, image.usable, surface, lights[k], options,
                                None if skip else intersector, image.clipped, edge, store.sieve)
            stats["on_surface"] += got.n_usable
            stats["not_needed"] += got.not_needed
            for reason, count in got.rejected.items():
                stats[reason] += count
            parts.append(got)
        if target is not None:
            for surface in target_surfaces:
                got = photo_samples(image.radiance, image.usable, surface, lights[k],
                                    target_options, None if lights[k].at_viewpoint else intersector,
                                    image.clipped, target_edge)
                target_rho.append(got.rho[~got.censored])
        per_photo.append(stats)
        part = {name: np.concatenate([getattr(p, name) for p in parts])
                for name in SAMPLE_FIELDS[:-2]} if parts else None
        if part is not None:
            part["face"] = (np.concatenate([p.face for p in parts]) if parts[0].face is not None
                            else np.full(len(part["theta_h"]), -1, np.int32))
        if part is not None:
            part["photo"] = np.full(len(part["theta_h"]), k)
            if parts[0].key is not None:
                part["key"] = np.concatenate([p.key for p in parts])
            if options.log_gradients:
                part["log_gradient"] = log_gradient(image, part["pixels"])
        if k == 0:  # segmentation reads the first photo whole, whatever the store keeps
            first = _FirstPhoto(part, object_mask, image.radiance, surfaces, camera,
                                normal_map, scene, intersector)
        if part is not None:
            store.add(part)
        del image, parts, part
        t = clock.add("samples", t)
    pooled = store.pooled()
    _check_above_ambient(scene, pooled["rho"])
    if target is not None:
        factor, level_report = target_level(
            np.concatenate(target_rho) if target_rho else np.zeros((0, 3)), level,
            f"{scene.json_path}: level.target")
        pooled["rho"] = pooled["rho"] * factor
        if first.samples is not None and store.subsampled:
            first.samples["rho"] = first.samples["rho"] * factor
        level_report["flash_intensity_rgb"] = [
            (np.asarray(light.power) / factor).tolist() for light in lights]
    elif level is not None and level.calibrated:
        level_report = calibrated_record()
    else:
        level_report = relative_record(scene)
    samples = FlashSamples(scene, options, pooled["theta_h"], pooled["theta_d"], pooled["rho"],
                           pooled["censored"], pooled["pixels"], pooled["photo"],
                           flashes[0].camera.shape, first.object_mask, first.face_image,
                           first.radiance, per_photo, clock.t, start, first.normals_at,
                           first.samples if store.subsampled else None, pooled["face"],
                           level_report, None if intersector is None else intersector.mesh,
                           pooled.get("log_gradient"), intersector)
    return samples


class _FirstPhoto:
    """What segmentation needs of the first flash photo: all its samples, its object mask, face
    image, radiance and a normals look-up."""

    def __init__(self, part, object_mask, radiance, surfaces, camera, normal_map, scene,
                 intersector):
        self.samples = part
        self.object_mask, self.radiance = object_mask, radiance
        self.normals_at = camera_normals(scene, camera, intersector)
        self.face_image = None
        if not normal_map:
            self.face_image = np.full(camera.shape, -1, dtype=np.int32)
            for surface in surfaces:
                self.face_image[surface.rows, surface.cols] = surface.face


def _measured(scene, options):
    """One pass for refine_flash_cameras: (the pooled samples' photo, theta_h, rho, censored and
    log_gradient; binned rho (90, 3)). The rest (the first photo: ~0.7 GB at 24 MP) is let go."""
    samples = collect_samples(scene, options)
    gradient = samples.log_gradient if samples.log_gradient is not None else np.zeros((0, 2))
    return (SimpleNamespace(photo=samples.photo, theta_h=samples.theta_h, rho=samples.rho,
                            censored=samples.censored, log_gradient=gradient),
            bin_samples(samples, photo_levels=False).rho)


def bin_samples(samples, photo_levels=True):
    """The slice (SliceResult) of FlashSamples: robust binning over the 90 theta_h bins.
    photo_levels: record each photo's level against the slice and warn of those far off it
    (slice_files.photo_levels); not for the pool of several materials, whose views may each
    see another mix of them.

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
                                              estimator=options.estimator, photo=samples.photo)
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
    report = extraction_report(scene, options, samples.per_photo, theta_h, theta_d, inlier, n,
                               clock.t, np.bincount(bins[censored], minlength=N_THETA_H),
                               censored)
    report["clamped_negative_bins"] = int(negative.any(axis=1).sum())
    report["level"] = samples.level
    if photo_levels:
        levels, warned = photo_level_check(samples.per_photo, bins, rho, censored, samples.photo,
                                           estimate)
        report["photos"] = [dict(p, **({"level_vs_slice": levels[k]} if k in levels else {}))
                            for k, p in enumerate(report["photos"])]
        report["warnings"] += warned
    return SliceResult(estimate, n, spread, report)


def extract_slice(scene, options=None):
    """The flash slice of a capture folder.

    scene: scene folder path or capture.Scene; options: ExtractOptions (defaults above).
    Returns SliceResult. InputError (exit 2) for bad input or when no pixel gives a sample.
    """
    return bin_samples(collect_samples(scene, options))


def extract_material_slices(samples, labels, where="--labels", face_labels=None):
    """One SliceResult per material: {k: SliceResult} for k = 1..labels.max().

    samples: FlashSamples; labels (H, W) int in the first flash photo's pixel grid (0 = not the
    object); face_labels (F,) int 1..K, a label per mesh face (LABELS.faces.npy), for the
    samples of flash photos taken from other views (a multi-view capture), or None. A
    material's slice leaves out its samples within segment.border_width_px of another material
    (label borders are the least sure), in other views those on a face next to another
    material's, except in theta_h bins the interior alone would leave with < BORDER_MIN_BIN
    samples. A material whose pixels give no usable sample gets None (the caller reports it).
    InputError for a wrong-sized label image, a label in 1..K with no pixel, or other views
    without face labels.
    """
    labels = np.asarray(labels)
    check_labels(labels, samples.shape, where)
    flash = samples.scene.photos_with_role("flash")
    in_first_view = np.array([capture.same_view(p.camera, flash[0].camera) for p in flash])
    by_pixel = in_first_view[samples.photo]
    count = int(labels.max())
    width = border_width_px(np.count_nonzero(labels))
    of_sample = np.zeros(len(samples.photo), np.int64)
    interior = np.ones(len(samples.photo), bool)
    of_sample[by_pixel] = np.take(labels.ravel(), samples.pixels[by_pixel])
    interior[by_pixel] = np.take(material_interior(labels, width).ravel(),
                                 samples.pixels[by_pixel])
    if not by_pixel.all():
        if face_labels is None or samples.face is None or np.any(samples.face[~by_pixel] < 0):
            raise InputError(where, "the flash photos come from several views: the other views' "
                                    "pixels take their material from the mesh faces "
                                    "(LABELS.faces.npy beside the label image), which is missing")
        face_labels = np.asarray(face_labels)
        faces = samples.face[~by_pixel]
        of_sample[~by_pixel] = face_labels[faces]
        interior[~by_pixel] = ~_border_faces(samples, face_labels)[faces]
    bins = merl_bin_index(samples.theta_h, 0.0, 0.0)[0]
    slices = {}
    for k in range(1, count + 1):
        mine = of_sample == k
        keep = interior_samples(mine, interior, bins)
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


def _border_faces(samples, face_labels):
    """(F,) bool: mesh faces that share an edge with a face of another material."""
    mesh = samples.mesh if samples.mesh is not None else \
        capture.load_mesh(samples.scene.geometry.mesh)[0]
    if len(face_labels) != len(mesh.faces):
        raise InputError("LABELS.faces.npy", f"has {len(face_labels)} labels but the mesh has "
                                             f"{len(mesh.faces)} faces")
    pairs = mesh.face_adjacency
    differ = face_labels[pairs[:, 0]] != face_labels[pairs[:, 1]]
    border = np.zeros(len(mesh.faces), bool)
    border[pairs[differ].ravel()] = True
    return border


def interior_samples(mine, interior, bins, min_bin=BORDER_MIN_BIN):
    """(N,) bool: a material's samples (mine (N,) bool) away from its borders with other
    materials (interior (N,) bool), except in the theta_h bins (bins (N,) int) where the
    interior keeps fewer than min_bin samples: there every sample of the material stays, so
    dropping the border never costs the slice a bin (nor thins a bin below min_bin)."""
    inner = mine & interior
    thin = np.bincount(bins[inner], minlength=N_THETA_H) < min_bin
    return inner | (mine & thin[bins])
