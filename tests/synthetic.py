"""Synthetic capture folders with a known BRDF, for tests of every stage.

It renders photos through the contract's pixel model (direct light only, no interreflection):
  point light:       pixel = V rho(wi, wo) I cos(theta_i) / r^2   (position in the CAMERA frame)
  directional light: pixel = V rho E cos(theta_i)                  (direction WORLD, toward light)
and writes a scene folder: scene.json, photos (.exr via OpenImageIO, or 16-bit linear .png via
OpenCV), and the mesh (.ply via trimesh, with vertex normals).

It deliberately shares no code with `capture`: rays are built from the contract formulas here,
hits come from trimesh's own ray interface, and normals are interpolated with trimesh's
barycentric helper, so a bug in capture cannot cancel itself out in a test.

Typical use (in a test, with tmp_path):
    from synthetic import (sphere_mesh, ggx_lambert, pinhole_camera, point_light,
                           write_synthetic_scene)
    folder = write_synthetic_scene(tmp_path / "s", sphere_mesh(), ggx_lambert(),
                                   pinhole_camera(256, 256, 1000.0),
                                   [point_light([0.03, 0, 0])])
BRDF functions take (wi, wo, normal) (N, 3) unit world vectors and return (N, 3) in 1/sr.
"""

import json
from pathlib import Path

import numpy as np

from flashbrdf.brdf.angles import half_diff_from_world
from flashbrdf.brdf.lookup import evaluate_table


# ----- BRDFs -------------------------------------------------------------------------------
def ggx_lambert(diffuse=(0.5, 0.3, 0.2), specular=(0.8, 0.8, 0.8), alpha=0.2):
    """Lambert + GGX microfacet (Smith separable masking, no Fresnel) BRDF function, 1/sr.

    rho = diffuse / pi + specular D(theta_h) G1(theta_i) G1(theta_o) / (4 cos theta_i cos theta_o)
    """
    kd = np.asarray(diffuse, dtype=float) / np.pi
    ks = np.asarray(specular, dtype=float)
    a2 = alpha ** 2

    def g1(cos_t):
        tan2 = np.maximum(1 - cos_t ** 2, 0) / np.maximum(cos_t ** 2, 1e-12)
        return 2 / (1 + np.sqrt(1 + a2 * tan2))

    def brdf(wi, wo, normal):
        h = wi + wo
        h = h / np.linalg.norm(h, axis=-1, keepdims=True)
        ch = np.clip(np.sum(h * normal, -1), 1e-9, 1)
        ci = np.sum(wi * normal, -1)
        co = np.sum(wo * normal, -1)
        d = a2 / (np.pi * (ch ** 2 * (a2 - 1) + 1) ** 2)
        up = (ci > 0) & (co > 0)
        spec = np.where(up, d * g1(np.clip(ci, 1e-9, 1)) * g1(np.clip(co, 1e-9, 1))
                        / (4 * np.clip(ci, 1e-9, 1) * np.clip(co, 1e-9, 1)), 0)
        return np.where(up[:, None], kd + spec[:, None] * ks, 0)

    return brdf


def table_brdf(merl_table, interpolate=False):
    """BRDF function from a MERL table (90, 90, 180, 3) 1/sr via brdf.lookup.evaluate_table."""
    def brdf(wi, wo, normal):
        th, td, pd = half_diff_from_world(wi, wo, normal)
        return evaluate_table(merl_table, th, td, pd, interpolate=interpolate)
    return brdf


def by_region(brdfs, region):
    """A spatially varying BRDF function: brdfs[k] where region(points (N, 3)) -> (N,) int is k.

    Evaluated by `render` with the hit points (the attribute `spatial` tells it to pass them).
    """
    def brdf(wi, wo, normal, points):
        which = np.asarray(region(points))
        out = np.zeros((len(wi), 3))
        for k, fn in enumerate(brdfs):
            mine = which == k
            if mine.any():
                out[mine] = fn(wi[mine], wo[mine], normal[mine])
        return out
    brdf.spatial = True
    return brdf


def region_image(mesh, cam, region):
    """(H, W) int: 1 + region(hit point) per pixel that sees the mesh, 0 elsewhere (the true
    label image of a by_region scene)."""
    from trimesh.ray.ray_pyembree import RayMeshIntersector
    origins, dirs = _rays(cam)
    loc, index_ray, _ = RayMeshIntersector(mesh).intersects_location(origins, dirs,
                                                                    multiple_hits=False)
    out = np.zeros(cam["height"] * cam["width"], int)
    out[index_ray] = 1 + np.asarray(region(loc))
    return out.reshape(cam["height"], cam["width"])


def true_slice(brdf_fn):
    """rho (90, 3) of an analytic BRDF at the MERL theta_h bin centres, theta_d = 0 exactly."""
    from flashbrdf.brdf.merl import theta_h_centres
    th = theta_h_centres()
    w = np.stack([np.sin(th), np.zeros_like(th), np.cos(th)], -1)
    return brdf_fn(w, w.copy(), np.tile([0.0, 0.0, 1.0], (len(th), 1)))


# ----- geometry, cameras, lights -------------------------------------------------------------
def sphere_mesh(radius=0.1, centre=(0, 0, 1.0), subdivisions=5):
    """Icosphere with exact sphere vertex normals (trimesh.Trimesh)."""
    import trimesh
    m = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    normals = m.vertices / np.linalg.norm(m.vertices, axis=1, keepdims=True)
    m.apply_translation(centre)
    return trimesh.Trimesh(m.vertices, m.faces, vertex_normals=normals, process=False)


def torus_mesh(major=0.09, minor=0.035, centre=(0, 0, 1.0), tilt_deg=50.0, sections=(128, 64)):
    """Torus tilted about the x axis, with exact analytic vertex normals: a non-convex mesh whose
    ring shadows itself under an offset flash."""
    import trimesh
    u, v = np.meshgrid(np.linspace(0, 2 * np.pi, sections[0], endpoint=False),
                       np.linspace(0, 2 * np.pi, sections[1], endpoint=False), indexing="ij")
    ring = np.stack([np.cos(u), np.sin(u), np.zeros_like(u)], -1)
    normal = np.cos(v)[..., None] * ring + np.sin(v)[..., None] * np.array([0, 0, 1.0])
    verts = major * ring + minor * normal
    i, j = np.meshgrid(np.arange(sections[0]), np.arange(sections[1]), indexing="ij")
    a = i * sections[1] + j
    b = ((i + 1) % sections[0]) * sections[1] + j
    c = ((i + 1) % sections[0]) * sections[1] + (j + 1) % sections[1]
    d = i * sections[1] + (j + 1) % sections[1]
    faces = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3),
                            np.stack([a, c, d], -1).reshape(-1, 3)])
    t = np.radians(tilt_deg)
    rot = np.array([[1, 0, 0], [0, np.cos(t), -np.sin(t)], [0, np.sin(t), np.cos(t)]])
    verts = verts.reshape(-1, 3) @ rot.T + np.asarray(centre)
    normal = normal.reshape(-1, 3) @ rot.T
    return trimesh.Trimesh(verts, faces, vertex_normals=normal, process=False)


def box_mesh(extents=(0.1, 0.1, 0.1), centre=(0, 0, 0.8)):
    """Axis-aligned box with split corners, so every face shades flat (its vertex normals are
    the face normal)."""
    import trimesh
    box = trimesh.creation.box(extents=extents)
    verts = box.triangles.reshape(-1, 3) + np.asarray(centre)
    normals = np.repeat(box.face_normals, 3, axis=0)
    return trimesh.Trimesh(verts, np.arange(len(verts)).reshape(-1, 3), vertex_normals=normals,
                           process=False)


def combine(*meshes):
    """One mesh from several, keeping each part's vertex normals."""
    import trimesh
    offsets = np.cumsum([0] + [len(m.vertices) for m in meshes[:-1]])
    return trimesh.Trimesh(np.concatenate([m.vertices for m in meshes]),
                           np.concatenate([m.faces + o for m, o in zip(meshes, offsets)]),
                           vertex_normals=np.concatenate([m.vertex_normals for m in meshes]),
                           process=False)


def pinhole_camera(width=256, height=256, focal=1000.0, world_from_camera=None, distortion=None):
    """Contract camera dict: centred pinhole, identity pose unless given."""
    cam = {"model": "pinhole", "width": width, "height": height, "fx": focal, "fy": focal,
           "cx": (width - 1) / 2, "cy": (height - 1) / 2,
           "world_from_camera": np.eye(4).tolist() if world_from_camera is None
           else np.asarray(world_from_camera).tolist()}
    if distortion is not None:
        cam["distortion"] = list(distortion)
    return cam


def orthographic_camera(width=256, height=256, pixel_size=0.001, world_from_camera=None):
    return {"model": "orthographic", "width": width, "height": height, "pixel_size": pixel_size,
            "world_from_camera": np.eye(4).tolist() if world_from_camera is None
            else np.asarray(world_from_camera).tolist()}


def point_light(position=(0, 0, 0), intensity=(1, 1, 1)):
    """Point light dict; position in the CAMERA frame (metres)."""
    return {"type": "point", "position": list(map(float, position)),
            "intensity_rgb": list(map(float, intensity))}


def directional_light(direction=(0, 0, -1), irradiance=(1, 1, 1)):
    return {"type": "directional", "direction": list(map(float, direction)),
            "irradiance_rgb": list(map(float, irradiance))}


# ----- rendering ---------------------------------------------------------------------------
def _rays(cam):
    """Contract rays (H*W, 3) origins and unit directions, world frame (no lens distortion)."""
    h, w = cam["height"], cam["width"]
    v, u = np.mgrid[0:h, 0:w].reshape(2, -1).astype(float)
    pose = np.asarray(cam["world_from_camera"], dtype=float)
    if cam["model"] == "orthographic":
        s = cam["pixel_size"]
        local = np.stack([(u - (w - 1) / 2) * s, (v - (h - 1) / 2) * s, 0 * u], -1)
        return local @ pose[:3, :3].T + pose[:3, 3], np.tile(pose[:3, 2], (len(u), 1))
    if cam.get("distortion"):
        raise NotImplementedError("synthetic renders use undistorted cameras")
    d = np.stack([(u - cam["cx"]) / cam["fx"], (v - cam["cy"]) / cam["fy"], np.ones_like(u)], -1)
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    return np.tile(pose[:3, 3], (len(u), 1)), d @ pose[:3, :3].T


def render(mesh, brdf_fn, cam, light, shadows=True):
    """Radiance (H, W, 3) float64 of `mesh` under one light dict; 0 where the rays miss."""
    import trimesh
    from trimesh.ray.ray_pyembree import RayMeshIntersector
    ray = RayMeshIntersector(mesh)
    origins, dirs = _rays(cam)
    loc, index_ray, index_tri = ray.intersects_location(origins, dirs, multiple_hits=False)
    bary = trimesh.triangles.points_to_barycentric(mesh.triangles[index_tri], loc)
    normal = np.einsum("nk,nkj->nj", bary, mesh.vertex_normals[mesh.faces[index_tri]])
    normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
    wo = -dirs[index_ray]
    pose = np.asarray(cam["world_from_camera"], dtype=float)
    if light["type"] == "point":
        pos = pose[:3, :3] @ np.asarray(light["position"]) + pose[:3, 3]
        wi = pos - loc
        r = np.linalg.norm(wi, axis=-1)
        wi /= r[:, None]
        power = np.asarray(light["intensity_rgb"]) / (r ** 2)[:, None]
    else:
        wi = np.tile(np.asarray(light["direction"], float) / np.linalg.norm(light["direction"]),
                     (len(loc), 1))
        r = None
        power = np.tile(np.asarray(light["irradiance_rgb"], float), (len(loc), 1))
    cos_i = np.sum(normal * wi, -1)
    rho = brdf_fn(wi, wo, normal, loc) if getattr(brdf_fn, "spatial", False) else \
        brdf_fn(wi, wo, normal)
    value = rho * power * np.clip(cos_i, 0, None)[:, None]
    if shadows:
        eps = 1e-5 * mesh.scale
        lit = np.flatnonzero(cos_i > 0)
        o = loc[lit] + eps * wi[lit]
        hit_loc, hit_ray, _ = ray.intersects_location(o, wi[lit], multiple_hits=False)
        dist = np.full(len(lit), np.inf)
        dist[hit_ray] = np.linalg.norm(hit_loc - o[hit_ray], axis=-1)
        blocked = np.zeros(len(loc), bool)
        blocked[lit] = dist < (np.inf if r is None else r[lit] - 2 * eps)
        value[blocked] = 0
    out = np.zeros((cam["height"] * cam["width"], 3))
    out[index_ray] = value
    return out.reshape(cam["height"], cam["width"], 3)


def add_photon_noise(image, photons, rng):
    """Poisson noise with `photons` expected counts at the mean of the nonzero pixels."""
    mean = image[image > 0].mean()
    k = photons / mean
    return rng.poisson(np.clip(image, 0, None) * k) / k


# ----- writing -----------------------------------------------------------------------------
def write_exr(path, image):
    import OpenImageIO as oiio
    image = np.ascontiguousarray(image, dtype=np.float32)
    out = oiio.ImageOutput.create(str(path))
    spec = oiio.ImageSpec(image.shape[1], image.shape[0], image.shape[2], "float")
    out.open(str(path), spec)
    out.write_image(image)
    out.close()


def write_png16(path, image, white=1.0):
    """16-bit linear PNG: code = image / white * 65535, clipped (clipping is the point here)."""
    import cv2
    codes = np.clip(np.round(image / white * 65535), 0, 65535).astype(np.uint16)
    cv2.imwrite(str(path), codes[..., ::-1])


# camera post hooks for write_synthetic_scene(post=...): what a camera's file does to a photo
def quantiser(bits):
    """post hook for tests/synthetic.write_synthetic_scene: the photo quantised in steps of
    1/(2^bits - 1) of the 99th percentile of its positive channel values (object and occluder):
    the step an exposure that keeps the body in range would have. Unlike a real 8-bit photo the
    top 1% (the highlight) is not clipped: it keeps its value, quantised in the same steps."""
    levels = 2 ** bits - 1

    def post(image, _):
        image = np.asarray(image)
        lit = image[image > 0]
        white = float(np.percentile(lit, 99)) if lit.size else 1.0
        return np.round(image / white * levels) / levels * white
    return post


def demosaiced(image, _):
    """post hook: the photo sampled through an RGGB Bayer mosaic and demosaiced bilinearly
    (OpenCV), as a camera's developed photo is: adjacent pixels then share noise."""
    import cv2
    image = np.asarray(image, np.float32)
    scale = float(image.max()) or 1.0
    mosaic = np.zeros(image.shape[:2], np.float32)
    mosaic[0::2, 0::2] = image[0::2, 0::2, 0]     # R
    mosaic[0::2, 1::2] = image[0::2, 1::2, 1]     # G
    mosaic[1::2, 0::2] = image[1::2, 0::2, 1]     # G
    mosaic[1::2, 1::2] = image[1::2, 1::2, 2]     # B
    # OpenCV names Bayer patterns from the second row; its output is BGR
    code = np.clip(mosaic / scale * 65535, 0, 65535).astype(np.uint16)
    bgr = cv2.cvtColor(code, cv2.COLOR_BayerBG2BGR).astype(np.float64) / 65535 * scale
    return bgr[..., ::-1]


def phone_jpeg(quality):
    """post hook: demosaiced (demosaiced), then stored as a phone stores it: gamma 1/2.2 on the
    99th-percentile pixel's scale, 8 bits, JPEG at `quality` (OpenCV), read back and linearised
    with (x/255)^2.2 (as the planar cards' photos are); the top 1% clips at 255."""
    import cv2

    def post(image, k):
        image = demosaiced(image, k)
        lit = image[image > 0]
        white = float(np.percentile(lit, 99)) if lit.size else 1.0
        code = np.clip(np.round((np.clip(image / white, 0, 1) ** (1 / 2.2)) * 255), 0, 255)
        ok, data = cv2.imencode(".jpg", code[..., ::-1].astype(np.uint8),
                                [cv2.IMWRITE_JPEG_QUALITY, quality])
        decoded = cv2.imdecode(data, cv2.IMREAD_COLOR)[..., ::-1].astype(np.float64)
        return (decoded / 255) ** 2.2 * white
    return post



def write_synthetic_scene(folder, mesh, brdf_fn, camera, lights, ambient=0.0, photons=None,
                          seed=0, photo_format="exr", white=None, scale=1.0, shadows=True,
                          mesh_name="object.ply", post=None, ambient_photo=True):
    """Render one flash photo per light dict and write a complete scene folder.

    folder: created if needed; mesh: trimesh.Trimesh (world units, vertex normals);
    brdf_fn(wi, wo, normal) -> (N, 3) 1/sr; camera: contract camera dict; lights: list of
    contract light dicts (point or directional).
    ambient: constant radiance added to every pixel of every photo, with a matching `ambient`
    photo (0 or ambient_photo=False: no ambient photo, the ambient stays in);
    photons: Poisson noise at that mean count (None = exact);
    photo_format: "exr" or "png16" (linear 16-bit, code 65535 = `white`, default the max pixel);
    scale: stored photo scale (pixels are multiplied by it); post(image, k) -> image: a hook to
    corrupt flash photo k (hot pixels, ...). Returns the folder Path.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    mesh.export(str(folder / mesh_name), vertex_normal=True)
    rng = np.random.default_rng(seed)
    images = [render(mesh, brdf_fn, camera, light, shadows) * scale + ambient
              for light in lights]
    if photons is not None:
        images = [add_photon_noise(im, photons, rng) for im in images]
    if post is not None:
        images = [post(im, k) for k, im in enumerate(images)]
    ext = ".exr" if photo_format == "exr" else ".png"
    top = white or max(float(np.max(im)) for im in images) * 1.0001
    photos = []
    for k, (light, image) in enumerate(zip(lights, images)):
        name = f"flash{k}{ext}"
        write_exr(folder / name, image) if ext == ".exr" else write_png16(folder / name, image,
                                                                           top)
        entry = {"file": name, "role": "flash", "light": light}
        if scale != 1.0:
            entry["scale"] = scale
        if ext == ".png":
            entry.update(encoding="linear", scale=scale / top)
        photos.append(entry)
    if ambient and ambient_photo:
        name = f"ambient{ext}"
        flat = np.full((camera["height"], camera["width"], 3), float(ambient))
        write_exr(folder / name, flat) if ext == ".exr" else write_png16(folder / name, flat, top)
        photos.append({"file": name, "role": "ambient"})
    scene = {"camera": camera, "geometry": {"mesh": mesh_name}, "photos": photos}
    (folder / "scene.json").write_text(json.dumps(scene, indent=1))
    return folder


def add_reference_photo(folder, mesh, brdf_fn, camera, light, photons, seed=1, name="ref.exr"):
    """Render `light` through the pixel model with photon noise (rng `seed`), write it to
    folder/name and list it in folder/scene.json as a reference photo."""
    image = add_photon_noise(render(mesh, brdf_fn, camera, light), photons,
                             np.random.default_rng(seed))
    write_exr(Path(folder) / name, image)
    doc = json.loads((Path(folder) / "scene.json").read_text())
    doc["photos"].append({"file": name, "role": "reference", "light": light})
    (Path(folder) / "scene.json").write_text(json.dumps(doc))
