"""Flash cameras refined against the photos (`extract --refine-poses`): a pose a pixel off blurs
the specular lobe, because every pixel then takes the normal of a surface point beside its own.

Each view's error shows as a shift between its photo and what the pooled slice predicts there:
the measured rho of a pixel against the slice's rho at the pixel's theta_h. For a small error
the photo's content sits at x + d where the traced geometry sits at x, so, to first order,
    ln rho_measured(x) + grad ln I(x) . d = ln rho_slice(theta_h(x))
and d (pixels, 2) is the least-squares solution over the view's samples (Lucas-Kanade on the
log-luminance, against a prediction pooled over every view, so that the views' random errors do
not align each other with themselves). The camera is then turned about its centre by d / f
across its optical axis, its flash with it: its pixel x sees what pixel x - d saw, to first
order (the intrinsics stay, and with them the lens' cached undistortion grid). The
slice is measured again with the corrected cameras, up to `iterations` times.

A view keeps no correction (and says why) when its samples cannot fix a shift to 0.05 px (the
least-squares standard error: a flat or noisy photo), when the total exceeds MAX_SHIFT_PX (not a
pose a pixel off but a wrong model, which a shift would only hide), or when it is under
MIN_SHIFT_PX (noise: right cameras stay exactly as they were). Orthographic views are left as
they are.
"""

from dataclasses import replace

import cv2
import numpy as np

from flashbrdf import capture
from flashbrdf.brdf.merl import theta_h_centres

MAX_SHIFT_PX = 2.0
# a total under this is left out: on exact cameras the fit finds up to ~0.1 px from how the
# pixel filter spreads a highlight (Mitsuba's Gaussian), and such a shift only adds its own error
MIN_SHIFT_PX = 0.1
MIN_SAMPLES = 200
# a shift is fixed only when the view's samples pin it down: its standard error (the fit's
# residual over the log-luminance gradients, whatever the resolution) under this many px
MAX_SHIFT_ERROR_PX = 0.05
MAX_RESIDUAL = 0.5  # ln units: pixels off by more than x1.6 are outliers, not a shift
CONVERGED_PX = 0.05


def refine_flash_cameras(scene, measure, iterations=3):
    """(scene with refined flash cameras, record): record[photo name] = {"shift_px": [du, dv]
    total image shift (applied as a turn of the camera, _turned), "refined": bool, "note": why
    not, when not}; the name is capture.photo_labels' (the stem, unless two photos share it).

    scene: capture.Scene; measure(scene) -> (FlashSamples, rho (90, 3) binned slice): one
    extraction pass (slice_extract.extract supplies it: this module runs no extraction itself).
    """
    views = _views(scene)
    total = {key: np.zeros(2) for key in views}
    notes = {key: "orthographic: not refined" for key, photos in views.items()
             if photos[0].camera.model != "pinhole"}
    current = scene
    # nothing to refine (every view orthographic, e.g. DiLiGenT): no pass, the extraction is one
    for _ in range(iterations if len(notes) < len(views) else 0):
        samples, slice_rho = measure(current)
        step = view_shifts(current, samples, slice_rho, views)
        del samples  # before the next pass: two passes' samples would double the peak memory
        for key, (d, note) in step.items():
            if note is not None:
                notes[key] = note
                continue
            total[key] += d
            if np.hypot(*total[key]) > MAX_SHIFT_PX:
                notes[key] = (f"a shift of {np.hypot(*total[key]):.1f} px: more than "
                              f"{MAX_SHIFT_PX:g} px is not a pose a pixel off")
        for key in notes:
            total[key] = np.zeros(2)
        current = _shifted(scene, views, total)
        if all(note is not None or np.hypot(*d) < CONVERGED_PX for d, note in step.values()):
            break
    for key in total:
        if key not in notes and np.hypot(*total[key]) < MIN_SHIFT_PX:
            notes[key] = f"{np.hypot(*total[key]):.3f} px: under {MIN_SHIFT_PX:g} px, kept as it is"
            total[key] = np.zeros(2)
    current = _shifted(scene, views, total)
    record = {}
    names = capture.photo_labels(scene.photos_with_role("flash"), scene.json_path.parent)
    for key, photos in views.items():
        for photo in photos:
            record[names[photo.index]] = {"shift_px": [round(float(v), 4) for v in total[key]],
                                          "refined": key not in notes}
            if key in notes:
                record[names[photo.index]]["note"] = notes[key]
    return current, record


def _views(scene):
    """{camera key: [flash photos taken from that view]}: one shift per view (photos of one
    view share their rays). Keys are the original cameras': shifted cameras keep them."""
    views = {}
    for photo in scene.photos_with_role("flash"):
        views.setdefault(capture.camera_key(photo.camera), []).append(photo)
    return views


def _view_of(views):
    """{photo index in scene.photos: camera key}."""
    return {photo.index: key for key, photos in views.items() for photo in photos}


def _shifted(scene, views, total):
    """The scene with each pinhole view turned by its total shift (_turned)."""
    view_of = _view_of(views)
    moved = {key: _turned(photos[0].camera, total[key]) for key, photos in views.items()
             if photos[0].camera.model == "pinhole" and np.any(total[key])}
    if not moved:
        return scene
    photos = [replace(p, camera=moved[view_of[p.index]]) if view_of.get(p.index) in moved else p
              for p in scene.photos]
    return replace(scene, photos=photos)


def _turned(camera, shift):
    """The pinhole camera turned about its centre, its flash with it (a flash position is in
    the camera frame), so that its pixel x sees what its pixel x - shift saw: to first order a
    turn by shift / f across the optical axis. The intrinsics stay, so every view keeps sharing
    its lens' cached undistortion grid."""
    turn, _ = cv2.Rodrigues(np.array([shift[1] / camera.fy, -shift[0] / camera.fx, 0.0]))
    pose = np.array(camera.world_from_camera, dtype=np.float64)
    pose[:3, :3] = pose[:3, :3] @ turn
    return replace(camera, world_from_camera=pose)


def view_shifts(scene, samples, slice_rho, views):
    """{camera key: (d (2,) px, None) or (None, note)}: each view's least-squares shift between
    its photo and the pooled slice's prediction at its samples (module docstring).

    samples carry, beside pixels, photo, theta_h, rho and censored (a clipped sample's rho is
    a lower bound, no measurement: left out), each sample's log_gradient (N, 2)
    (`log_gradient`, NaN where not usable), taken by the extraction pass that read the photo:
    a refinement round decodes every photo once."""
    centres = theta_h_centres()
    filled = np.all(np.isfinite(slice_rho), axis=1)
    level = np.where(filled, np.where(filled[:, None], slice_rho, 0.0).mean(axis=1), np.nan)
    known = filled & (level > 0)
    view_of = _view_of(views)
    normal = {key: [] for key in views}
    for k, photo in enumerate(scene.photos_with_role("flash")):
        mine = samples.photo == k
        if photo.camera.model != "pinhole" or known.sum() < 2 or not mine.any():
            continue
        rho = samples.rho[mine].mean(axis=1)
        predicted = np.exp(np.interp(samples.theta_h[mine], centres[known], np.log(level[known])))
        gradient = np.asarray(samples.log_gradient[mine], dtype=np.float64)
        usable = np.all(np.isfinite(gradient), axis=1)
        residual = np.log(np.where(rho > 0, rho, np.nan)) - np.log(predicted)
        keep = (usable & ~samples.censored[mine] & np.isfinite(residual)
                & (np.abs(residual) < MAX_RESIDUAL))
        normal[view_of[photo.index]].append((gradient[keep], residual[keep]))
    shifts = {}
    for key in views:
        if views[key][0].camera.model != "pinhole":
            shifts[key] = (None, "orthographic: not refined")
            continue
        parts = normal[key]
        g = np.concatenate([p[0] for p in parts]) if parts else np.zeros((0, 2))
        r = np.concatenate([p[1] for p in parts]) if parts else np.zeros(0)
        if len(r) < MIN_SAMPLES:
            shifts[key] = (None, f"{len(r)} samples with a gradient: too few to fix a shift")
            continue
        normal_matrix = g.T @ g
        if np.linalg.eigvalsh(normal_matrix)[0] <= 0:
            shifts[key] = (None, "the photo does not vary across the view: no shift to fix")
            continue
        d = -np.linalg.solve(normal_matrix, g.T @ r)
        # least squares' covariance: residual variance x (G^T G)^-1
        variance = np.mean((r + g @ d) ** 2) * np.linalg.eigvalsh(np.linalg.inv(normal_matrix))[-1]
        if np.sqrt(variance) > MAX_SHIFT_ERROR_PX:
            shifts[key] = (None, f"the view's samples fix a shift only to +-{np.sqrt(variance):.2f}"
                                 " px: camera kept")
            continue
        shifts[key] = (d, None)
    return shifts


def log_gradient(image, pixels):
    """(N, 2) float32 central-difference gradient of ln(mean RGB radiance) per px along (u, v) at
    flat pixel indices of a loaded photo (capture.iter_flash_images), NaN where a neighbour is
    outside the frame, unusable or not positive."""
    height, width = image.usable.shape
    rows, cols = np.divmod(np.asarray(pixels, np.int64), width)
    inside = (rows > 0) & (rows < height - 1) & (cols > 0) & (cols < width - 1)
    rows, cols = np.where(inside, rows, 1), np.where(inside, cols, 1)
    flat = rows * width + cols
    luminance = image.radiance.reshape(-1, 3)
    usable = image.usable.ravel()
    values, ok = [], inside.copy()
    for step in (1, -1, width, -width):
        neighbour = flat + step
        value = luminance[neighbour].mean(axis=1).astype(np.float64)
        ok &= usable[neighbour] & (value > 0)
        values.append(np.log(np.where(value > 0, value, 1.0)))
    gradient = np.stack([values[0] - values[1], values[2] - values[3]], axis=1) / 2
    return np.where(ok[:, None], gradient, np.nan).astype(np.float32)
