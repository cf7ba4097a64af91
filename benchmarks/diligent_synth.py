"""Synthetic DiLiGenT-format objects: non-convex shapes with a known BRDF, cast shadows, clipping.

    python -m benchmarks.diligent_synth --out DIR [--cases dent_diffuse,...]
        [--lights /work/shared/data/real/diligent-ball] [--width 612 --height 512] [--list]

Each case is written as DIR/<case>/ exactly as DiLiGenT ships an object: 001.png ... 096.png
(16-bit RGB, or 8-bit linear crops as value / 257), filenames.txt, light_directions.txt and
light_intensities.txt (the real ball's, when --lights names its folder, else a built-in ring),
mask.png and Normal_gt.mat (key Normal_gt, H x W x 3, zeros outside the mask), plus truth.json
(the BRDF, the global exposure and the true theta_d = 0 slice in the imported photos' units).

Frames as DiLiGenT: x image right, y image up, z toward the camera; orthographic view along -z,
one world unit per pixel. Pixel model per light k (direct light, cast shadows by ray casting):
    code = clip(round(V * rho(wi, wo) * cos(theta_i) * EXPOSURE * intensity_k * 65535), 0, 65535)
so `import-diligent` (code / 65535 / intensity_k) gives rho * cos * EXPOSURE, and the true
slice in the photo's units is EXPOSURE * rho(theta_h, theta_d = 0).
"""

import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
from tests.synthetic import ggx_lambert, torus_mesh, true_slice

BALL = Path("/work/shared/data/real/diligent-ball")
CAMERA_Z = 5000.0


# ----- shapes (world = DiLiGenT frame, units = pixels, centred on the image centre) ----------
def _icosphere(radius, subdivisions=6):
    import trimesh
    return trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)


def _smooth(vertices, faces):
    import trimesh
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    return trimesh.Trimesh(vertices, faces, vertex_normals=mesh.vertex_normals, process=False)


def dented_sphere(radius=150.0, depth=0.6, width=0.6, axis=(0.35, 0.3, 1.0)):
    """A sphere with a deep smooth dent facing the camera (a bowl that shadows itself)."""
    base = _icosphere(1.0, 7)
    u = base.vertices / np.linalg.norm(base.vertices, axis=1, keepdims=True)
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    angle = np.arccos(np.clip(u @ a, -1, 1))
    r = radius * (1 - depth * np.exp(-(angle / width) ** 2))
    return _smooth(u * r[:, None], base.faces)


def two_spheres():
    """Two overlapping spheres, the smaller in front of and beside the larger: occlusion
    boundaries and a cast shadow of one on the other."""
    import trimesh
    big = _icosphere(130.0)
    small = _icosphere(80.0)
    big.apply_translation([-50, -20, 0])
    small.apply_translation([95, 60, 90])
    out = []
    for m in (big, small):
        n = m.vertices - m.vertices.mean(0)
        out.append(trimesh.Trimesh(m.vertices, m.faces,
                                   vertex_normals=n / np.linalg.norm(n, axis=1, keepdims=True),
                                   process=False))
    return _combine(out)


def _combine(meshes):
    import trimesh
    offsets = np.cumsum([0] + [len(m.vertices) for m in meshes[:-1]])
    return trimesh.Trimesh(np.concatenate([m.vertices for m in meshes]),
                           np.concatenate([m.faces + o for m, o in zip(meshes, offsets)]),
                           vertex_normals=np.concatenate([m.vertex_normals for m in meshes]),
                           process=False)


def torus():
    """A tilted torus: a hole in the mask, and the ring shadows itself."""
    import trimesh
    m = torus_mesh(major=150.0, minor=55.0, centre=(0, 0, 0), tilt_deg=-35.0, sections=(256, 96))
    return trimesh.Trimesh(m.vertices, m.faces, vertex_normals=m.vertex_normals, process=False)


def sphere_with_handle():
    """A sphere body with a thin torus handle on its right side (like a pot's handle): a thin
    part, a hole, and the handle's cast shadow on the body."""
    import trimesh
    body = _icosphere(140.0)
    n = body.vertices / np.linalg.norm(body.vertices, axis=1, keepdims=True)
    body = trimesh.Trimesh(body.vertices, body.faces, vertex_normals=n, process=False)
    handle = torus_mesh(major=75.0, minor=14.0, centre=(170.0, 0.0, 20.0), tilt_deg=20.0,
                        sections=(160, 40))
    return _combine([body, handle])


def big_offset_sphere():
    """A large sphere cut by the image's right edge (an object larger than the frame)."""
    import trimesh
    m = _icosphere(260.0, 6)
    n = m.vertices / np.linalg.norm(m.vertices, axis=1, keepdims=True)
    m.apply_translation([150.0, 0.0, 0.0])
    return trimesh.Trimesh(m.vertices, m.faces, vertex_normals=n, process=False)


def wires_and_islands():
    """Thin parts and separate pieces: a sphere, a 2-3 px wide wire ring around it (the mask is
    a few pixels wide there), and a small separate sphere (a second mask component)."""
    import trimesh
    body = _icosphere(110.0)
    n = body.vertices / np.linalg.norm(body.vertices, axis=1, keepdims=True)
    body = trimesh.Trimesh(body.vertices, body.faces, vertex_normals=n, process=False)
    wire = torus_mesh(major=170.0, minor=1.6, centre=(0, 0, 0), tilt_deg=-25.0,
                      sections=(512, 16))
    wire2 = torus_mesh(major=200.0, minor=3.0, centre=(0, 0, -30.0), tilt_deg=60.0,
                       sections=(512, 16))
    island = _icosphere(25.0, 4)
    n = island.vertices / np.linalg.norm(island.vertices, axis=1, keepdims=True)
    island.apply_translation([-240.0, 170.0, 0.0])
    island = trimesh.Trimesh(island.vertices, island.faces, vertex_normals=n, process=False)
    return _combine([body, wire, wire2, island])


SHAPES = {"wires": wires_and_islands, "big": big_offset_sphere, "dent": dented_sphere,
          "twospheres": two_spheres, "torus": torus, "handle": sphere_with_handle}


# ----- BRDFs ---------------------------------------------------------------------------------
def brdf_named(name):
    """(brdf_fn(wi, wo, normal[, points]), description dict)."""
    if name == "diffuse":
        d = (0.55, 0.40, 0.30)
        return ggx_lambert(d, (0, 0, 0), 0.3), {"model": "lambert", "diffuse": d}
    if name == "glossy":
        d, s, a = (0.35, 0.22, 0.15), (0.9, 0.9, 0.9), 0.08
        return ggx_lambert(d, s, a), {"model": "lambert+ggx", "diffuse": d, "specular": s,
                                      "alpha": a}
    if name == "dark":
        d, s, a = (0.025, 0.02, 0.018), (0.08, 0.08, 0.08), 0.15
        return ggx_lambert(d, s, a), {"model": "lambert+ggx", "diffuse": d, "specular": s,
                                      "alpha": a}
    if name == "metal":
        d, s, a = (0.004, 0.004, 0.003), (0.9, 0.75, 0.5), 0.05
        return ggx_lambert(d, s, a), {"model": "lambert+ggx", "diffuse": d, "specular": s,
                                      "alpha": a}
    if name == "textured":
        s, a = (0.5, 0.5, 0.5), 0.12
        spec_only = ggx_lambert((0, 0, 0), s, a)

        def albedo(points):
            # stripes and blobs of two paints on one glossy coat (textured, one material)
            t = 0.5 + 0.5 * np.sin(points[:, 0] / 9.0) * np.cos(points[:, 1] / 13.0)
            lo, hi = np.array([0.15, 0.25, 0.45]), np.array([0.55, 0.45, 0.25])
            return lo + t[:, None] * (hi - lo)

        def brdf(wi, wo, normal, points):
            up = (np.sum(wi * normal, -1) > 0) & (np.sum(wo * normal, -1) > 0)
            return spec_only(wi, wo, normal) + np.where(up[:, None], albedo(points) / np.pi, 0)
        brdf.spatial = True
        return brdf, {"model": "textured lambert + ggx", "specular": s, "alpha": a,
                      "albedo": "0.15..0.55 stripes"}
    if name == "patches":
        # six paints in Voronoi patches under one glossy coat (a painted object, harvest-like)
        s, a = (0.4, 0.4, 0.4), 0.1
        spec_only = ggx_lambert((0, 0, 0), s, a)
        seeds = np.random.default_rng(3).uniform(-160, 160, (40, 3))
        paints = np.array([[0.6, 0.15, 0.1], [0.1, 0.4, 0.15], [0.15, 0.2, 0.6],
                           [0.6, 0.55, 0.1], [0.05, 0.05, 0.05], [0.7, 0.7, 0.65]])

        def brdf(wi, wo, normal, points):
            from scipy.spatial import cKDTree
            which = cKDTree(seeds).query(points)[1] % len(paints)
            up = (np.sum(wi * normal, -1) > 0) & (np.sum(wo * normal, -1) > 0)
            return spec_only(wi, wo, normal) + np.where(up[:, None], paints[which] / np.pi, 0)
        brdf.spatial = True
        return brdf, {"model": "6 paints in patches + ggx coat", "specular": s, "alpha": a}
    raise KeyError(name)


# ----- rendering -----------------------------------------------------------------------------
def render_object(mesh, brdf_fn, directions, height, width, shadows=True):
    """-> (images (K, H, W, 3) rho*cos*V, normals (H, W, 3) DiLiGenT frame, hit mask (H, W))."""
    import trimesh
    from trimesh.ray.ray_pyembree import RayMeshIntersector
    ray = RayMeshIntersector(mesh)
    v, u = np.mgrid[0:height, 0:width].reshape(2, -1).astype(float)
    origins = np.stack([u - (width - 1) / 2, -(v - (height - 1) / 2),
                        np.full_like(u, CAMERA_Z)], -1)
    dirs = np.tile([0.0, 0.0, -1.0], (len(u), 1))
    loc, index_ray, index_tri = ray.intersects_location(origins, dirs, multiple_hits=False)
    bary = trimesh.triangles.points_to_barycentric(mesh.triangles[index_tri], loc)
    normal = np.einsum("nk,nkj->nj", bary, mesh.vertex_normals[mesh.faces[index_tri]])
    normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
    wo = np.tile([0.0, 0.0, 1.0], (len(loc), 1))
    images = np.zeros((len(directions), height * width, 3))
    eps = 1e-3 * mesh.scale
    for k, light in enumerate(directions):
        wi = np.tile(light, (len(loc), 1))
        cos_i = normal @ light
        rho = brdf_fn(wi, wo, normal, loc) if getattr(brdf_fn, "spatial", False) else \
            brdf_fn(wi, wo, normal)
        value = rho * np.clip(cos_i, 0, None)[:, None]
        if shadows:
            lit = np.flatnonzero(cos_i > 0)
            # offset along the light and the geometric normal: no self-hit acne
            o = loc[lit] + eps * wi[lit] + eps * mesh.face_normals[index_tri[lit]]
            blocked = ray.intersects_any(o, wi[lit])
            value[lit[blocked]] = 0
        images[k, index_ray] = value
    normals = np.zeros((height * width, 3))
    normals[index_ray] = normal
    hit = np.zeros(height * width, bool)
    hit[index_ray] = True
    return (images.reshape(len(directions), height, width, 3),
            normals.reshape(height, width, 3), hit.reshape(height, width))


def render_mitsuba(mesh, bsdf, directions, height, width, spp=64, max_depth=8, seed=0):
    """(K, H, W, 3) radiance with interreflections (Mitsuba 3 path tracer, llvm_ad_rgb): the
    same orthographic view and directional lights as render_object; pixels are box-filtered
    (antialiased silhouettes) and carry Monte Carlo noise."""
    import tempfile

    import mitsuba as mi
    mi.set_variant("llvm_ad_rgb")
    with tempfile.TemporaryDirectory() as tmp:
        ply = Path(tmp) / "object.ply"
        mesh.export(str(ply), vertex_normal=True)
        base = {
            "type": "scene", "integrator": {"type": "path", "max_depth": max_depth},
            "sensor": {"type": "orthographic",
                       "to_world": mi.ScalarTransform4f.look_at(
                           origin=[0, 0, CAMERA_Z], target=[0, 0, 0], up=[0, 1, 0])
                       @ mi.ScalarTransform4f.scale([width / 2, width / 2, 1]),
                       "film": {"type": "hdrfilm", "width": width, "height": height,
                                "rfilter": {"type": "box"}, "pixel_format": "rgb"},
                       "sampler": {"type": "independent", "sample_count": spp}},
            "obj": {"type": "ply", "filename": str(ply), "bsdf": bsdf}}
        images = []
        for k, light in enumerate(directions):
            scene = mi.load_dict(base | {"light": {
                "type": "directional", "direction": [float(-x) for x in light],
                "irradiance": {"type": "rgb", "value": [1.0, 1.0, 1.0]}}})
            images.append(np.array(mi.render(scene, seed=seed + k), dtype=np.float64))
    return np.stack(images)


MITSUBA_BSDFS = {
    "diffuse_bright": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.8, 0.6, 0.4]}},
    "gold": {"type": "roughconductor", "material": "Au", "distribution": "ggx", "alpha": 0.25},
    "plastic": {"type": "roughplastic", "distribution": "ggx", "alpha": 0.1,
                "diffuse_reflectance": {"type": "rgb", "value": [0.5, 0.3, 0.2]}},
}

# ----- cases ---------------------------------------------------------------------------------
CASES = {
    # name: shape, brdf, exposure, options
    "dent_diffuse": ("dent", "diffuse", 0.5, {}),
    "dent_glossy": ("dent", "glossy", 0.6, {}),
    "twospheres_glossy": ("twospheres", "glossy", 0.6, {}),
    "torus_diffuse": ("torus", "diffuse", 0.5, {}),
    "handle_glossy": ("handle", "glossy", 0.6, {}),
    "dent_dark": ("dent", "dark", 0.5, {}),
    "handle_textured": ("handle", "textured", 0.5, {}),
    "twospheres_holes": ("twospheres", "diffuse", 0.5, {"mask_holes": True}),
    "dent_badnormals": ("dent", "glossy", 0.6, {"bad_normals": True}),
    "torus_glossy": ("torus", "glossy", 0.6, {}),
    "torus_glossy_8bit": ("torus", "glossy", 0.6, {"bits": 8}),
    "dent_glossy_noshadow": ("dent", "glossy", 0.6, {"shadows": False}),
    "big_glossy_edge": ("big", "glossy", 0.6, {}),
    "dent_dark_8bit": ("dent", "dark", 0.5, {"bits": 8}),
    "dent_patches": ("dent", "patches", 0.5, {}),
    "wires_glossy": ("wires", "glossy", 0.6, {}),
    "wires_diffuse_8bit": ("wires", "diffuse", 0.5, {"bits": 8}),
    "dent_verydark_noisy": ("dent", "dark", 0.06, {"noise": True}),
    "dent_glossy_noisy": ("dent", "glossy", 0.6, {"noise": True}),
    "twospheres_metal": ("twospheres", "metal", 0.3, {}),
    "twospheres_metal_8bit": ("twospheres", "metal", 0.3, {"bits": 8}),
    # Mitsuba path traced: interreflections, antialiased silhouettes, Monte Carlo noise
    "dent_gi_diffuse": ("dent", "diffuse", 0.5, {"mitsuba": "diffuse_bright"}),
    "twospheres_gi_plastic": ("twospheres", "glossy", 0.6, {"mitsuba": "plastic"}),
    "dent_gi_gold": ("dent", "glossy", 0.25, {"mitsuba": "gold"}),
}


def _read_lights(folder):
    folder = Path(folder) if folder else None
    if folder and (folder / "light_directions.txt").is_file():
        d = np.loadtxt(folder / "light_directions.txt")
        i = np.loadtxt(folder / "light_intensities.txt")
        return d / np.linalg.norm(d, axis=1, keepdims=True), i
    rng = np.random.default_rng(0)  # 96 lights within 50 degrees of the view, 052 nearly on axis
    theta = np.radians(np.concatenate([rng.uniform(11, 50, 95)]))
    phi = rng.uniform(0, 2 * np.pi, 95)
    d = np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], -1)
    d = np.insert(d, 51, [np.sin(0.076), 0.0, np.cos(0.076)], axis=0)
    return d, rng.uniform(1.2, 2.8, (96, 3))


def write_case(out_dir, name, lights_dir=BALL, height=512, width=612):
    import cv2
    import scipy.io
    shape, brdf_name, exposure, opts = CASES[name]
    folder = Path(out_dir) / name
    folder.mkdir(parents=True, exist_ok=True)
    directions, intensities = _read_lights(lights_dir)
    mesh = SHAPES[shape]()
    brdf_fn, desc = brdf_named(brdf_name)
    images, normals, mask = render_object(mesh, brdf_fn, directions, height, width,
                                          shadows=opts.get("shadows", True))
    if opts.get("mitsuba"):
        images = render_mitsuba(mesh, MITSUBA_BSDFS[opts["mitsuba"]], directions, height, width)
        brdf_fn = lambda *a: None  # noqa: E731  the truth is Mitsuba's BSDF: no analytic slice
        brdf_fn.spatial = True
        desc = {"model": "mitsuba", "bsdf": opts["mitsuba"]}
    bits = opts.get("bits", 16)
    clipped = []
    for k in range(len(directions)):
        value = images[k] * exposure * intensities[k]
        codes = value * 65535
        if opts.get("noise"):
            # as a real sensor: a dark offset with read noise (~40 codes, as the ball's
            # background) and shot noise at 4 codes per electron
            rng = np.random.default_rng(100 + k)
            codes = rng.poisson(np.clip(codes, 0, None) / 4.0) * 4.0 \
                + rng.normal(40.0, 12.0, codes.shape)
        codes = np.clip(np.round(codes), 0, 65535)
        clipped.append(int((codes >= 65535).any(axis=2).sum()))
        if bits == 8:
            png = np.clip(np.round(codes / 257), 0, 255).astype(np.uint8)
        else:
            png = codes.astype(np.uint16)
        cv2.imwrite(str(folder / f"{k + 1:03d}.png"), png[..., ::-1])
    (folder / "filenames.txt").write_text("".join(f"{k + 1:03d}.png\n"
                                                  for k in range(len(directions))))
    np.savetxt(folder / "light_directions.txt", directions, fmt="%.6f")
    np.savetxt(folder / "light_intensities.txt", intensities, fmt="%.6f")
    mask_out = mask.copy()
    if opts.get("mask_holes"):
        # holes in the mask over object pixels (as DiLiGenT's hand-drawn masks leave out)
        v, u = np.mgrid[0:height, 0:width]
        for cu, cv_, r in ((260, 250, 12), (330, 200, 6), (200, 300, 20)):
            mask_out &= (u - cu) ** 2 + (v - cv_) ** 2 > r * r
    gt = np.where(mask_out[..., None], normals, 0.0)
    if opts.get("bad_normals"):
        rows, cols = np.nonzero(mask_out)
        pick = np.random.default_rng(1).choice(len(rows), 60, replace=False)
        gt[rows[pick[:20]], cols[pick[:20]]] = 0.0                      # zero normal in the mask
        gt[rows[pick[20:40]], cols[pick[20:40]]] = [0.3, 0.2, -0.93]    # facing away
        gt[rows[pick[40:]], cols[pick[40:]]] = np.nan                   # NaN
    cv2.imwrite(str(folder / "mask.png"), np.repeat(mask_out[..., None], 3, 2).astype(np.uint8)
                * 255)
    scipy.io.savemat(folder / "Normal_gt.mat", {"Normal_gt": gt})
    if getattr(brdf_fn, "spatial", False):
        truth = None
    else:
        truth = (true_slice(brdf_fn) * exposure).tolist()
    (folder / "truth.json").write_text(json.dumps({
        "case": name, "shape": shape, "brdf": desc, "exposure": exposure, "bits": bits,
        "options": opts, "mask_pixels": int(mask_out.sum()),
        "clipped_pixels_per_photo": clipped,
        "true_slice_photo_units": truth}, indent=1))
    return folder


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=False, type=Path)
    parser.add_argument("--cases", default="all")
    parser.add_argument("--lights", default=str(BALL))
    parser.add_argument("--width", type=int, default=612)
    parser.add_argument("--height", type=int, default=512)
    parser.add_argument("--list", action="store_true")
    args = parser.parse_args(argv)
    if args.list or args.out is None:
        print("\n".join(f"{k}: {v[0]}, {v[1]}, {v[3]}" for k, v in CASES.items()))
        return 0
    names = list(CASES) if args.cases == "all" else args.cases.split(",")
    for name in names:
        folder = write_case(args.out, name, args.lights, args.height, args.width)
        print(f"wrote {folder}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
