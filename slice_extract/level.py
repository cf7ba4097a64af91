"""The absolute level of a flash slice.

A flash photo gives rho = pixel r^2 / (I cos theta_i): with an uncalibrated flash (I unknown) and
a Structure-from-Motion model (r in unknown units) rho is known only up to one factor, the same in
every theta_h bin. scene.json's "level" (capture.Level) fixes it:
- target: a diffuse target of known reflectance (a grey card, a Spectralon patch), its own mesh
  in the scene's frame, seen in some flash photos. Its pixels give rho_target through the same
  pixel model; a Lambertian target's true rho is reflectance / pi at every angle, so every
  sample of the object is multiplied by factor = (reflectance / pi) / median(rho_target), per
  channel (a grey target also fixes the flash's colour). The factor also gives the flash's
  intensity in the scene's units (intensity_rgb / factor): a flash calibrated once.
- calibrated: intensity_rgb was measured before (in the scene's units): the level is absolute
  as given.
- neither: the slice is relative, and slice.json, BRDF.json and the report say so.
Target pixels are those where the target's ray hit lies in front of the object's; they are left
out of the object's samples, and the object shadows the target under an offset flash.
"""

import numpy as np

from flashbrdf import capture
from flashbrdf.files.errors import InputError
from flashbrdf.slice_extract.visibility import hit_depth, pixel_surfaces

MIN_TARGET_SAMPLES = 50
TARGET_MIN_COS = capture.scene.TARGET_MIN_COS


def relative_record(scene):
    """The level of a slice no target or calibration fixes."""
    powers = sorted({tuple(p.light.intensity_rgb.tolist()) if p.light.type == "point"
                     else tuple(p.light.irradiance_rgb.tolist())
                     for p in scene.photos_with_role("flash")})
    given = "; ".join(", ".join(f"{v:g}" for v in rgb) for rgb in powers)
    return {"absolute": False, "source": "relative",
            "note": "relative: rho is known up to one factor, the same in every bin: the flash's "
                    f"intensity is taken as given ({given}) in the scene's "
                    "units; fix it with a target of known reflectance or a calibrated flash "
                    "(scene.json \"level\", docs/capture.md)"}


def calibrated_record():
    return {"absolute": True, "source": "calibrated flash",
            "note": "absolute: the flash's intensity_rgb in scene.json was calibrated"}


# A target farther from (or nearer to) the camera than this many times the object is in other
# units or another frame (a card in cm or mm beside a model in metres: 38x and 375x on the
# docs/capture.md capture): its level would be off by the square of it, silently (ρ × 0.002 for
# cm), so it is refused. A card beside the object reads 0.5-2x.
TARGET_DEPTH_RATIO = 8.0


def trace_target(intersector, camera, object_depth, chunk, where):
    """capture.Surface batches of `camera`'s pixels whose ray meets the target before the object
    (object_depth (H, W), inf where the object is missed), and the (H, W) mask of those pixels.
    InputError naming `where` when the target's median depth is off the object's by more than
    TARGET_DEPTH_RATIO either way (where=None: no such check; an orthographic camera's depth is
    from an arbitrary plane, and a directional light's level does not depend on distance)."""
    mask = np.zeros(camera.shape, bool)
    surfaces, depths = [], []
    for surface in pixel_surfaces(camera, intersector, chunk):
        depth = hit_depth(camera, surface.points)
        depths.append(depth[::97])   # a sample is enough for a median
        front = depth < object_depth[surface.rows, surface.cols]
        keep = [None if v is None else v[front] for v in
                (surface.rows, surface.cols, surface.points, surface.normals, surface.view_dirs,
                 surface.face)]
        surfaces.append(capture.Surface(*keep))
        mask[keep[0], keep[1]] = True
    target_depth = np.concatenate(depths) if depths else np.zeros(0)
    seen = object_depth.ravel()[::97]       # a sample, as for the target
    seen = seen[np.isfinite(seen)]
    if where is not None and len(target_depth) and len(seen):
        ratio = float(np.median(target_depth) / np.median(seen))
        if not 1 / TARGET_DEPTH_RATIO <= ratio <= TARGET_DEPTH_RATIO:
            raise InputError(where, f"the target lies {ratio:.3g}x as far from the camera as the "
                                    "object: its mesh is not in the object's units and frame "
                                    "(a card in cm or mm beside a model in metres?), and its "
                                    f"level would be off by {ratio ** 2:.3g}x")
    return surfaces, mask


def target_level(rho, level, where):
    """(factor (3,), slice.json's "level") from the target's measured samples rho (M, 3) 1/sr
    (clipped ones left out) and the scene's capture.Level. InputError naming `where` with too
    few samples."""
    usable = rho[np.all(np.isfinite(rho), axis=1)]
    if len(usable) < MIN_TARGET_SAMPLES:
        raise InputError(where, f"the target is seen in {len(usable)} usable flash pixels (at "
                                f"least {MIN_TARGET_SAMPLES} are needed to fix the level): "
                                "check its mesh's frame, that it faces the camera within "
                                f"{np.degrees(np.arccos(TARGET_MIN_COS)):.0f}° in some photos, "
                                "that it is not clipped, and that its faces were cut out of the "
                                "object's mesh (a card left in it hides itself)")
    median = np.median(usable, axis=0)
    if not np.all(median > 0):
        raise InputError(where, "the target's pixels are black in some channel: its level "
                                "cannot be read")
    truth = np.asarray(level.reflectance, float) / np.pi
    factor = truth / median
    # robust spread of the target's samples: a card lit unevenly, or not Lambertian
    spread = np.median(np.abs(usable / median - 1), axis=0) * 1.4826
    return factor, {
        "absolute": True, "source": "target", "target": str(level.target_mesh),
        "reflectance": [float(v) for v in level.reflectance],
        "factor_rgb": [float(v) for v in factor], "samples": int(len(usable)),
        "target_spread_rgb": [float(v) for v in spread],
        "note": f"absolute: a target of reflectance {np.round(level.reflectance, 4).tolist()} "
                f"({level.target_mesh.name}, {len(usable)} pixels) multiplied rho by "
                f"{np.round(factor, 4).tolist()}"}
