"""capture: scene.json validation, camera conventions, Embree hits and shadow rays."""

import json

import cv2
import numpy as np
import pytest

from flashbrdf import capture
from flashbrdf.files.errors import InputError
from synthetic import box_mesh, combine, pinhole_camera, sphere_mesh, torus_mesh


def _write(folder, doc):
    (folder / "scene.json").write_text(json.dumps(doc))
    return folder


def _doc(**camera):
    cam = pinhole_camera(64, 48, 50.0)
    cam.update(camera)
    return {"camera": cam, "geometry": {"mesh": "object.ply"},
            "photos": [{"file": "f.exr", "role": "flash",
                        "light": {"type": "point", "position": [0.03, 0, 0],
                                  "intensity_rgb": [1, 2, 3]}},
                       {"file": "a.exr", "role": "ambient", "scale": 2},
                       {"brackets": [{"file": "r1.png", "exposure_s": 0.01}], "role": "reference",
                        "light": {"type": "envmap", "file": "env.hdr"}}]}


def test_load_scene_fields(tmp_path):
    scene = capture.load_scene(_write(tmp_path, _doc()))
    assert scene.camera.model == "pinhole" and scene.camera.shape == (48, 64)
    assert scene.camera.cx == 31.5 and scene.geometry.mesh == tmp_path / "object.ply"
    flash, ambient, ref = scene.photos
    assert np.array_equal(flash.light.position, [0.03, 0, 0]) and flash.scale == 1.0
    assert ambient.scale == 2.0 and ambient.scale_given and not flash.scale_given
    assert ref.brackets == ((tmp_path / "r1.png", 0.01),) and ref.stem == "r1"
    assert np.array_equal(ref.light.world_from_envmap, np.eye(3))
    assert scene.photos_with_role("flash") == [flash]


@pytest.mark.parametrize("edit, field", [
    (lambda d: d["camera"].update(model="fisheye"), "camera.model"),
    (lambda d: d["camera"].pop("fx"), "camera.fx"),
    (lambda d: d["camera"].update(width=0), "camera.width"),
    (lambda d: d["camera"].update(world_from_camera=[[1, 0, 0], [0, 1, 0]]),
     "camera.world_from_camera"),
    (lambda d: d["camera"].update(world_from_camera=np.diag([2, 1, 1, 1]).tolist()),
     "camera.world_from_camera"),
    (lambda d: d["camera"].update(distortion=[0.1, 0.2]), "camera.distortion"),
    (lambda d: d.update(geometry={}), "geometry"),
    (lambda d: d["photos"][0]["light"].update(position=[0, 0]), "photos[0].light.position"),
    (lambda d: d["photos"][0]["light"].update(intensity_rgb=[1, -1, 1]),
     "photos[0].light.intensity_rgb"),
    (lambda d: d["photos"][0].update(role="key"), "photos[0].role"),
    (lambda d: d["photos"][0].pop("light"), "photos[0].light"),
    (lambda d: d["photos"][1].update(scale="x"), "photos[1].scale"),
    (lambda d: d["photos"][2]["brackets"][0].pop("exposure_s"),
     "photos[2].brackets[0].exposure_s"),
    (lambda d: d["photos"][0].update(brackets=[]), "photos[0]"),
    (lambda d: d.update(photos=[]), "photos"),
    # a normal map is the scene camera's view only: another camera's photo was rendered through
    # it, rotated by the other pose, at exit 0
    (lambda d: (d.update(geometry={"normal_map": "n.npy", "mask": "m.png"}),
                d["photos"][2].update(camera={**d["camera"], "fx": 60.0})), "photos[2].camera"),
])
def test_bad_fields_name_file_and_field(tmp_path, edit, field):
    doc = _doc()
    edit(doc)
    with pytest.raises(InputError) as err:
        capture.load_scene(_write(tmp_path, doc))
    assert str(err.value).startswith(f"{tmp_path / 'scene.json'}: {field}:")


def test_missing_and_broken_json(tmp_path):
    with pytest.raises(InputError, match="scene.json: not found"):
        capture.load_scene(tmp_path)
    (tmp_path / "scene.json").write_text("{")
    with pytest.raises(InputError, match="not valid JSON"):
        capture.load_scene(tmp_path)


def _camera(tmp_path, **camera):
    return capture.load_scene(_write(tmp_path, _doc(**camera))).camera


def test_pinhole_rays_follow_opencv_convention(tmp_path):
    pose = np.eye(4)
    pose[:3, :3] = cv2.Rodrigues(np.array([0.1, -0.2, 0.3]))[0]
    pose[:3, 3] = [0.5, -1, 2]
    cam = _camera(tmp_path, world_from_camera=pose.tolist(), fx=50.0, fy=60.0, cx=30.0, cy=20.0)
    origins, dirs = capture.camera_rays(cam)
    assert dirs.shape == (48, 64, 3) and np.allclose(np.linalg.norm(dirs, axis=-1), 1)
    assert np.allclose(origins, pose[:3, 3])
    # the principal point's ray is the camera's +z axis in world
    assert np.allclose(dirs[20, 30], pose[:3, 2])
    # pixel (u, v) = (column, row): u = fx X / Z + cx in the camera frame
    local = dirs[7, 41] @ pose[:3, :3]
    assert np.allclose([50 * local[0] / local[2] + 30, 60 * local[1] / local[2] + 20], [41, 7])
    uv, depth = capture.project_points(cam, origins[7, 41] + 3 * dirs[7, 41])
    assert np.allclose(uv, [[41, 7]]) and depth[0] > 0


def test_distorted_rays_reproject_through_opencv(tmp_path):
    cam = _camera(tmp_path, distortion=[-0.25, 0.08, 0.001, -0.002, 0.01])
    origins, dirs = capture.camera_rays(cam)
    points = (origins + 2.0 * dirs).reshape(-1, 3)
    uv, _ = cv2.projectPoints(points, np.zeros(3), np.zeros(3), cam.intrinsics, cam.distortion)
    rows, cols = np.mgrid[0:48, 0:64]
    assert np.abs(uv.reshape(-1, 2) - np.stack([cols.ravel(), rows.ravel()], -1)).max() < 1e-6
    # and distortion moves the corner rays (barrel: k1 < 0 pushes them outward)
    plain = capture.camera_rays(_camera(tmp_path))[1]
    assert np.degrees(np.arccos(np.dot(plain[0, 0], dirs[0, 0]))) > 0.5


def test_orthographic_rays(tmp_path):
    doc = _doc()
    doc["camera"] = {"model": "orthographic", "width": 5, "height": 3, "pixel_size": 0.01,
                     "world_from_camera": np.eye(4).tolist()}
    cam = capture.load_scene(_write(tmp_path, doc)).camera
    origins, dirs = capture.camera_rays(cam)
    assert np.allclose(origins[0, 0], [-0.02, -0.01, 0]) and np.allclose(origins[2, 4],
                                                                          [0.02, 0.01, 0])
    assert np.allclose(dirs, [0, 0, 1])


def _sphere_rays(tmp_path):
    cam = _camera(tmp_path, width=96, height=96, fx=300.0, fy=300.0, cx=47.5, cy=47.5)
    return cam, *capture.camera_rays(cam)


def test_intersect_matches_analytic_sphere(tmp_path):
    cam, origins, dirs = _sphere_rays(tmp_path)
    mesh = sphere_mesh(radius=0.1, centre=(0, 0, 1), subdivisions=5)
    hits = capture.intersect(capture.MeshIntersector(mesh), origins, dirs)
    b = np.einsum("...i,...i", dirs, origins - [0, 0, 1])
    disc = b ** 2 - (np.sum((origins - [0, 0, 1]) ** 2, -1) - 0.01)
    inside = disc > 0
    t = -b - np.sqrt(np.clip(disc, 0, None))
    exact = origins + t[..., None] * dirs
    # only rim pixels may differ (the mesh is inscribed in the sphere)
    assert np.count_nonzero(inside != hits.hit) <= 0.02 * inside.sum()
    core = inside & hits.hit & (t < 0.93)  # incidence < 46 deg, away from the rim
    # icosphere level 5: edges ~ 3.8 mm (up to ~1.2x that), sagitta ~ edge^2 / (8 r) <= 26 um
    # radially, / cos(46 deg) along the ray: <= 37 um
    assert np.abs(hits.points[core] - exact[core]).max() < 4e-5
    normal = (exact - [0, 0, 1]) / 0.1
    angle = np.degrees(np.arccos(np.clip(np.sum(normal[core] * hits.normals[core], -1), -1, 1)))
    assert angle.max() < 0.1  # interpolated vertex normals are nearly exact
    assert np.all(hits.face[~hits.hit] == -1) and np.all(np.isinf(hits.distance[~hits.hit]))


def test_face_normals_when_file_has_none(tmp_path):
    import trimesh
    trimesh.creation.icosphere(3, radius=0.1).export(tmp_path / "plain.obj", include_normals=False)
    mesh, has_normals = capture.load_mesh(tmp_path / "plain.obj")
    assert not has_normals
    mesh.apply_translation([0, 0, 1])
    mi = capture.MeshIntersector(mesh, use_vertex_normals=has_normals)
    cam, origins, dirs = _sphere_rays(tmp_path)
    hits = capture.intersect(mi, origins, dirs)
    assert np.allclose(hits.normals[hits.hit], mesh.face_normals[hits.face[hits.hit]])


def test_mesh_file_normals_are_used(tmp_path):
    sphere_mesh().export(tmp_path / "s.ply", vertex_normal=True)
    _, has_normals = capture.load_mesh(tmp_path / "s.ply")
    assert has_normals
    with pytest.raises(InputError, match="mesh file not found"):
        capture.load_mesh(tmp_path / "none.ply")
    (tmp_path / "bad.ply").write_text("ply\nnonsense\n")
    with pytest.raises(InputError, match="bad.ply"):
        capture.load_mesh(tmp_path / "bad.ply")
    # a binary STL claiming 2^31 triangles: trimesh falls back to a text reader whose optional
    # dependency may be absent: one line says the file cannot be decoded (not "No module named")
    (tmp_path / "bomb.stl").write_bytes(b"\0" * 80 + (2 ** 31).to_bytes(4, "little") + b"\0" * 50)
    with pytest.raises(InputError, match="bomb.stl: cannot read mesh") as err:
        capture.load_mesh(tmp_path / "bomb.stl")
    assert "No module named" not in str(err.value) and "\n" not in str(err.value)


def test_vertex_past_float32_rays_is_bad_input(tmp_path):
    """A vertex at 1e31 (finite, but past what float32 rays and Embree hold once squared or
    differenced) is bad input naming the mesh; at 1e29 the mesh loads."""
    import trimesh
    for far, ok in ((1e29, True), (1e31, False)):
        mesh = trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, far, 0]], [[0, 1, 2]], process=False)
        mesh.export(tmp_path / "far.ply")
        if ok:
            vertices = capture.load_mesh(tmp_path / "far.ply")[0].vertices
            assert np.isclose(vertices.max(), far, rtol=1e-7)   # PLY stores float32
        else:
            with pytest.raises(InputError, match=r"far.ply: a vertex coordinate 1e\+31 is beyond"):
                capture.load_mesh(tmp_path / "far.ply")


def test_gltf_file_normals_are_used_and_placed_by_the_scene_graph(tmp_path):
    """A GLB loads as a trimesh Scene; its NORMAL attribute is the file's vertex normals and is
    the shading normal (contract geometry.mesh), transformed with the node. One flat triangle in
    z = 1 whose file normals all tilt 30 deg about y, in a node turned 90 deg about z: a ray down
    the optical axis must see the tilted normal turned about z (sin 30, 0, -cos 30) -> (0, sin 30,
    -cos 30), not the face normal (0, 0, -1) (which Scene.dump() gave: it drops file normals)."""
    import trimesh
    tilt = np.radians(30.0)
    normal = [np.sin(tilt), 0.0, -np.cos(tilt)]
    triangle = trimesh.Trimesh([[-1.0, -1.0, 0.0], [0.0, 2.0, 0.0], [2.0, -1.0, 0.0]], [[0, 1, 2]],
                               vertex_normals=[normal] * 3, process=False)
    node = trimesh.transformations.rotation_matrix(np.pi / 2, [0, 0, 1])
    node[2, 3] = 1.0
    scene = trimesh.Scene()
    scene.add_geometry(triangle, transform=node)
    scene.export(tmp_path / "t.glb")
    mesh, has_normals = capture.load_mesh(tmp_path / "t.glb")
    assert has_normals
    mi = capture.MeshIntersector(mesh, use_vertex_normals=has_normals)
    hits = capture.intersect(mi, np.array([[0.1, 0.1, 0.0]]), np.array([[0.0, 0.0, 1.0]]))
    assert hits.hit[0] and abs(hits.points[0, 2] - 1.0) < 1e-6
    assert np.allclose(hits.normals[0], [0.0, np.sin(tilt), -np.cos(tilt)], atol=1e-5)


def test_a_part_without_normals_takes_face_normals_and_leaves_the_others_theirs(tmp_path):
    """Contract geometry.mesh: the file's vertex normals, or the face normal where there are none.
    A GLB of two parts, one with tilted file normals and one without any, was shaded with face
    normals everywhere: the first part's ray saw (0, 0, -1) instead of its file's tilted normal."""
    import trimesh
    tilt = np.radians(30.0)
    normal = [np.sin(tilt), 0.0, -np.cos(tilt)]
    with_normals = trimesh.Trimesh([[-3.0, -1.0, 1.0], [-2.0, 2.0, 1.0], [-1.0, -1.0, 1.0]],
                                   [[0, 1, 2]], vertex_normals=[normal] * 3, process=False)
    without = trimesh.Trimesh([[1.0, -1.0, 1.0], [3.0, -1.0, 1.0], [2.0, 2.0, 1.5]], [[0, 1, 2]],
                              process=False)
    scene = trimesh.Scene()
    scene.add_geometry(with_normals)
    scene.add_geometry(without)
    scene.export(tmp_path / "mixed.glb")
    mesh, has_normals = capture.load_mesh(tmp_path / "mixed.glb")
    assert has_normals
    mi = capture.MeshIntersector(mesh, use_vertex_normals=has_normals)
    hits = capture.intersect(mi, np.array([[-2.0, 0.0, 0.0], [2.0, 0.0, 0.0]]),
                             np.array([[0.0, 0.0, 1.0]] * 2))
    assert hits.hit.all()
    assert np.allclose(hits.normals[0], normal, atol=1e-5)
    # the second part's face normal, up to its side (which way the ray meets it)
    assert np.allclose(np.abs(hits.normals[1]), np.abs(without.face_normals[0]), atol=1e-5)


def test_non_numeric_normal_map_is_bad_input(tmp_path, capsys):
    """A normals.npy of strings is bad input (exit 2, one line naming the file), not a
    traceback (exit 1)."""
    from flashbrdf.cli.main import main
    from synthetic import write_exr
    np.save(tmp_path / "normals.npy", np.full((4, 4, 3), "a"))
    cv2.imwrite(str(tmp_path / "mask.png"), np.full((4, 4), 255, np.uint8))
    write_exr(tmp_path / "flash.exr", np.full((4, 4, 3), 0.5))
    (tmp_path / "scene.json").write_text(json.dumps({
        "camera": {"model": "orthographic", "width": 4, "height": 4, "pixel_size": 1.0,
                   "world_from_camera": np.eye(4).tolist()},
        "geometry": {"normal_map": "normals.npy", "mask": "mask.png"},
        "photos": [{"file": "flash.exr", "role": "flash",
                    "light": {"type": "directional", "direction": [0, 0, -1],
                              "irradiance_rgb": [1, 1, 1]}}]}))
    assert main(["extract", str(tmp_path), "--out", str(tmp_path / "out" / "s.csv")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "normals.npy: holds <U1 values" in err[0]
    assert not (tmp_path / "out").exists()


def test_vertices_no_face_uses_are_dropped(tmp_path):
    """Vertices no face uses (photogrammetry leaves them after cleaning) are dropped on load: a
    stray vertex 1e6 away would otherwise widen the box of pixels traced to every pixel of every
    photo, and a NaN one would refuse a mesh whose triangles are fine. Hits agree with the clean
    mesh to float64 rounding."""
    import trimesh
    sphere = sphere_mesh(radius=0.1, centre=(0, 0, 1), subdivisions=4)
    stray = np.array([[1e6, 1e6, 1e6], [-1e6, 0, 0], [np.nan, 0, 0]])
    dirty = trimesh.Trimesh(np.vstack([stray, sphere.vertices]), sphere.faces + len(stray),
                            vertex_normals=np.vstack([np.tile([0, 0, 1.0], (3, 1)),
                                                      sphere.vertex_normals]), process=False)
    sphere.export(tmp_path / "clean.ply", vertex_normal=True)
    dirty.export(tmp_path / "dirty.ply", vertex_normal=True)
    clean, _ = capture.load_mesh(tmp_path / "clean.ply")
    loaded, has_normals = capture.load_mesh(tmp_path / "dirty.ply")
    assert has_normals and len(loaded.vertices) == len(sphere.vertices)
    assert np.array_equal(loaded.vertices, clean.vertices)
    assert np.array_equal(loaded.vertex_normals, clean.vertex_normals)
    _, origins, dirs = _sphere_rays(tmp_path)
    want = capture.intersect(capture.MeshIntersector(clean, True), origins, dirs)
    got = capture.intersect(capture.MeshIntersector(loaded, True), origins, dirs)
    assert np.array_equal(got.hit, want.hit) and want.hit.sum() > 1000
    assert np.abs(got.points - want.points).max() < 1e-12


def test_triangles_kept_far_from_the_object_cost_it_no_precision(tmp_path):
    """A triangle 3e4 sphere sizes away (a Poisson skirt left untrimmed) must not move the float32
    frame off the object, nor scale the shadow-ray offset by the whole box: that offset was 1e-4
    of the box's diagonal, 0.6 here, three times the sphere, so a ray through the sphere from its
    surface started beyond it. Hits agree with the sphere alone to float32 rounding at the
    object's size (the frame centred on the box put the sphere at 3e3, spacing 2.4e-4)."""
    import trimesh
    sphere = sphere_mesh(radius=0.1, centre=(0, 0, 1), subdivisions=4)
    far = np.array([[6e3, 0, 1], [6e3 + 0.2, 0, 1], [6e3, 0.2, 1]])
    count = len(sphere.vertices)
    skirted = trimesh.Trimesh(np.vstack([sphere.vertices, far]),
                              np.vstack([sphere.faces, [[count, count + 1, count + 2]]]),
                              process=False)
    _, origins, dirs = _sphere_rays(tmp_path)
    want = capture.intersect(capture.MeshIntersector(sphere), origins, dirs)
    got = capture.intersect(capture.MeshIntersector(skirted), origins, dirs)
    assert np.array_equal(got.hit, want.hit) and want.hit.sum() > 1000
    assert np.abs(got.points - want.points)[want.hit].max() < 1e-6  # 1e-5 of the sphere
    # from the near pole straight through the sphere: the far side blocks it
    assert capture.occluded(capture.MeshIntersector(skirted), np.array([[0, 0, 0.9]]),
                            np.array([[0, 0, 1.0]]))[0]


def test_occluded_and_convexity():
    sphere = sphere_mesh(radius=0.1, centre=(0, 0, 1))
    blocker = box_mesh((0.1, 0.1, 0.02), (0, 0, 0.5))
    mi = capture.MeshIntersector(combine(sphere, blocker))
    top = np.array([[0, 0, 0.9]])  # sphere's front pole
    up = np.array([[0, 0, -1.0]])
    assert capture.occluded(mi, top, up, max_dist=0.9)[0]  # the box is in between
    assert not capture.occluded(mi, top, up, max_dist=0.3)[0]  # the light is before the box
    side = np.array([[1.0, 0, 0]])
    assert not capture.occluded(mi, np.array([[0.1, 0, 1]]), side)[0]
    assert capture.is_convex(sphere) and not capture.is_convex(torus_mesh())


def test_pixel_box_covers_every_hit(tmp_path):
    cam, origins, dirs = _sphere_rays(tmp_path)
    mesh = sphere_mesh(radius=0.05, centre=(0.05, -0.03, 0.8))
    hits = capture.intersect(mesh, origins, dirs)
    r0, r1, c0, c1 = capture.pixel_box(cam, mesh.bounds)
    rows, cols = np.nonzero(hits.hit)
    assert rows.min() >= r0 and rows.max() < r1 and cols.min() >= c0 and cols.max() < c1
    assert (r1 - r0) * (c1 - c0) < 0.5 * 96 * 96  # and it does cull


def test_gltf_node_with_a_singular_transform_is_bad_input(tmp_path):
    """A scene node that scales an axis to 0 has no inverse for its normals: InputError naming
    the file, not numpy's LinAlgError."""
    import trimesh
    from flashbrdf.files.errors import InputError
    triangle = trimesh.Trimesh([[-1.0, -1.0, 0.0], [0.0, 2.0, 0.0], [2.0, -1.0, 0.0]], [[0, 1, 2]],
                               vertex_normals=[[0.0, 0.0, 1.0]] * 3, process=False)
    scene = trimesh.Scene()
    scene.add_geometry(triangle, transform=np.diag([0.0, 1.0, 1.0, 1.0]))
    scene.export(tmp_path / "t.glb")
    with pytest.raises(InputError, match="t.glb"):
        capture.load_mesh(tmp_path / "t.glb")


@pytest.mark.parametrize("length", [2, 3, 6, 9])
def test_a_distortion_of_a_length_opencv_cannot_read_says_what_lengths_are_read(tmp_path, length):
    """4, 8, 12 and 14 coefficients are read as OpenCV reads them; any other length was refused
    with "expected 5 numbers", which a user with 8 that worked could not square with 3 that did
    not."""
    doc = _doc()
    doc["camera"]["distortion"] = [0.01] * length
    with pytest.raises(InputError) as err:
        capture.load_scene(_write(tmp_path, doc))
    assert str(err.value) == (f"{tmp_path / 'scene.json'}: camera.distortion: expected [k1, k2, "
                              "p1, p2, k3] (OpenCV's 4, 8, 12 or 14 coefficients are read too), "
                              f"got {length} numbers")
