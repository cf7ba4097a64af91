"""A BRDF with a per-point diffuse albedo (texture) on top: rho = T_k + A(x)/pi - f_k.

T_k is the BRDF of the point's material k (a model, or a MaterialMap's k-th), f_k (3,) 1/sr its
diffuse floor and A(x) (3,) the point's diffuse albedo (slice_extract.albedo). The renderer is
linear in the BRDF, so the textured render is the BRDF's render plus the render of a constant
BRDF of 1/sr (Lambert with albedo pi) times delta(x) = A(x)/pi - f_k per point: one extra render
whatever the number of materials, and the BRDF's own importance sampling is kept.
"""

import numpy as np

from flashbrdf.files.errors import InputError
from flashbrdf.brdf.models import Lambert
from flashbrdf.capture.scene import camera_key
from flashbrdf.render.material_map import MaterialMap


def table_floor(table):
    """A MERL table's diffuse floor (3,) 1/sr: per channel, the minimum over theta_h of its
    theta_d = 0 row (mean over phi_d), over bins with data."""
    table = np.asarray(table, float)
    row = table[:, 0]                       # (90, 3) for 2D, (90, 180, 3) for 3D
    if row.ndim == 2:
        row = row[:, None, :]
    with np.errstate(invalid="ignore"):
        valid = np.isfinite(row) & (row >= 0)
        mean = np.where(valid, row, 0.0).sum(axis=1) / np.maximum(valid.sum(axis=1), 1)
    has = valid.any(axis=1).all(axis=1)
    return mean[has].min(axis=0) if has.any() else np.zeros(3)


class DiffuseAlbedoMap:
    """A BRDF `base` (a brdf.models model or a MaterialMap) with a diffuse albedo map.

    albedo (H, W, 3) in `camera`'s pixel grid (the flash photo's); floors (K, 3) 1/sr, f_k of
    material k; faces (F, 3) or None: an albedo per mesh face, for views from other cameras.
    A point whose albedo is 0 in all channels (off the map) keeps the base BRDF.
    """

    def __init__(self, base, albedo, floors, camera, faces=None, where="--albedo"):
        self.base, self.albedo, self.camera = base, np.asarray(albedo, np.float32), camera
        self.floors = np.atleast_2d(np.asarray(floors, float))
        self.faces = None if faces is None else np.asarray(faces, float)
        self.where = where

    def point_delta(self, surface, camera):
        """(N, 3) delta = A/pi - f_k at the points of a capture.Surface seen from `camera`."""
        if camera_key(camera) == camera_key(self.camera):
            albedo = self.albedo[surface.rows, surface.cols].astype(float)
        elif self.faces is not None and surface.face is not None:
            albedo = self.faces[surface.face]
        else:
            raise InputError(self.where, "a reference photo from another camera needs an albedo "
                                         "per face (ALBEDO.faces.npy, written for mesh geometry)")
        labels = (self.base.point_labels(surface, camera) if isinstance(self.base, MaterialMap)
                  else np.ones(len(albedo), np.int64))
        floors = self.floors[np.clip(labels, 1, len(self.floors)) - 1]
        known = np.any(albedo > 0, axis=1)
        return np.where(known[:, None], albedo / np.pi - floors, 0.0)


def render_albedo_maps(maps, surface, camera, render_with, emit):
    """emit(i, values (N, 3) float64) of the points under each DiffuseAlbedoMap maps[i], one map
    at a time: render_with(models) -> [(N, 3) per model] renders the surface with a list of
    models (or MaterialMaps). The constant 1/sr BRDF's render is made once, for the first map
    whose delta is not 0, and kept for the others. The maps' bases are not rendered together:
    each map holds its base's values, its delta and their sum (N × 3 float64 each, 0.6 GB at
    24 MP), and several maps' at once would hold that many times more."""
    unit = None
    for i, albedo_map in enumerate(maps):
        values = render_with([albedo_map.base])[0]
        delta = albedo_map.point_delta(surface, camera)
        if np.any(delta):
            if unit is None:
                unit = render_with([Lambert(np.pi)])[0]   # rho = 1 / sr
            values = np.maximum(values + unit * delta, 0.0)
        emit(i, values)
        del values, delta
