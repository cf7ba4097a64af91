"""An orthonormal shading frame, in the manner of pbrt's Frame and Mitsuba's Frame3f.

A Frame holds three (..., 3) unit vectors: tangent s, bitangent t and normal n (right-handed:
s x t = n). `to_local` gives a world vector's coordinates (v.s, v.t, v.n), so the normal is +z in
the local frame; `to_world` is its inverse. Everything is vectorised over leading axes
(trimesh-style plain arrays), float64.
"""

from dataclasses import dataclass

import numpy as np


def _dot(a, b):
    return np.einsum("...k,...k->...", a, b)


@dataclass(frozen=True, eq=False)
class Frame:
    """tangent, bitangent, normal: (..., 3) orthonormal, right-handed."""
    tangent: np.ndarray
    bitangent: np.ndarray
    normal: np.ndarray

    @classmethod
    def from_normal(cls, normal):
        """The frame about unit normals (..., 3), tangent chosen by Duff et al. 2017 (branchless,
        no singularity; tangent (1, 0, 0) for n = +z). Isotropic BRDFs do not depend on the choice.
        """
        n = np.asarray(normal, dtype=np.float64)
        nx, ny, nz = n[..., 0], n[..., 1], n[..., 2]
        sign = np.where(nz >= 0.0, 1.0, -1.0)
        a = -1.0 / (sign + nz)
        b = nx * ny * a
        tangent = np.stack([1.0 + sign * nx * nx * a, sign * b, -sign * nx], axis=-1)
        bitangent = np.stack([b, sign + ny * ny * a, -ny], axis=-1)
        return cls(tangent, bitangent, n)

    def to_local(self, v):
        """World vectors (..., 3) -> local coordinates (..., 3) (normal along +z)."""
        return np.stack([_dot(v, self.tangent), _dot(v, self.bitangent), _dot(v, self.normal)],
                        axis=-1)

    def to_world(self, v):
        """Local coordinates (..., 3) -> world vectors (..., 3)."""
        return v[..., 0:1] * self.tangent + v[..., 1:2] * self.bitangent + v[..., 2:3] * self.normal
