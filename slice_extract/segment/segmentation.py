"""The segmentation of a flash photo's samples into materials: the entry point (segment_samples).
"""

import numpy as np
from threadpoolctl import threadpool_limits

from flashbrdf.capture import load_mesh
from flashbrdf.capture.scene import same_view
from flashbrdf.files.errors import InputError
from flashbrdf.slice_extract.segment.clustering import Segmentation, SegmentOptions, cluster_samples
from flashbrdf.slice_extract.segment.features import (
    log_samples,
    material_features,
    resolution_floor,
    theta_h_bins,
)
from flashbrdf.slice_extract.segment.labels import (align_bin_labels, clean_label_image,
                                                    face_label_agreement, face_labels,
                                                    face_parts)
from flashbrdf.slice_extract.segment.slices import assign_all, refine_labels

# share of the flash view's labelled pixels whose face carries their label, at least (faces
# straddling a border between materials cost a few percent)
FACES_CARRY = 0.9


def segment_samples(samples, materials="auto", options=None, empty_ok=False):
    """Segmentation of FlashSamples (slice_extract.extract.collect_samples) of the first flash
    photo; materials: "auto" or an int K >= 1 (then the mixture has K components, unmerged).
    empty_ok: with materials 1, a first flash photo that sees no object pixel gives an empty
    label image (`run`, which needs no labels for one material) instead of an InputError."""
    options = options or SegmentOptions()
    with threadpool_limits(1):  # tiny 3x3 algebra: BLAS threads only contend on a busy machine
        return _segment_samples(samples, materials, options, empty_ok)


def _segment_samples(samples, materials, options, empty_ok):
    rho, theta_h, pixels, censored = samples.first_photo()
    first = ~censored & np.all(np.isfinite(rho), axis=1)
    if not first.all():  # the usual case (one flash photo, nothing clipped) needs no copies
        rho, theta_h, pixels = rho[first], theta_h[first], pixels[first]
    if not len(rho):
        if len(samples.rho) == 0:  # nothing to segment: the error extracting a slice would give
            raise samples.no_sample_error()
        if materials != 1 or not empty_ok:
            photo = samples.scene.photos_with_role("flash")[0]
            raise InputError(photo.file or photo.brackets[0][0],
                             "the first flash photo has no usable object pixel, and "
                             "segmentation labels its pixels: list first a flash photo that "
                             "sees the object" + (", or give --materials 1" if empty_ok else ""))
    if materials == 1:  # one material by request: every object pixel, nothing to cluster
        labels = np.where(samples.object_mask, 1, 0).astype(np.int32)
        return Segmentation(labels, 1, {"samples": int(len(rho)), "reason": "--materials 1",
                                        "bins_renamed": 0, "chosen_k": 1})
    if materials == "auto":
        every = slice(None, None, max(1, len(rho) // 50000))  # no 12-MP gather for a floor
        at_least = resolution_floor(rho[every], samples.radiance.reshape(-1, 3)[pixels[every]])
        labels, k, criterion = cluster_samples(rho, theta_h, options, pixels, samples.shape,
                                               at_least, samples.normals_at)
    else:
        k = int(materials)
        if k > 1 and len(rho) < 2 * k:  # a K-component mixture needs 2K samples at least
            raise InputError("--materials", f"{k} materials need at least {2 * k} usable object "
                                            f"pixels; the flash photo has {len(rho)}")
        labels, criterion = _fixed_k(rho, theta_h, k, options)
    labels, renamed = align_bin_labels(labels, theta_h_bins(theta_h), pixels, samples.shape)
    criterion["bins_renamed"] = renamed
    image = np.zeros(samples.shape, np.int32)
    image.ravel()[pixels] = labels + 1
    cleaned = clean_label_image(image, samples.object_mask, options.min_area_fraction)
    criterion["chosen_k"] = int(cleaned.max())
    return Segmentation(cleaned, int(cleaned.max()), criterion)


def _fixed_k(rho, theta_h, k, options):
    """K given by the user: a K-component mixture, refined by K slices, no merging."""
    from sklearn.mixture import GaussianMixture  # lazy: +2.4 s on every import of slice_extract
    n = len(rho)
    if k == 1 or n < 2 * k:
        return np.zeros(n, int), {"samples": int(n), "reason": f"--materials {k}"}
    rng = np.random.default_rng(options.seed)
    pick = rng.choice(n, size=min(options.work_samples, n), replace=False)
    features, _ = material_features(rho[pick], theta_h[pick])
    fit = rng.choice(len(pick), size=min(options.fit_samples, len(pick)), replace=False)
    x = features / (features[fit].std(axis=0) + 1e-6)
    gm = GaussianMixture(k, covariance_type="full", reg_covar=1e-4, init_params="k-means++",
                         random_state=options.seed).fit(x[fit])
    log_rho, _, _ = log_samples(rho[pick])
    labels, kept = refine_labels(log_rho, theta_h_bins(theta_h[pick]), gm.predict(x), k, options)
    reason = f"--materials {k}" + ("" if kept == k else
                                   f"; {kept} kept: the slices of the others explained under "
                                   f"{options.min_fraction:.0%} of the pixels each")
    return assign_all(rho, theta_h, pick, labels, kept), {"samples": int(n), "reason": reason}


def segment_scene(samples, materials="auto", options=None, empty_ok=False):
    """(Segmentation, face labels (F,) int32 or None) of FlashSamples: with a mesh, each face
    takes its pixels' label (face_labels). empty_ok: see segment_samples."""
    segmentation = segment_samples(samples, materials, options, empty_ok)
    faces = None
    if samples.face_image is not None:
        mesh = samples.mesh if samples.mesh is not None else \
            load_mesh(samples.scene.geometry.mesh)[0]
        parts = face_parts(mesh.vertices, mesh.faces) if segmentation.k > 1 else None
        faces = face_labels(segmentation.labels, samples.face_image, mesh.triangles_center,
                            parts)
        if segmentation.k > 1:
            share = face_label_agreement(segmentation.labels, samples.face_image, faces)
            if share is not None:
                segmentation.criterion["faces_agree"] = round(share, 4)
    return segmentation, faces


def coarse_faces_warning(segmentation, faces, scene):
    """A warning line when the mesh's faces carry the flash view's materials on under
    FACES_CARRY of its labelled pixels and some photo from another camera takes its materials
    from them (LABELS.faces.npy); else None. Those photos then get a face's majority material
    where the flash photo shows several, silently (a 2-triangle card: every view one ink)."""
    share = segmentation.criterion.get("faces_agree")
    flash = scene.photos_with_role("flash")
    if faces is None or share is None or share >= FACES_CARRY or not flash:
        return None
    others = [p for p in scene.photos if p.role in ("flash", "reference")
              and not same_view(p.camera, flash[0].camera)]
    if not others:
        return None
    return (f"the mesh's {len(faces)} faces carry the flash view's {segmentation.k} materials "
            f"on only {share:.0%} of its labelled pixels (a face takes its pixels' majority "
            f"material): the {len(others)} photo(s) from other cameras take their materials "
            "from the faces, so they are wrong where a face spans several; subdivide the mesh "
            "into faces smaller than the materials' patches")
