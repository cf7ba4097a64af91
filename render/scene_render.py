"""Render a capture folder's reference lightings, and a lone sphere for Table 2.

Scenes come from capture (its public API only). For each camera the primary rays are cast once
(capture.surface_from_mesh, or capture.surface_from_normal_map without ray casting) and reused for
every lighting seen from that camera. Shadow rays go through Embree only for non-convex meshes.
"""

import numpy as np

from flashbrdf.files.errors import InputError
from flashbrdf.render.albedo_map import DiffuseAlbedoMap, render_albedo_maps
from flashbrdf.capture.scene import camera_key
from flashbrdf.render.material_map import MaterialMap
from flashbrdf.brdf.models import TabulatedBRDF
from flashbrdf.render.envmap import EnvMap
from flashbrdf.render.integrator import render_directional_light, render_envmap, render_point_light


class SceneGeometry:
    """A scene's geometry with cached per-camera primary hits (capture.Surface).

    The cache holds at most CACHED_HITS hits (the oldest cameras go first): a run renders every
    reference once (for all methods) and its previews from the flash camera, so hits are
    reused, but 30 views of 24 MP would fill the memory.
    """

    CACHED_HITS = 40_000_000

    def __init__(self, scene, intersector=None):
        """intersector: the scene mesh's capture.MeshIntersector when the caller has built one
        (extraction has: loading a 2.9 M-face mesh and its BVH again cost 14 s), else built."""
        from flashbrdf import capture  # lazy: capture costs 0.2-0.8 s on every import of render
        self.scene = scene
        self._surfaces = {}
        if scene.geometry.mesh is not None:
            self.intersector = intersector or capture.scene_intersector(scene)
            self.convex = capture.is_convex(self.intersector)
        else:
            self.intersector, self.convex = None, True

    def surface(self, camera):
        """capture.Surface of the pixels that see the object, cast once per camera."""
        from flashbrdf import capture
        key = camera_key(camera)
        if key not in self._surfaces:
            if self.intersector is not None:
                surface = capture.surface_from_mesh(self.intersector, camera)
            else:
                surface = capture.surface_from_normal_map(self.scene.geometry, camera)
            while self._surfaces and (sum(len(s.rows) for s in self._surfaces.values())
                                      + len(surface.rows) > self.CACHED_HITS):
                del self._surfaces[next(iter(self._surfaces))]  # the oldest camera's
            self._surfaces[key] = surface
        return self._surfaces[key]

    def sees_object(self, camera):
        """Whether some pixel of `camera` sees the object, without filling the cache: a cached
        camera answers at once, else up to 4096 of the pixels whose ray can reach a face are
        traced (a full trace only when none of those hits). Checking every camera by a full,
        cached trace re-traced each one once the cameras outgrew the cache."""
        from flashbrdf import capture
        key = camera_key(camera)
        if key in self._surfaces:
            return len(self._surfaces[key].rows) > 0
        if self.intersector is None:
            return len(self.surface(camera).rows) > 0
        if len(capture.surface_sample(self.intersector, camera, 4096).rows):
            return True
        return len(self.surface(camera).rows) > 0

    def occluder(self):
        """The integrator's shadow-ray callback, or None (convex mesh or normal map)."""
        if self.convex or self.intersector is None:
            return None
        from flashbrdf import capture
        mi = self.intersector
        return lambda points, dirs, max_dist: capture.occluded(mi, points, dirs, max_dist)


def _part(surface, keep):
    """The capture.Surface restricted to keep (N,) bool."""
    from flashbrdf.capture import Surface
    pick = [None if v is None else v[keep] for v in (surface.rows, surface.cols, surface.points,
                                                     surface.normals, surface.view_dirs,
                                                     surface.face)]
    return Surface(*pick)


def render_surface(surface, camera, light, brdfs, emit, spp=64, seed=0, occluded=None,
                   envmaps=None, progress=None, where="light"):
    """Pixel-model values (unscaled) of a capture.Surface under one capture.Light, for each of
    `brdfs` at once: emit(rows, m, values) takes values (n, 3) float64 of brdfs[m] at the
    points `rows` (a slice or an index array) as they are made. Each brdf's values equal its
    render alone; what does not depend on the BRDF is computed once (render.integrator).

    brdfs: a list of brdf.models models, MaterialMaps (each material rendered with its own)
    or render.albedo_map.DiffuseAlbedoMaps (either, with a per-point diffuse albedo)."""
    def render(items, sink, points=surface):
        render_surface(points, camera, light, items, sink, spp, seed, occluded, envmaps,
                       progress, where)
    groups = {}  # models, material maps (by labels), albedo maps: each kind rendered together
    for m, brdf in enumerate(brdfs):
        kind = (DiffuseAlbedoMap if isinstance(brdf, DiffuseAlbedoMap)
                else MaterialMap if isinstance(brdf, MaterialMap) else None)
        groups.setdefault(kind, []).append(m)
    for kind, members in groups.items():
        items = [brdfs[m] for m in members]

        def sink(rows, i, value, members=members):   # a group's i-th item is brdfs[members[i]]
            emit(rows, members[i], value)
        if kind is DiffuseAlbedoMap:
            render_albedo_maps(items, surface, camera, render, sink)
        elif kind is MaterialMap:
            _render_materials(surface, camera, items, render, sink)
        else:
            _render_models(surface, camera, light, items, sink, spp, seed, occluded, envmaps,
                           progress, where)


def _render_materials(surface, camera, maps, render, emit):
    """MaterialMaps, each point rendered with its material's BRDF; maps with the same labels
    are rendered together, material by material. render(items, sink, part) renders a part of
    the surface (see render_surface)."""
    labelled = []  # (labels, [map index]) per distinct labelling of the points
    for i, brdf in enumerate(maps):
        labels = brdf.point_labels(surface, camera)
        same = next((group for group in labelled if np.array_equal(group[0], labels)), None)
        if same is None:
            labelled.append((labels, [i]))
        else:
            same[1].append(i)
    for labels, members in labelled:
        for k in range(1, max(len(maps[i].brdfs) for i in members) + 1):
            mine = labels == k
            which = [i for i in members if k <= len(maps[i].brdfs)]
            if not mine.any() or not which:
                continue
            where_mine = np.nonzero(mine)[0]
            render([maps[i].brdfs[k - 1] for i in which],
                   lambda rows, j, value, which=which, where_mine=where_mine:
                   emit(where_mine[rows], which[j], value), _part(surface, mine))


def _render_models(surface, camera, light, models, emit, spp, seed, occluded, envmaps, progress,
                   where):
    """brdf.models models under one light (see render_surface)."""
    points = surface.points
    if light.type == "point":
        if points is None:
            raise InputError(where, "a point light needs mesh geometry (a normal map has no depth)")
        position = camera.to_world(light.position)
        return _in_chunks(lambda p, n, v: render_point_light(
            p, n, v, models, position, light.intensity_rgb, occluded), points, surface, emit)
    if points is None:
        points = np.zeros_like(surface.normals)
    if light.type == "directional":
        return _in_chunks(lambda p, n, v: render_directional_light(
            p, n, v, models, light.direction, light.irradiance_rgb, occluded), points, surface,
            emit)
    if light.type == "envmap":
        key = (str(light.file), np.asarray(light.world_from_envmap).tobytes(), light.scale)
        envmaps = {} if envmaps is None else envmaps
        if key not in envmaps:
            envmaps[key] = EnvMap.from_file(light.file, light.world_from_envmap, light.scale)
        return render_envmap(points, surface.normals, surface.view_dirs, models, envmaps[key],
                             spp=spp, seed=seed, occluded=occluded, progress=progress, emit=emit)
    raise InputError(where, f"unknown light type {light.type!r}")


DIRECT_CHUNK = 1 << 20  # points shaded at once under a point or directional light


def _in_chunks(shade, points, surface, emit):
    """emit(rows, m, values) of shade(points, normals, view) -> [values per model] over the
    surface, a million points at a time: a 24 MP view at once made a dozen (N, 3) float64
    temporaries, 0.6 GB each."""
    n = len(surface.normals)
    for s in range(0, n, DIRECT_CHUNK):
        part = slice(s, s + DIRECT_CHUNK)
        for m, value in enumerate(shade(points[part], surface.normals[part],
                                        surface.view_dirs[part])):
            emit(part, m, value)


def render_scene(scene, brdf, spp=64, seed=0, photos=None, progress=True, geometry=None):
    """Render every `reference` photo's lighting (or the given photos) from its camera.

    scene: capture.Scene; brdf: a brdf.models model, MaterialMap or DiffuseAlbedoMap, or a list
    of them. Yields (photo, image, mask) per photo: image (H, W, 3) float32 in the photo's own
    pixel units (the pixel model times the photo's `scale`), 0 where the pixel misses the
    geometry, or a list of images, one per BRDF of the list (each equal to its render alone,
    the BRDF-independent work done once); mask (H, W) bool of the pixels that see it.
    geometry: a SceneGeometry of this scene to reuse (its primary hits are cached per camera).
    Every light is checked (and every envmap loaded), and every camera must see the object,
    before the first render.
    """
    several = isinstance(brdf, (list, tuple))
    brdfs = list(brdf) if several else [brdf]
    photos = scene.photos_with_role("reference") if photos is None else photos
    envmaps = {}
    for photo in photos:                       # check every light before any rendering
        light = photo.light
        if light is None:
            raise InputError(photo.where, "a reference photo needs a light to render")
        if light.type == "point" and scene.geometry.mesh is None:
            raise InputError(f"{photo.where}.light",
                             "a point light needs mesh geometry (a normal map has no depth)")
        if light.type == "envmap":
            key = (str(light.file), np.asarray(light.world_from_envmap).tobytes(), light.scale)
            if key not in envmaps:
                envmaps[key] = EnvMap.from_file(light.file, light.world_from_envmap, light.scale)
    # A SceneGeometry passed in keeps its primary hits across calls (run's renders, previews).
    geometry = SceneGeometry(scene) if geometry is None else geometry
    for photo in photos:                       # and every camera: a view of nothing is no render
        if not geometry.sees_object(photo.camera):
            field = (f"{scene.json_path}: camera" if photo.camera is scene.camera
                     else f"{photo.where}.camera")
            raise InputError(field, f"no pixel of {photo.stem}'s view sees the object (check "
                                    "fx, fy, cx, cy, world_from_camera and units)")
    occluded = geometry.occluder()
    for photo in photos:
        camera = photo.camera
        surface = geometry.surface(camera)
        # written chunk by chunk into float32 pixels: no (N, 3) float64 array per BRDF is held
        images = [np.zeros(camera.shape + (3,), dtype=np.float32) for _ in brdfs]

        def to_pixels(rows, m, values, surface=surface, scale=photo.scale):
            images[m][surface.rows[rows], surface.cols[rows]] = values * scale
        render_surface(surface, camera, photo.light, brdfs, to_pixels, spp, seed, occluded,
                       envmaps, progress=f"render {photo.stem}" if progress else None,
                       where=f"{photo.where}.light")
        mask = np.zeros(camera.shape, dtype=bool)
        mask[surface.rows, surface.cols] = True
        yield photo, (images if several else images[0]), mask
        del images


def sphere_view(size):
    """An orthographic view of the unit sphere at the origin, camera looking along world -z
    (image right = +x, up = +y). Returns mask (size, size) bool, normals (N, 3), view (N, 3)."""
    c = (np.arange(size) - (size - 1) / 2) / (size / 2)   # pixel centres, sphere fills the frame
    y, x = -c[:, None] * np.ones(size)[None], np.ones(size)[:, None] * c[None]
    r2 = x * x + y * y
    mask = r2 < 1.0
    normals = np.stack([x, y, np.sqrt(np.maximum(0.0, 1.0 - r2))], axis=-1)[mask]
    view = np.broadcast_to([0.0, 0.0, 1.0], normals.shape)
    return mask, normals, view


def render_sphere(table, envmap_path, size=128, spp=64, seed=0, interpolate=False,
                  world_from_envmap=None, scale=1.0, threads=None, progress=None):
    """A unit sphere with a tabulated BRDF under an environment map (Table 2's renders).

    table: (90, 90, 180, 3) or (90, 90, 3) in 1/sr (NaN/negative = no data) or a
    brdf.models BRDF; envmap_path: lat-long map (or an EnvMap). Orthographic camera
    looking along -z (see sphere_view); no shadowing (a sphere is convex).
    Returns (size, size, 3) float32, 0 off the sphere.
    """
    brdf = table if hasattr(table, "evaluate_local") else TabulatedBRDF(table, interpolate)
    envmap = envmap_path if isinstance(envmap_path, EnvMap) else \
        EnvMap.from_file(envmap_path, world_from_envmap, scale)
    mask, normals, view = sphere_view(size)
    values = render_envmap(normals, normals, view, brdf, envmap, spp=spp, seed=seed,
                           threads=threads, progress=progress)
    image = np.zeros((size, size, 3), dtype=np.float32)
    image[mask] = values
    return image
