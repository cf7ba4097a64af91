"""Rusinkiewicz half/difference angles for isotropic BRDFs, vectorised: the one set of conversions.

Frames:
- the *local* (shading) frame has the surface normal along +z;
- the *half-vector* frame is the local frame rotated by -phi_h about z, then by -theta_h about y,
  so that h lies along +z (Rusinkiewicz 1998). The difference vector d is omega_i in that frame:
  d = (sin theta_d cos phi_d, sin theta_d sin phi_d, cos theta_d).

In the half-vector frame, its x axis is t = cos(theta_h) p - sin(theta_h) n and its y axis is
b = n x p, where p is the unit tangential part of h. At theta_h = 0, p is undefined; any tangent
gives the same BRDF value for an isotropic material, so a fixed tangent is used (no NaN).

All angles are radians; direction arrays are (..., 3) unit vectors pointing away from the surface.

phi_d at theta_d = 0 (wi = wo = h) is undefined: the BRDF of a continuous material does not depend
on it there. half_diff_from_world returns atan2 of two zeros, folded into [0, pi): 0 (or -0.0).
The render hot path (brdf.angles.merl_flat_index_local) may land in phi_d bin 0 or 179 there,
depending on signed zeros; only that convention differs (tests/test_render_brdf.py).

Hot paths keep specialised copies beside the general function, each with a test that they agree:
half_diff_thetas (float32-ready, no phi_d; slice extraction) here, and
brdf.angles.merl_flat_index_local (angles straight to MERL bins; rendering).
"""

import numpy as np

from flashbrdf.brdf.frame import Frame

_TINY = 1e-12


def _dot(a, b):
    return np.einsum("...i,...i->...", a, b)


def _normalise(v):
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), _TINY)


def half_diff_from_world(wi, wo, normal, fold=True):
    """(theta_h, theta_d, phi_d) of direction pairs about a normal, in any common frame.

    wi, wo, normal: (..., 3) unit vectors (broadcastable). Returns three (...) arrays in radians.
    phi_d is in [0, pi) when `fold` (reciprocity: phi_d and phi_d + pi swap wi and wo, which an
    isotropic, reciprocal BRDF cannot tell apart), else in (-pi, pi].
    """
    wi, wo, n = np.broadcast_arrays(*(np.asarray(v, dtype=np.float64) for v in (wi, wo, normal)))
    h = _normalise(wi + wo)
    cos_h = _dot(h, n)
    tangential = h - cos_h[..., None] * n
    sin_h = np.linalg.norm(tangential, axis=-1)
    p = np.where((sin_h > _TINY)[..., None], tangential / np.maximum(sin_h, _TINY)[..., None],
                 Frame.from_normal(n).tangent)
    theta_h = np.arctan2(sin_h, cos_h)
    t = np.cos(theta_h)[..., None] * p - np.sin(theta_h)[..., None] * n
    b = np.cross(n, p)
    # atan2 forms keep full precision near 0 where arccos would lose half the digits.
    theta_d = np.arctan2(np.linalg.norm(np.cross(wi, h), axis=-1), _dot(wi, h))
    phi_d = np.arctan2(_dot(wi, b), _dot(wi, t))
    if fold:
        phi_d = np.mod(phi_d, np.pi)
    return theta_h, theta_d, phi_d


def half_diff_from_local(wi, wo, fold=True):
    """(theta_h, theta_d, phi_d) of local-frame (normal = +z) directions; see half_diff_from_world."""
    return half_diff_from_world(wi, wo, np.array([0.0, 0.0, 1.0]), fold=fold)


def phi_h_from_local(wi, wo):
    """Azimuth of the half vector in the local frame, radians (...); 0 where theta_h = 0."""
    h = np.asarray(wi, dtype=np.float64) + np.asarray(wo, dtype=np.float64)
    return np.arctan2(h[..., 1], h[..., 0])


def local_from_half_diff(theta_h, theta_d, phi_d, phi_h=0.0):
    """Local-frame (wi, wo), each (..., 3), from Rusinkiewicz angles (radians, broadcastable)."""
    theta_h, theta_d, phi_d, phi_h = np.broadcast_arrays(
        *(np.asarray(a, dtype=np.float64) for a in (theta_h, theta_d, phi_d, phi_h)))
    d = np.stack([np.sin(theta_d) * np.cos(phi_d), np.sin(theta_d) * np.sin(phi_d),
                  np.cos(theta_d)], axis=-1)
    # wi = Rz(phi_h) Ry(theta_h) d
    ct, st = np.cos(theta_h), np.sin(theta_h)
    x = d[..., 0] * ct + d[..., 2] * st
    z = -d[..., 0] * st + d[..., 2] * ct
    cp, sp = np.cos(phi_h), np.sin(phi_h)
    wi = np.stack([x * cp - d[..., 1] * sp, x * sp + d[..., 1] * cp, z], axis=-1)
    h = np.stack([st * cp, st * sp, ct], axis=-1)
    wo = 2 * _dot(wi, h)[..., None] * h - wi
    return wi, wo


def half_diff_thetas(wi, wo, normal):
    """theta_h, theta_d (N,) radians of unit direction pairs (N, 3) about unit normals (N, 3).

    Hot-path copy of half_diff_from_world for slice extraction (phi_d is not needed for the
    slice; float32 inputs stay float32), in the half-angle form 2 atan2(|a - b|, |a + b|), which
    keeps full precision near 0 and near pi (tests/test_extract_cli.py checks they agree).
    """
    h = wi + wo
    h /= _norm(h)[:, None].astype(h.dtype)
    theta_h = 2 * np.arctan2(_norm(h - normal), _norm(h + normal))
    theta_d = 2 * np.arctan2(_norm(wi - h), _norm(wi + h))
    return theta_h, theta_d


def _norm(v):
    return np.sqrt(np.einsum("ij,ij->i", v, v))


def cos_in_out(theta_h, theta_d, phi_d):
    """cos θi, cos θo of the light/view pair at half/difference angles (any broadcastable shapes).

    With h = Ry(θh)·z and the difference vector d in the half-vector frame, ωi = Ry(θh)·d and
    ωo = 2(ωi·h)h − ωi, so cos θi = cos θd cos θh − sin θd cos φd sin θh and cos θo the same with +
    (the z components of local_from_half_diff, which is independent of φh).
    """
    a = np.cos(theta_d) * np.cos(theta_h)
    b = np.sin(theta_d) * np.cos(phi_d) * np.sin(theta_h)
    return a - b, a + b
