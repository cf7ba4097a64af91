"""Rusinkiewicz half/difference angles for isotropic BRDFs, vectorised.

Frames:
- the *local* (shading) frame has the surface normal along +z;
- the *half-vector* frame is the local frame rotated by -phi_h about z, then by -theta_h about y,
  so that h lies along +z (Rusinkiewicz 1998). The difference vector d is omega_i in that frame:
  d = (sin theta_d cos phi_d, sin theta_d sin phi_d, cos theta_d).

In the half-vector frame, its x axis is t = cos(theta_h) p - sin(theta_h) n and its y axis is
b = n x p, where p is the unit tangential part of h. At theta_h = 0, p is undefined; any tangent
gives the same BRDF value for an isotropic material, so a fixed tangent is used (no NaN).

All angles are radians; direction arrays are (..., 3) unit vectors pointing away from the surface.
"""

import numpy as np

from brdf.merl import N_PHI_D, N_THETA_D, N_THETA_H, theta_h_bin_coordinate

_TINY = 1e-12


def _dot(a, b):
    return np.einsum("...i,...i->...", a, b)


def _normalise(v):
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), _TINY)


def _any_tangent(n):
    """A unit vector perpendicular to each n, (..., 3); (1, 0, 0) for n = +z (Duff et al. 2017)."""
    sign = np.where(n[..., 2] >= 0, 1.0, -1.0)
    a = -1.0 / (sign + n[..., 2])
    b = n[..., 0] * n[..., 1] * a
    return np.stack([1 + sign * n[..., 0] ** 2 * a, sign * b, -sign * n[..., 0]], axis=-1)


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
                 _any_tangent(n))
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


def merl_bin_index(theta_h, theta_d, phi_d):
    """MERL's own bin indices (i, j, k) as int arrays, clamped as in its BRDFRead.cpp.

    theta_h uses square-root spacing, theta_d and phi_d 1-degree bins; phi_d is folded into [0, pi).
    """
    theta_h = np.asarray(theta_h, dtype=np.float64)
    i = theta_h_bin_coordinate(np.clip(theta_h, 0, None))
    j = np.asarray(theta_d, dtype=np.float64) / (np.pi / 2) * N_THETA_D
    k = np.mod(np.asarray(phi_d, dtype=np.float64), np.pi) / np.pi * N_PHI_D
    return (np.clip(i, 0, N_THETA_H - 1).astype(np.intp),
            np.clip(j, 0, N_THETA_D - 1).astype(np.intp),
            np.clip(k, 0, N_PHI_D - 1).astype(np.intp))


def merl_bin_coordinates(theta_h, theta_d, phi_d):
    """Continuous bin coordinates (u_h, u_d, u_p) where integer values are bin centres.

    u_h and u_d are clamped to [0, 89]; u_p is in [-0.5, 179.5) and periodic with period 180.
    """
    u_h = theta_h_bin_coordinate(np.clip(np.asarray(theta_h, dtype=np.float64), 0, None)) - 0.5
    u_d = np.degrees(np.asarray(theta_d, dtype=np.float64)) - 0.5
    u_p = np.mod(np.degrees(np.asarray(phi_d, dtype=np.float64)), 180.0) - 0.5
    return (np.clip(u_h, 0, N_THETA_H - 1), np.clip(u_d, 0, N_THETA_D - 1), u_p)
