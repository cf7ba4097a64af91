"""Per-pixel BRDF samples from one flash photo over a patch of visible surface.

Pixel model (contract), after ambient removal and division by the photo's scale:
  point light:        pixel = V rho I cos(theta_i) / r^2  ->  rho = pixel r^2 / (I cos theta_i)
  directional light:  pixel = V rho E cos(theta_i)        ->  rho = pixel / (E cos theta_i)
A point light's position is in the CAMERA frame (a flash offset from the lens); a directional
light's direction is a unit WORLD vector toward the light.

Rejections, in this order (each pixel counted once, under the first reason that applies):
  silhouette  next to the object's outline in the image (slice_extract.extract.silhouette_mask);
  backfacing  cos(theta_o) <= 0: the shading normal faces away from the camera;
  grazing     cos(theta_o) < min_cos or cos(theta_i) < min_cos (light behind or at grazing);
  theta_d     theta_d above max_theta_d (the light is too far from the camera for a theta_d ~ 0
              sample);
  shadowed    the segment to the light hits the mesh (not tested for normal-map geometry).
Once a capture's pooled samples are subsampled (SampleStore), a sample its full bin could never
keep is dropped before the shadow test and counted as not_needed, not as shadowed.
"""

from dataclasses import dataclass

import numpy as np

from flashbrdf.files.errors import InputError
from flashbrdf.brdf.rusinkiewicz import half_diff_thetas
from flashbrdf.capture import occluded

REASONS = ("silhouette", "backfacing", "grazing", "theta_d", "shadowed")


@dataclass(frozen=True, eq=False)
class LightSetup:
    """A flash photo's light in the WORLD frame.

    kind "point": position (3,) world, power = intensity_rgb (3,);
    kind "directional": direction (3,) unit toward the light, power = irradiance_rgb (3,).
    at_viewpoint: the light sits exactly where the camera looks from (co-located pinhole flash,
    or a directional light along an orthographic view): shadow rays are then the primary rays
    reversed and can be skipped.
    """
    kind: str
    power: np.ndarray
    position: np.ndarray = None
    direction: np.ndarray = None
    at_viewpoint: bool = False


def light_setup(photo):
    """LightSetup of a flash Photo (see capture.Photo); InputError for unusable light fields."""
    light, camera = photo.light, photo.camera
    if light.type == "point":
        power = light.intensity_rgb
        field = "light.intensity_rgb"
    else:
        power = light.irradiance_rgb
        field = "light.irradiance_rgb"
    if np.any(power <= 0):
        raise InputError(f"{photo.where}.{field}",
                         f"must be positive in every channel for a flash photo, got "
                         f"{power.tolist()}")
    if light.type == "point":
        position = camera.to_world(light.position)
        at_view = camera.model == "pinhole" and not np.any(light.position)
        return LightSetup("point", power, position=position, at_viewpoint=at_view)
    view = -camera.forward
    at_view = camera.model == "orthographic" and bool(np.allclose(light.direction, view,
                                                                  atol=1e-12))
    return LightSetup("directional", power, direction=light.direction, at_viewpoint=at_view)


@dataclass(frozen=True, eq=False)
class PhotoSamples:
    """Samples of one photo over one surface patch.

    theta_h, theta_d (M,) radians; rho (M, 3) 1/sr; censored (M,) bool: clipped pixels that
    passed the geometric tests, their rho a lower bound (the clipped value; +inf if unknown);
    pixels (M,) int flat index row * width + col of each sample in the photo;
    rejected: counts per REASONS among usable pixels; n_usable: usable pixels on the patch.
    """
    theta_h: np.ndarray
    theta_d: np.ndarray
    rho: np.ndarray
    censored: np.ndarray
    rejected: dict
    n_usable: int
    pixels: np.ndarray = None  # (M,) flat pixel index (row * width + col) of each sample
    face: np.ndarray = None    # (M,) mesh face of each sample, or None (normal-map geometry)
    key: np.ndarray = None     # (M,) float32 subsampling keys from `sieve`, or None
    not_needed: int = 0        # samples the sieve dropped: their bin already holds enough


def photo_samples(radiance, usable, surface, light, options, intersector=None, clipped=None,
                  edge=None, sieve=None):
    """BRDF samples from one photo over one Surface patch (pixels that see the object).

    radiance (H, W, 3) pixel-model units; usable (H, W) bool; clipped (H, W) bool or None:
    too-bright pixels, kept as censored samples so that bins know where a highlight was lost;
    surface: capture.Surface; light: LightSetup; options: ExtractOptions; intersector:
    capture.MeshIntersector for shadow rays, or None to skip them (convex mesh, light at the
    viewpoint, normal-map geometry); edge (H, W) bool or None: silhouette pixels to reject;
    sieve: None, or sieve(theta_h (M,)) -> None or (wanted (M,) bool, keys (K,) float32 of the
    wanted) (SampleStore.sieve): samples a full bin could never keep are dropped before the shadow
    rays, the costliest step, and are counted in not_needed, not as rejected.
    Returns PhotoSamples.
    """
    # flat indices + np.take: several times faster than 2D fancy indexing on big images
    flat = surface.rows * usable.shape[1] + surface.cols
    valid = np.take(usable.ravel(), flat)
    cens = (np.zeros_like(valid) if clipped is None
            else np.take(clipped.ravel(), flat) & ~valid)
    keep = valid | cens
    n_usable = int(np.count_nonzero(valid))
    silhouette = 0
    if edge is not None:
        on_edge = np.take(edge.ravel(), flat)
        silhouette = int(np.count_nonzero(valid & on_edge))
        keep &= ~on_edge
    normals, wo, points, face = surface.normals, surface.view_dirs, surface.points, surface.face
    if not keep.all():  # (usually all are: the surface was traced for these pixels)
        flat, cens = np.compress(keep, flat), np.compress(keep, cens)
        face = None if face is None else np.compress(keep, face)
        normals, wo = np.compress(keep, normals, axis=0), np.compress(keep, wo, axis=0)
        points = None if points is None else np.compress(keep, points, axis=0)
    f32 = np.float32
    normals, wo = normals.astype(f32, copy=False), wo.astype(f32, copy=False)
    if light.kind == "point":
        if points is None:
            raise InputError("geometry", "a point light needs surface depth, which a normal map "
                             "lacks: use a mesh or a directional light")
        to_light = light.position - points  # float64: world points may sit far from the origin
        r2 = np.einsum("ij,ij->i", to_light, to_light)
        wi = (to_light / np.sqrt(r2)[:, None]).astype(f32)
    else:
        wi = np.broadcast_to(light.direction.astype(f32), normals.shape)
        r2 = None
    # direction math in float32: ~1e-7 rad, far below the narrowest theta_h bin (1.9e-4 rad)
    cos_o = np.einsum("ij,ij->i", normals, wo)
    cos_i = np.einsum("ij,ij->i", normals, wi)
    rejected = dict.fromkeys(REASONS, 0)
    rejected["silhouette"] = silhouette

    def drop(mask, reason):  # count only usable pixels; censored ones are not "used" anyway
        rejected[reason] = int(np.count_nonzero(mask & ~cens_now))

    cens_now = cens
    ok = cos_o > 0
    drop(~ok, "backfacing")
    graze = ok & ((cos_o < options.min_cos) | (cos_i < options.min_cos))
    drop(graze, "grazing")
    idx = np.flatnonzero(ok & ~graze)
    everything = len(idx) == len(ok)  # the common case: skip the gathers
    cens_now = cens if everything else np.take(cens, idx)
    theta_h, theta_d = (half_diff_thetas(wi, wo, normals) if everything else half_diff_thetas(
        *(np.take(v, idx, axis=0) for v in (wi, wo, normals))))
    near = theta_d <= np.radians(options.max_theta_d_deg)
    drop(~near, "theta_d")
    if not near.all():
        idx, theta_h, theta_d, cens_now = idx[near], theta_h[near], theta_d[near], cens_now[near]
    sieved = None if sieve is None else sieve(theta_h)
    key, not_needed = None, 0
    if sieved is not None:
        wanted, key = sieved
        not_needed = int(np.count_nonzero(~wanted & ~cens_now))  # usable ones, as REASONS
        idx, theta_h, theta_d = idx[wanted], theta_h[wanted], theta_d[wanted]
        cens_now = cens_now[wanted]
    if intersector is not None and len(idx):
        blocked = occluded(intersector, np.take(points, idx, axis=0), np.take(wi, idx, axis=0),
                           None if r2 is None else np.sqrt(np.take(r2, idx)))
        drop(blocked, "shadowed")
        idx, theta_h, theta_d = idx[~blocked], theta_h[~blocked], theta_d[~blocked]
        cens_now = cens_now[~blocked]
        key = None if key is None else key[~blocked]
    pixels = np.take(flat, idx)
    face = None if face is None else np.take(face, idx).astype(np.int32)
    pixel = np.take(radiance.reshape(-1, 3), pixels, axis=0).astype(np.float64)
    cos_i = np.take(cos_i, idx)
    factor = 1.0 / cos_i if r2 is None else np.take(r2, idx) / cos_i
    rho = pixel * (factor[:, None] / light.power)
    return PhotoSamples(theta_h, theta_d, rho, cens_now, rejected, n_usable, pixels, face, key,
                        not_needed)
