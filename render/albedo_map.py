"""A BRDF with a per-point diffuse albedo (texture) on top: rho = T_k + A(x)/pi - f_k.

T_k is the BRDF of the point's material k (a model, or a MaterialMap's k-th), f_k (3,) 1/sr its
diffuse floor and A(x) (3,) the point's diffuse albedo (slice_extract.albedo). The renderer is
linear in the BRDF, so the textured render is the BRDF's render plus the render of a constant
BRDF of 1/sr (Lambert with albedo pi) times delta(x) = A(x)/pi - f_k per point: one extra render
whatever the number of materials and of maps (render_albedo_maps renders all the maps' bases
together), and the BRDF's own importance sampling is kept.
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

    def floor_index(self, surface, camera):
        """(N,) row of `floors` of each point of a capture.Surface seen from `camera` (its
        material's, through the MaterialMap base's labels), in the smallest integer type, or
        None when the base is one model (floors[0] everywhere). Checks first that the albedo
        can be looked up from `camera`."""
        self._albedo_at(surface, camera, slice(0, 0))
        if not isinstance(self.base, MaterialMap):
            return None
        labels = self.base.point_labels(surface, camera)
        index = np.clip(labels, 1, len(self.floors)) - 1
        return index.astype(np.min_scalar_type(len(self.floors) - 1))

    def point_delta(self, surface, camera, rows=slice(None), floor_index=None):
        """(n, 3) delta = A/pi - f_k at the points `rows` (a slice or an index array) of a
        capture.Surface seen from `camera`; floor_index: its floor_index(surface, camera), made
        once for many calls (else made here, for the whole surface)."""
        albedo = self._albedo_at(surface, camera, rows)
        if floor_index is None:
            floor_index = self.floor_index(surface, camera)
        floors = self.floors[0] if floor_index is None else self.floors[floor_index[rows]]
        known = np.any(albedo > 0, axis=1)
        return np.where(known[:, None], albedo / np.pi - floors, 0.0)

    def _albedo_at(self, surface, camera, rows):
        """(n, 3) float64 albedo of the points `rows`: through the map for its own camera, else
        through the face albedos."""
        if camera_key(camera) == camera_key(self.camera):
            return self.albedo[surface.rows[rows], surface.cols[rows]].astype(float)
        if self.faces is not None and surface.face is not None:
            return self.faces[surface.face[rows]]
        raise InputError(self.where, "a reference photo from another camera needs an albedo "
                                     "per face (ALBEDO.faces.npy, written for mesh geometry)")


DELTA_CHUNK = 1 << 14  # points whose delta is checked at once: ~2 MB of temporaries, any N


def render_albedo_maps(maps, surface, camera, render, emit):
    """emit(rows, i, values (n, 3) float64) of the points `rows` (a slice or an index array)
    under each DiffuseAlbedoMap maps[i], as they are made. render(items, sink) renders the
    surface with a list of models or MaterialMaps (render_surface: sink(rows, j, values) per
    chunk of items[j]).

    The constant 1/sr BRDF is rendered first, into one (N, 3) float64 array, when some map's
    delta is not 0 somewhere; then every map's base in one render, so that what does not depend
    on the BRDF (the envmap's samples, radiance and shadow rays) is computed once for all. Each
    chunk of a base's values becomes max(values + unit * delta, 0) as it comes, its delta made
    for its rows only: no (N, 3) array per map is held, only the unit render and, per map with
    a MaterialMap base, one small integer per point (its floor). A map whose delta is 0
    everywhere emits its base's values unchanged."""
    n = len(surface.normals)
    floor_index = [albedo_map.floor_index(surface, camera) for albedo_map in maps]
    textured = [any(np.any(albedo_map.point_delta(surface, camera, slice(s, s + DELTA_CHUNK),
                                                  index))
                    for s in range(0, n, DELTA_CHUNK))
                for albedo_map, index in zip(maps, floor_index)]
    unit = None
    if any(textured):
        unit = np.zeros((n, 3))

        def keep(rows, _, values):
            unit[rows] = values
        render([Lambert(np.pi)], keep)                     # rho = 1 / sr

    def textured_sink(rows, i, values):
        if textured[i]:
            delta = maps[i].point_delta(surface, camera, rows, floor_index[i])
            values = np.maximum(values + unit[rows] * delta, 0.0)
        emit(rows, i, values)
    render([albedo_map.base for albedo_map in maps], textured_sink)
