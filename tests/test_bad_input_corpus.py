"""A corpus of bad inputs for every command: each must exit 2 with one stderr line naming the file
or field, leave no new file anywhere, and leave every input byte-identical.

The world (a tiny 40x40 sphere capture with a flash photo and an envmap-lit reference, one MERL
(NBRDF proxy) table, its slice, two EXRs, a DiLiGenT folder, a folder of three MERL tables and
the shipped model) is built once; a case that needs a broken file breaks a copy in its own
tmp_path. Before and after each case every file under the world, the case's tmp_path and the
proxy tables is hashed (sha256; symlinks by their target text): a new file, a removed file, a
temporary folder left behind or a changed byte fails the case. The valid controls at the end run
the same commands on good input (exit 0), so a harness that passes everything would fail them.
"""

import hashlib
import json
import os
import shutil
import zipfile
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import pytest
import scipy.io

from flashbrdf.cli.main import main
from flashbrdf.pipeline.options import DEFAULT_MODEL
from flashbrdf.files.outputs import MARKER
from synthetic import ggx_lambert, pinhole_camera, point_light, sphere_mesh, write_synthetic_scene
from test_diligent_import import make_diligent

ENVMAP = Path(__file__).resolve().parents[2] / "shared" / "data" / "envmaps" / \
    "grace_latlong_256x128.hdr"
TABLES = ("blue-acrylic", "gold-metallic-paint", "red-specular-plastic")


@dataclass
class World:
    base: Path
    scene: Path
    model: Path
    brdf: Path
    slice: Path
    pred: Path
    ref: Path
    diligent: Path
    merl_dir: Path
    proxy_dir: Path


@pytest.fixture(scope="module")
def world(merl_proxy, tmp_path_factory):
    if not ENVMAP.is_file():
        pytest.skip(f"{ENVMAP} is absent (../shared beside the checkout is needed)")
    base = tmp_path_factory.mktemp("corpus")
    scene = write_synthetic_scene(base / "scene", sphere_mesh(subdivisions=3), ggx_lambert(),
                                  pinhole_camera(40, 40, 100.0), [point_light([0.02, 0, 0])])
    shutil.copy(ENVMAP, scene / "env.hdr")
    shutil.copy(scene / "flash0.exr", scene / "ref_env.exr")
    doc = json.loads((scene / "scene.json").read_text())
    doc["photos"].append({"file": "ref_env.exr", "role": "reference",
                          "light": {"type": "envmap", "file": "env.hdr",
                                    "world_from_envmap": np.eye(3).tolist()}})
    (scene / "scene.json").write_text(json.dumps(doc, indent=1))
    tables = merl_proxy(*TABLES)
    merl_dir = base / "merl"
    merl_dir.mkdir()
    for table in tables:
        (merl_dir / table.name).symlink_to(table)
    model = base / "model.npz"
    model.symlink_to(DEFAULT_MODEL)
    w = World(base, scene, model, tables[0], base / "slice.csv", base / "pred.exr",
              base / "ref.exr", base / "obj", merl_dir, tables[0].parent)
    assert main(["merl-slice", str(w.brdf), "--out", str(w.slice)]) == 0
    shutil.copy(scene / "flash0.exr", w.pred)
    shutil.copy(scene / "ref_env.exr", w.ref)
    make_diligent(w.diligent)
    return w


def snapshot(*roots):
    """{path: ("dir",) | ("link", target) | ("file", sha256)} of everything under the roots."""
    found = {}
    for root in roots:
        for folder, dirs, files in os.walk(root):
            found[folder] = ("dir",)
            for name in dirs + files:
                path = os.path.join(folder, name)
                if os.path.islink(path):
                    found[path] = ("link", os.readlink(path))
                elif name in files:
                    found[path] = ("file", file_hash(path))
    return found


_HASHES = {}


def file_hash(path):
    """sha256 of a file, remembered under its (inode, size, mtime, ctime): any write changes the
    ctime (which no user call can set back), so an unchanged key means unchanged bytes, and the
    35 MB tables are hashed once, not twice per case."""
    st = os.stat(path)
    key = (path, st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns)
    if key not in _HASHES:
        with open(path, "rb") as f:
            _HASHES[key] = hashlib.sha256(f.read()).hexdigest()
    return _HASHES[key]


# ----- helpers that make broken copies in the case's tmp_path --------------------------------
def scene_copy(w, tmp, edit=None):
    """A copy of the world's scene in tmp; edit(doc) changes its scene.json (a dict) in place."""
    folder = tmp / "scene"
    shutil.copytree(w.scene, folder)
    if edit is not None:
        doc = json.loads((folder / "scene.json").read_text())
        edit(doc)
        (folder / "scene.json").write_text(json.dumps(doc))  # NaN / Infinity as Python writes them
    return folder


def scene_with_literal(w, tmp, path, literal):
    """A copy of the world's scene whose scene.json holds the JSON text `literal` at doc[path...]
    (json.dumps cannot write an integer no float holds)."""
    folder = scene_copy(w, tmp, set_field(path, "@literal@"))
    text = (folder / "scene.json").read_text()
    (folder / "scene.json").write_text(text.replace('"@literal@"', literal))
    return folder


def scene_with_envmap(w, tmp, name, data):
    """A copy of the world's scene whose reference photo is lit by the map `data` as `name`."""
    folder = scene_copy(w, tmp, lambda doc: doc["photos"][1]["light"].update(file=name))
    (folder / name).write_bytes(data)
    return folder


def same_file_bracketed(doc):
    """scene_copy edit: the flash photo as brackets of one file at two exposures."""
    flash = doc["photos"][0]
    name = flash.pop("file")
    flash["brackets"] = [{"file": name, "exposure_s": t} for t in (1.0, 2.0)]


def scene_with_file(w, tmp, name, data):
    folder = scene_copy(w, tmp)
    (folder / name).write_bytes(data)
    return folder


def scene_with_flash(w, tmp, name, data, **fields):
    """A copy of the world's scene whose flash photo is `data` as `name` (fields: photos[0]'s
    others, e.g. encoding)."""
    folder = scene_copy(w, tmp, lambda doc: doc["photos"][0].update(file=name, **fields))
    (folder / name).write_bytes(data)
    return folder


def set_field(path, value):
    """An edit setting doc[path...] = value, path like ("camera", "width")."""
    def edit(doc):
        target = doc
        for key in path[:-1]:
            target = target[key]
        target[path[-1]] = value
    return edit


def ply_triangle(face):
    """An ASCII PLY of three vertices and one face of vertex indices `face` ("0 1 2")."""
    return ("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
            "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
            f"end_header\n0 0 1\n0.1 0 1\n0 0.1 1\n3 {face}\n").encode()


def normal_map_scene(w, tmp, save):
    """A copy of the world's scene with normal-map geometry (save(path) writes n.npy; the mask
    is all object) and only its flash photo, lit by a directional light."""
    import cv2

    def edit(doc):
        doc["geometry"] = {"normal_map": "n.npy", "mask": "m.png"}
        doc["photos"] = [{**doc["photos"][0], "light": {
            "type": "directional", "direction": [0, 0, -1], "irradiance_rgb": [1, 1, 1]}}]
    folder = scene_copy(w, tmp, edit)
    save(folder / "n.npy")
    cv2.imwrite(str(folder / "m.png"), np.full((40, 40), 255, np.uint8))
    return folder


def truncated(path, fraction=0.5):
    data = Path(path).read_bytes()
    return data[:int(len(data) * fraction)]


def exr_channels(tmp, names, values=0.5, name="c.exr", width=40, height=40):
    """The bytes of a width x height EXR with the given channel names (e.g. ("A",), ("X", "Y",
    "Z"))."""
    import OpenImageIO as oiio
    path = tmp / name
    spec = oiio.ImageSpec(width, height, len(names), oiio.FLOAT)
    spec.channelnames = tuple(names)
    out = oiio.ImageOutput.create(str(path))
    out.open(str(path), spec)
    out.write_image(np.full((height, width, len(names)), values, np.float32))
    out.close()
    data = path.read_bytes()
    path.unlink()
    return data


def image_bytes(ext, img):
    import cv2
    ok, buf = cv2.imencode(ext, img)
    assert ok
    return buf.tobytes()


def ascii_ply_cut(w):
    """The world's mesh as an ASCII PLY whose header declares every face and whose body holds
    half of them (a truncated download): trimesh reads it silently."""
    import trimesh
    mesh = trimesh.load(w.scene / "object.ply", process=False)
    head = ["ply", "format ascii 1.0", f"element vertex {len(mesh.vertices)}",
            "property float x", "property float y", "property float z",
            f"element face {len(mesh.faces)}", "property list uchar int vertex_indices",
            "end_header"]
    body = [" ".join(map(str, v)) for v in mesh.vertices] + \
        ["3 " + " ".join(map(str, f)) for f in mesh.faces[:len(mesh.faces) // 2]]
    return ("\n".join(head + body) + "\n").encode()


def write(tmp, name, data):
    path = tmp / name
    path.write_bytes(data if isinstance(data, bytes) else data.encode())
    return path


def zip_without_npz(tmp):
    path = tmp / "model.npz"
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("readme.txt", "not a model")
    return path


def npz_of_other_format(tmp):
    path = tmp / "model.npz"
    np.savez(path, format=np.array("somebody-elses-model"), names=np.array(["x"]))
    return path


def npz_of_wrong_shapes(tmp):
    from flashbrdf.infer.model_file import FORMAT
    path = tmp / "model.npz"
    np.savez(path, format=np.array(FORMAT), names=np.array(["a", "b"]),
             slices=np.zeros((2, 90)), tables_2d=np.zeros((2, 90, 90, 3)),
             params=np.array("{}"), merl_dir=np.array(""))
    return path


def model_with_valid_3d(w, tmp, bins):
    """A copy of the shipped model with stored 3D rows of `bins` bins per material (a whole
    model has one per valid MERL bin)."""
    path = tmp / "model.npz"
    with np.load(w.model, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    arrays["valid_3d"] = np.zeros((len(arrays["names"]), bins, 3), np.float32)
    np.savez(path, **arrays)
    return path


def second_reference(name):
    """An edit adding a second reference photo, `name` (a copy of the first's file is made by
    the case's scene_copy only where the name exists: the stem clash is found before any read)."""
    def edit(doc):
        doc["photos"].append({**doc["photos"][1], "file": name})
    return edit


def two_of_one_stem(folder):
    """A DiLiGenT folder whose filenames.txt lists a/x.png and b/x.png (and two more)."""
    for sub, photo in (("a", "001.png"), ("b", "002.png")):
        (folder / sub).mkdir()
        shutil.copy(folder / photo, folder / sub / "x.png")
    (folder / "filenames.txt").write_text("a/x.png\nb/x.png\n003.png\n004.png\n")


def marked_folder(tmp):
    folder = tmp / "old"
    folder.mkdir()
    (folder / MARKER).write_text("{}\n")
    (folder / "report.md").write_text("an earlier result\n")
    return folder


def user_folder(tmp):
    folder = tmp / "mine"
    folder.mkdir()
    (folder / "notes.txt").write_text("keep me\n")
    return folder


def merl_copy(w, tmp, broken=None):
    """A folder of links to the world's tables, plus `broken` (bytes) as bad.binary."""
    folder = tmp / "merl"
    folder.mkdir()
    for table in w.merl_dir.iterdir():
        (folder / table.name).symlink_to(os.readlink(table))
    if broken is not None:
        (folder / "bad.binary").write_bytes(broken)
    return folder


def diligent_copy(w, tmp, edit=None):
    folder = tmp / "obj"
    shutil.copytree(w.diligent, folder)
    if edit is not None:
        edit(folder)
    return folder


def merl_header(w, values):
    data = bytearray(w.brdf.read_bytes())
    data[:12] = np.array(values, "<i4").tobytes()
    return bytes(data)


def merl_body(w, edit):
    """The world's table with its stored values (file units, flat) replaced by edit(values)."""
    body = np.fromfile(w.brdf, dtype="<f8", offset=12)
    return w.brdf.read_bytes()[:12] + edit(body).astype("<f8").tobytes()


def nan_table(w):
    data = bytearray(w.brdf.read_bytes())
    data[12 + 8 * 1000:12 + 8 * 1001] = np.array([np.nan]).tobytes()
    return bytes(data)


def png8(folder):
    import cv2
    png16 = cv2.imread(str(folder / "002.png"), cv2.IMREAD_UNCHANGED)
    cv2.imwrite(str(folder / "002.png"), (png16 // 257).astype(np.uint8))


def window_bomb(tmp, name="bomb.exr"):
    """A 4x4 EXR whose display window is 60000x60000: placing it there took 40 GiB."""
    import OpenImageIO as oiio
    path = tmp / name
    spec = oiio.ImageSpec(4, 4, 3, oiio.FLOAT)
    spec.full_width = spec.full_height = 60000
    out = oiio.ImageOutput.create(str(path))
    out.open(str(path), spec)
    out.write_image(np.ones((4, 4, 3), np.float32))
    out.close()
    return path


def png_bomb(side=40000):
    """A PNG header of side x side 16-bit RGB pixels and a little data: over OpenCV's 2^30-pixel
    limit, where cv2.imread raises instead of returning None."""
    import struct
    import zlib

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(
            ">I", zlib.crc32(kind + data))
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", side, side, 16, 2, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(bytes(1000))) + chunk(b"IEND", b""))


def small_exr(tmp, name="small.exr"):
    from flashbrdf.render.images import write_exr
    path = tmp / name
    write_exr(path, np.ones((10, 12, 3), np.float32))
    return path


# ----- the corpus: (command, case id, argv builder (world, tmp) -> list, what the line names) ----
HERE = "<the case's tmp_path>"  # the error line must name the case's own folder


def _out(tmp, name="out"):
    return str(tmp / name)


def _run(scene, out, *extra):
    return ["run", str(scene), "--out", str(out), "--methods", "chandraker", "--spp", "2", *extra]


def _render(scene, brdf, out, *extra):
    return ["render", str(scene), "--brdf", str(brdf), "--out", str(out), "--spp", "2", *extra]


CASES = [
    # merl-slice
    ("merl-slice", "missing table", lambda w, t: ["merl-slice", str(t / "no.binary"), "--out",
                                                  _out(t, "s.csv")], "no.binary"),
    ("merl-slice", "truncated table", lambda w, t: ["merl-slice", str(write(
        t, "m.binary", truncated(w.brdf))), "--out", _out(t, "s.csv")], "m.binary"),
    ("merl-slice", "wrong header", lambda w, t: ["merl-slice", str(write(
        t, "m.binary", merl_header(w, [90, 90, 90]))), "--out", _out(t, "s.csv")], "m.binary"),
    ("merl-slice", "NaN in the table", lambda w, t: ["merl-slice", str(write(
        t, "m.binary", nan_table(w))), "--out", _out(t, "s.csv")], "m.binary"),
    ("merl-slice", "every value negative (no data)", lambda w, t: ["merl-slice", str(write(
        t, "m.binary", merl_body(w, lambda body: -np.ones_like(body)))), "--out",
        _out(t, "s.csv")], "m.binary"),
    ("merl-slice", "values of 1e300", lambda w, t: ["merl-slice", str(write(
        t, "m.binary", merl_body(w, lambda body: body * 1e300))), "--out", _out(t, "s.csv")],
     "m.binary"),
    ("export", "values of 1e300 (the fit's render check overflowed)", lambda w, t: [
        "export", str(write(t, "m.binary", merl_body(w, lambda body: body * 1e300))), "--out",
        _out(t)], "m.binary"),
    ("merl-slice", "out is the table", lambda w, t: ["merl-slice", str(w.brdf), "--out",
                                                     str(w.brdf)], TABLES[0]),
    ("merl-slice", "out is a link to the table", lambda w, t: [
        "merl-slice", str(w.brdf), "--out", str(link(t / "s.csv", w.brdf))], "s.csv"),
    ("merl-slice", "out is a folder", lambda w, t: ["merl-slice", str(w.brdf), "--out", str(t)],
     HERE),
    ("merl-slice", "out under a file", lambda w, t: [
        "merl-slice", str(w.brdf), "--out", str(write(t, "f.txt", "x") / "s.csv")], "f.txt"),
    ("merl-slice", "out ends in a slash", lambda w, t: ["merl-slice", str(w.brdf), "--out",
                                                    str(t / "s.csv") + "/"], "s.csv/"),
    ("merl-slice", "table is a folder", lambda w, t: ["merl-slice", str(t), "--out",
                                                      _out(t, "s.csv")], HERE),
    # extract
    ("extract", "no scene folder", lambda w, t: ["extract", str(t / "none"), "--out",
                                                 _out(t, "s.csv")], "none"),
    ("extract", "scene.json not JSON", lambda w, t: ["extract", str(scene_with_file(
        w, t, "scene.json", b"{camera: oops")), "--out", _out(t, "s.csv")], "scene.json"),
    ("extract", "ambient photo is the flash photo", lambda w, t: [  # flash - ambient = 0
        "extract", str(scene_copy(w, t, lambda doc: doc["photos"].append(
            {"file": "flash0.exr", "role": "ambient"}))), "--out", _out(t, "s.csv")],
     "flash0.exr"),
    ("extract", "camera.width NaN", lambda w, t: ["extract", str(scene_copy(
        w, t, set_field(("camera", "width"), float("nan")))), "--out", _out(t, "s.csv")],
     "scene.json: camera.width"),
    ("extract", "camera.height Infinity", lambda w, t: ["extract", str(scene_copy(
        w, t, set_field(("camera", "height"), float("inf")))), "--out", _out(t, "s.csv")],
     "scene.json: camera.height"),
    ("extract", "camera.width huge", lambda w, t: ["extract", str(scene_copy(
        w, t, set_field(("camera", "width"), 10 ** 12))), "--out", _out(t, "s.csv")],
     "scene.json: camera.width"),
    ("extract", "light position -Infinity", lambda w, t: ["extract", str(scene_copy(
        w, t, lambda d: d["photos"][0]["light"]["position"].__setitem__(1, float("-inf")))),
        "--out", _out(t, "s.csv")], "photos[0].light.position[1]"),
    ("extract", "NaN in an unknown field", lambda w, t: ["extract", str(scene_copy(
        w, t, set_field(("provenance",), {"x": [1, float("nan")]}))), "--out", _out(t, "s.csv")],
     "provenance.x[1]"),
    ("extract", "camera.fx an integer of 400 digits", lambda w, t: ["extract", str(
        scene_with_literal(w, t, ("camera", "fx"), "1" + "0" * 400)), "--out", _out(t, "s.csv")],
     "scene.json: camera.fx"),
    ("extract", "light position an integer of 400 digits", lambda w, t: ["extract", str(
        scene_with_literal(w, t, ("photos", 0, "light", "position", 0), "-1" + "0" * 400)),
        "--out", _out(t, "s.csv")], "photos[0].light.position[0]"),
    ("extract", "an integer of 5000 digits (over Python's limit)", lambda w, t: [
        "extract", str(scene_with_literal(w, t, ("camera", "width"), "4" * 5000)), "--out",
        _out(t, "s.csv")], "scene.json"),
    ("extract", "flash photo's name a lone surrogate (valid JSON, no file name)", lambda w, t: [
        "extract", str(scene_with_literal(w, t, ("photos", 0, "file"), r'"\ud800.exr"')),
        "--out", _out(t, "s.csv")], "photos[0].file"),
    ("extract", "camera pose not a rotation", lambda w, t: ["extract", str(scene_copy(
        w, t, set_field(("camera", "world_from_camera"), (2 * np.eye(4)).tolist()))), "--out",
        _out(t, "s.csv")], "camera.world_from_camera"),
    ("extract", "flash photo missing", lambda w, t: ["extract", str(scene_copy(
        w, t, lambda d: d["photos"][0].__setitem__("file", "gone.exr"))), "--out",
        _out(t, "s.csv")], "gone.exr"),
    ("extract", "flash photo truncated", lambda w, t: ["extract", str(scene_with_file(
        w, t, "flash0.exr", truncated(w.scene / "flash0.exr"))), "--out", _out(t, "s.csv")],
     "flash0.exr"),
    ("extract", "flash EXR of an alpha channel only", lambda w, t: ["extract", str(
        scene_with_file(w, t, "flash0.exr", exr_channels(t, ("A",)))), "--out",
        _out(t, "s.csv")], "flash0.exr"),
    ("extract", "flash EXR of X, Y, Z channels", lambda w, t: ["extract", str(
        scene_with_file(w, t, "flash0.exr", exr_channels(t, ("X", "Y", "Z")))), "--out",
        _out(t, "s.csv")], "flash0.exr"),
    ("extract", "flash EXR of R and G only", lambda w, t: ["extract", str(
        scene_with_file(w, t, "flash0.exr", exr_channels(t, ("R", "G")))), "--out",
        _out(t, "s.csv")], "flash0.exr"),
    ("extract", "flash photo an 8-bit PNG named .exr", lambda w, t: ["extract", str(
        scene_with_file(w, t, "flash0.exr", image_bytes(".png", np.full((40, 40, 3), 90,
                                                                         np.uint8)))),
        "--out", _out(t, "s.csv")], "flash0.exr"),
    ("extract", "flash photo a BMP", lambda w, t: ["extract", str(scene_with_flash(
        w, t, "f.bmp", image_bytes(".bmp", np.full((40, 40, 3), 90, np.uint8)))), "--out",
        _out(t, "s.csv")], "f.bmp"),
    ("extract", "encoding srgb on a float EXR", lambda w, t: ["extract", str(scene_copy(
        w, t, lambda d: d["photos"][0].__setitem__("encoding", "srgb"))), "--out",
        _out(t, "s.csv")], "flash0.exr"),
    ("extract", "a key given twice in scene.json", lambda w, t: ["extract", str(
        scene_with_literal(w, t, ("camera", "fx"), '100.0, "fx": 5000.0')), "--out",
        _out(t, "s.csv")], "'fx' is given twice"),
    ("extract", "one file twice in brackets", lambda w, t: ["extract", str(scene_copy(
        w, t, same_file_bracketed)), "--out", _out(t, "s.csv")], "photos[0].brackets[1].file"),
    ("extract", "ASCII PLY holding half its declared faces", lambda w, t: ["extract", str(
        scene_with_file(w, t, "object.ply", ascii_ply_cut(w))), "--out", _out(t, "s.csv")],
     "object.ply"),
    ("extract", "flash photo's display window 60000x60000", lambda w, t: ["extract", str(
        scene_with_file(w, t, "flash0.exr", window_bomb(t).read_bytes())), "--out",
        _out(t, "s.csv")], "flash0.exr"),
    ("extract", "flash photo a PNG of 40000x40000", lambda w, t: ["extract", str(
        scene_with_flash(w, t, "big.png", png_bomb(), encoding="linear")), "--out",
        _out(t, "s.csv")], "big.png"),
    ("extract", "normal map's mask a PNG of 40000x40000", lambda w, t: [
        "extract", str(write(normal_map_scene(w, t, lambda f: np.save(f, np.ones((40, 40, 3)))),
                             "m.png", png_bomb()).parent), "--out", _out(t, "s.csv")], "m.png"),
    ("extract", "mesh is garbage", lambda w, t: ["extract", str(scene_with_file(
        w, t, "object.ply", b"ply\nformat nonsense\n")), "--out", _out(t, "s.csv")],
     "object.ply"),
    ("extract", "mesh face past the last vertex", lambda w, t: ["extract", str(scene_with_file(
        w, t, "object.ply", ply_triangle("0 1 99"))), "--out", _out(t, "s.csv")], "object.ply"),
    ("extract", "mesh face of a negative vertex", lambda w, t: ["extract", str(scene_with_file(
        w, t, "object.ply", ply_triangle("0 1 -7"))), "--out", _out(t, "s.csv")], "object.ply"),
    ("extract", "normal map of strings", lambda w, t: ["extract", str(normal_map_scene(
        w, t, lambda f: np.save(f, np.full((40, 40, 3), "a")))), "--out", _out(t, "s.csv")],
     "n.npy"),
    ("extract", "normal map complex", lambda w, t: ["extract", str(normal_map_scene(
        w, t, lambda f: np.save(f, np.ones((40, 40, 3), complex)))), "--out", _out(t, "s.csv")],
     "n.npy"),
    ("extract", "normal map an .npz", lambda w, t: ["extract", str(normal_map_scene(
        w, t, lambda f: (np.savez(f.with_suffix(".npz"), n=np.ones((40, 40, 3))),
                         f.with_suffix(".npz").rename(f)))), "--out", _out(t, "s.csv")], "n.npy"),
    ("extract", "out is scene.json", lambda w, t: ["extract", str(w.scene), "--out",
                                                   str(w.scene / "scene.json")], "scene.json"),
    ("extract", "out is the flash photo", lambda w, t: ["extract", str(w.scene), "--out",
                                                        str(w.scene / "flash0.exr")], "flash0"),
    ("extract", "sidecar would replace scene.json", lambda w, t: [
        "extract", str(w.scene), "--out", str(w.scene / "scene.csv")], "scene"),
    ("extract", "out is a folder", lambda w, t: ["extract", str(w.scene), "--out", str(t)],
     HERE),
    ("extract", "out is the scene folder", lambda w, t: ["extract", str(w.scene), "--out",
                                                         str(w.scene)], "scene"),
    ("extract", "out ends in a slash", lambda w, t: ["extract", str(w.scene), "--out",
                                                 str(t / "s.csv") + "/"], "s.csv/"),
    ("extract", "out empty", lambda w, t: ["extract", str(w.scene), "--out", ""], "--out"),
    ("extract", "max-theta-d 0", lambda w, t: ["extract", str(w.scene), "--out", _out(t, "s.csv"),
                                               "--max-theta-d", "0"], "--max-theta-d"),
    # infer
    ("infer", "model missing", lambda w, t: ["infer", "--model", str(t / "none.npz"), "--slice",
                                             str(w.slice), "--out", _out(t, "b.binary")],
     "none.npz"),
    ("infer", "model truncated", lambda w, t: ["infer", "--model", str(write(
        t, "m.npz", truncated(w.model, 0.7))), "--slice", str(w.slice), "--out",
        _out(t, "b.binary")], "m.npz"),
    ("infer", "model empty", lambda w, t: ["infer", "--model", str(write(t, "m.npz", b"")),
                                           "--slice", str(w.slice), "--out", _out(t, "b.binary")],
     "m.npz"),
    ("infer", "model is text", lambda w, t: ["infer", "--model", str(write(
        t, "m.npz", "a model, honest\n")), "--slice", str(w.slice), "--out", _out(t, "b.binary")],
     "m.npz"),
    ("infer", "model is another zip", lambda w, t: ["infer", "--model", str(zip_without_npz(t)),
                                                    "--slice", str(w.slice), "--out",
                                                    _out(t, "b.binary")], "model.npz"),
    ("infer", "model of another format", lambda w, t: [
        "infer", "--model", str(npz_of_other_format(t)), "--slice", str(w.slice), "--out",
        _out(t, "b.binary")], "model.npz"),
    ("infer", "model arrays of the wrong shape", lambda w, t: [
        "infer", "--model", str(npz_of_wrong_shapes(t)), "--method", "pca", "--slice",
        str(w.slice), "--out", _out(t, "b.binary")], "model.npz"),
    ("infer", "model valid_3d of the wrong shape", lambda w, t: [
        "infer", "--model", str(model_with_valid_3d(w, t, 2)),
        "--method", "pca", "--slice", str(w.slice), "--out", _out(t, "b.binary")], "model.npz"),
    ("infer", "slice header wrong", lambda w, t: ["infer", "--method", "chandraker", "--slice",
                                                  str(write(t, "s.csv", "a,b,c\n")), "--out",
                                                  _out(t, "b.binary")], "s.csv"),
    ("infer", "slice too short", lambda w, t: ["infer", "--method", "chandraker", "--slice", str(
        write(t, "s.csv", "".join(w.slice.read_text().splitlines(True)[:40]))), "--out",
        _out(t, "b.binary")], "s.csv"),
    ("infer", "slice holds NaN", lambda w, t: ["infer", "--method", "chandraker", "--slice", str(
        write(t, "s.csv", nan_slice(w))), "--out", _out(t, "b.binary")], "s.csv"),
    ("infer", "slice value 1e300 (its prediction overflowed the table)", lambda w, t: [
        "infer", "--method", "chandraker", "--slice", str(write(t, "s.csv", nan_slice(w).replace(
            "nan", "1e300"))), "--out", _out(t, "b.binary")], "s.csv"),
    ("infer", "slice n beyond int64", lambda w, t: ["infer", "--method", "chandraker", "--slice",
                                                    str(write(t, "s.csv", slice_n(w, "9" * 30))),
                                                    "--out", _out(t, "b.binary")], "s.csv"),
    ("infer", "slice n negative in an empty bin", lambda w, t: [
        "infer", "--method", "chandraker", "--slice", str(write(t, "s.csv", slice_n(
            w, "-1", empty_bin=True))), "--out", _out(t, "b.binary")], "s.csv"),
    ("infer", "out is the slice", lambda w, t: ["infer", "--method", "chandraker", "--slice",
                                                str(w.slice), "--out", str(w.slice)], "slice.csv"),
    ("infer", "out is the model", lambda w, t: ["infer", "--model", str(w.model), "--slice",
                                                str(w.slice), "--out", str(w.model)], "model.npz"),
    ("infer", "sidecar would replace the slice", lambda w, t: [
        "infer", "--method", "chandraker", "--slice",
        str(write(t, "s.json", w.slice.read_bytes())), "--out", _out(t, "s.binary")], "s.json"),
    ("infer", "out ends in a slash", lambda w, t: ["infer", "--method", "chandraker", "--slice",
                                               str(w.slice), "--out", str(t / "b.binary") + "/"],
     "b.binary/"),
    ("infer", "out empty", lambda w, t: ["infer", "--method", "chandraker", "--slice",
                                         str(w.slice), "--out", ""], "--out"),
    ("infer", "slice empty (it named no file)", lambda w, t: [
        "infer", "--method", "chandraker", "--slice", "", "--out", _out(t, "b.binary")],
     "--slice"),
    ("infer", "merl-dir empty (it named no folder)", lambda w, t: [
        "infer", "--model", str(w.model), "--slice", str(w.slice), "--merl-dir", "", "--out",
        _out(t, "b.binary")], "--merl-dir"),
    ("infer", "out is a folder", lambda w, t: ["infer", "--method", "chandraker", "--slice",
                                               str(w.slice), "--out", str(t)], HERE),
    # train
    ("train", "merl-dir missing", lambda w, t: ["train", "--merl-dir", str(t / "none"), "--out",
                                                _out(t, "m.npz")], "none"),
    ("train", "merl-dir empty", lambda w, t: ["train", "--merl-dir", str(empty(t)), "--out",
                                              _out(t, "m.npz")], "empty"),
    ("train", "merl-dir is a file", lambda w, t: ["train", "--merl-dir", str(w.slice), "--out",
                                                  _out(t, "m.npz")], "slice.csv"),
    ("train", "a truncated table", lambda w, t: ["train", "--merl-dir", str(merl_copy(
        w, t, truncated(w.brdf, 0.1))), "--out", _out(t, "m.npz")], "bad.binary"),
    ("train", "a table of no data in a second folder", lambda w, t: [
        "train", "--merl-dir", str(w.merl_dir), "--merl-dir", str(write(
            empty(t), "none.binary", merl_body(w, lambda body: -np.ones_like(body))).parent),
        "--out", _out(t, "m.npz")], "none.binary"),
    ("train", "out is a table", lambda w, t: ["train", "--merl-dir", str(w.merl_dir), "--out",
                                              str(w.merl_dir / f"{TABLES[1]}.binary")], TABLES[1]),
    ("train", "out is the merl-dir", lambda w, t: ["train", "--merl-dir", str(w.merl_dir),
                                                   "--out", str(w.merl_dir)], "merl"),
    ("train", "out is a folder", lambda w, t: ["train", "--merl-dir", str(w.merl_dir), "--out",
                                               str(t)], HERE),
    # render
    ("render", "brdf missing", lambda w, t: _render(w.scene, t / "none.binary", _out(t)),
     "none.binary"),
    ("render", "brdf truncated", lambda w, t: _render(
        w.scene, write(t, "b.binary", truncated(w.brdf)), _out(t)), "b.binary"),
    ("render", "out is the scene", lambda w, t: _render(w.scene, w.brdf, w.scene), "scene"),
    ("render", "out holds the scene", lambda w, t: _render(w.scene, w.brdf, w.base), "corpus"),
    ("render", "out is a file", lambda w, t: _render(w.scene, w.brdf, write(t, "f.txt", "x")),
     "f.txt"),
    ("render", "out is someone's folder", lambda w, t: _render(w.scene, w.brdf, user_folder(t)),
     "mine"),
    ("render", "force on someone's folder", lambda w, t: _render(
        w.scene, w.brdf, user_folder(t), "--force"), "mine"),
    ("render", "earlier output without --force", lambda w, t: _render(
        w.scene, w.brdf, marked_folder(t)), "old"),
    ("render", "envmap missing", lambda w, t: _render(scene_copy(
        w, t, lambda d: d["photos"][1]["light"].__setitem__("file", "gone.hdr")), w.brdf,
        _out(t)), "gone.hdr"),
    ("render", "envmap garbage", lambda w, t: _render(scene_with_file(
        w, t, "env.hdr", b"#?RADIANCE\nnonsense"), w.brdf, _out(t)), "env.hdr"),
    ("render", "envmap's display window 60000x60000", lambda w, t: _render(scene_with_file(
        w, t, "env.hdr", window_bomb(t).read_bytes()), w.brdf, _out(t)), "env.hdr"),
    ("render", "world_from_envmap zero", lambda w, t: _render(scene_copy(
        w, t, lambda d: d["photos"][1]["light"].__setitem__("world_from_envmap",
                                                            np.zeros((3, 3)).tolist())),
        w.brdf, _out(t)), "photos[1].light.world_from_envmap"),
    ("render", "world_from_envmap 3I", lambda w, t: _render(scene_copy(
        w, t, lambda d: d["photos"][1]["light"].__setitem__("world_from_envmap",
                                                            (3 * np.eye(3)).tolist())),
        w.brdf, _out(t)), "photos[1].light.world_from_envmap"),
    ("render", "world_from_envmap a mirror", lambda w, t: _render(scene_copy(
        w, t, lambda d: d["photos"][1]["light"].__setitem__(
            "world_from_envmap", np.diag([1.0, 1.0, -1.0]).tolist())),
        w.brdf, _out(t)), "photos[1].light.world_from_envmap"),
    ("render", "reference photo wrong size", lambda w, t: _render(scene_with_file(
        w, t, "ref_env.exr", small_exr(t).read_bytes()), w.brdf, _out(t)), "ref_env.exr"),
    ("render", "camera cx 1e35 (no pixel sees the object)", lambda w, t: _render(scene_copy(
        w, t, lambda d: d["camera"].__setitem__("cx", 1e35)), w.brdf, _out(t)), "camera"),
    ("render", "a reference photo's own camera looks away", lambda w, t: _render(scene_copy(
        w, t, lambda d: d["photos"][1].__setitem__("camera", d["camera"] | {
            "world_from_camera": (np.diag([1.0, -1.0, -1.0, 1.0])
                                  @ np.asarray(d["camera"]["world_from_camera"])).tolist()})),
        w.brdf, _out(t)), "photos[1].camera"),
    ("render", "envmap of negative radiance", lambda w, t: _render(scene_with_envmap(
        w, t, "neg.exr", exr_channels(t, ("R", "G", "B"), values=-1.0, width=32, height=16)), w.brdf, _out(t)),
     "neg.exr"),
    ("render", "spp 0", lambda w, t: _render(w.scene, w.brdf, _out(t), "--spp", "0"), "--spp"),
    ("render", "spp 10**11 (out of memory)", lambda w, t: _render(
        w.scene, w.brdf, _out(t), "--spp", str(10 ** 11)), "--spp"),
    # compare
    ("compare", "pred missing", lambda w, t: ["compare", str(t / "none.exr"), str(w.ref),
                                              "--out", _out(t)], "none.exr"),
    ("compare", "ref garbage", lambda w, t: ["compare", str(w.pred), str(write(
        t, "r.exr", b"\x76\x2f\x31\x01garbage")), "--out", _out(t)], "r.exr"),
    ("compare", "sizes differ", lambda w, t: ["compare", str(w.pred), str(small_exr(t)),
                                              "--out", _out(t)], "small.exr"),
    ("compare", "pred's display window 60000x60000", lambda w, t: [
        "compare", str(window_bomb(t, "p.exr")), str(w.ref), "--out", _out(t)], "p.exr"),
    ("compare", "mask wrong size", lambda w, t: ["compare", str(w.pred), str(w.ref), "--mask",
                                                 str(small_exr(t, "m.exr")), "--out", _out(t)],
     "m.exr"),
    ("compare", "mask garbage", lambda w, t: ["compare", str(w.pred), str(w.ref), "--mask",
                                              str(write(t, "m.png", b"\x89PNG\r\n\x1a\nxx")),
                                              "--out", _out(t)], "m.png"),
    ("compare", "out is pred", lambda w, t: ["compare", str(w.pred), str(w.ref), "--out",
                                             str(w.pred)], "pred.exr"),
    ("compare", "out holds pred", lambda w, t: ["compare", str(w.pred), str(w.ref), "--out",
                                                str(w.base)], "corpus"),
    ("compare", "out is a file", lambda w, t: ["compare", str(w.pred), str(w.ref), "--out",
                                               str(write(t, "f.txt", "x"))], "f.txt"),
    # run
    ("run", "model truncated", lambda w, t: _run(w.scene, _out(t), "--model", str(write(
        t, "m.npz", truncated(w.model, 0.7)))), "m.npz"),
    ("run", "model is text", lambda w, t: _run(w.scene, _out(t), "--model", str(write(
        t, "m.npz", "not a model\n"))), "m.npz"),
    ("run", "model damaged inside", lambda w, t: _run(w.scene, _out(t), "--model", str(write(
        t, "m.npz", flipped_byte(w.model)))), "m.npz"),
    ("run", "model of another format", lambda w, t: _run(w.scene, _out(t), "--model",
                                                         str(npz_of_other_format(t))),
     "model.npz"),
    ("run", "model missing", lambda w, t: _run(w.scene, _out(t), "--model", str(t / "n.npz")),
     "n.npz"),
    ("run", "envmap missing", lambda w, t: _run(scene_copy(
        w, t, lambda d: d["photos"][1]["light"].__setitem__("file", "gone.hdr")), _out(t)),
     "gone.hdr"),
    ("run", "envmap not lat-long", lambda w, t: _run(scene_with_file(
        w, t, "env.hdr", small_exr(t, "e.exr").read_bytes()), _out(t)), "env.hdr"),
    ("run", "reference photo wrong size", lambda w, t: _run(scene_with_file(
        w, t, "ref_env.exr", small_exr(t).read_bytes()), _out(t)), "ref_env.exr"),
    ("run", "flash photo truncated", lambda w, t: _run(scene_with_file(
        w, t, "flash0.exr", truncated(w.scene / "flash0.exr")), _out(t)), "flash0.exr"),
    ("run", "scale NaN", lambda w, t: _run(scene_copy(
        w, t, lambda d: d["photos"][1]["light"].__setitem__("scale", float("nan"))), _out(t)),
     "photos[1].light.scale"),
    ("run", "world_from_envmap 3I", lambda w, t: _run(scene_copy(
        w, t, lambda d: d["photos"][1]["light"].__setitem__("world_from_envmap",
                                                            (3 * np.eye(3)).tolist())), _out(t)),
     "world_from_envmap"),
    ("run", "out is the scene", lambda w, t: _run(w.scene, w.scene), "scene"),
    ("run", "out holds the model", lambda w, t: _run(w.scene, w.base), "corpus"),
    ("run", "out is the model", lambda w, t: _run(w.scene, w.model, "--model", str(w.model)),
     "model.npz"),
    ("run", "out is a file", lambda w, t: _run(w.scene, write(t, "f.txt", "x")), "f.txt"),
    ("run", "out is someone's folder", lambda w, t: _run(w.scene, user_folder(t), "--force"),
     "mine"),
    ("run", "earlier output without --force", lambda w, t: _run(w.scene, marked_folder(t)),
     "old"),
    ("run", "out under a file", lambda w, t: _run(w.scene, write(t, "f.txt", "x") / "out"),
     "f.txt"),
    ("run", "out empty", lambda w, t: _run(w.scene, ""), "--out"),
    ("run", "unknown method", lambda w, t: ["run", str(w.scene), "--out", _out(t), "--methods",
                                            "magic"], "--methods"),
    # evaluate
    ("evaluate", "merl-dir missing", lambda w, t: ["evaluate", "--merl-dir", str(t / "none"),
                                                   "--out", _out(t)], "none"),
    ("evaluate", "merl-dir empty", lambda w, t: ["evaluate", "--merl-dir", str(empty(t)),
                                                 "--out", _out(t)], "empty"),
    ("evaluate", "out is the merl-dir", lambda w, t: ["evaluate", "--merl-dir", str(w.merl_dir),
                                                      "--out", str(w.merl_dir)], "merl"),
    ("evaluate", "out holds the merl-dir", lambda w, t: ["evaluate", "--merl-dir",
                                                         str(w.merl_dir), "--out", str(w.base)],
     "corpus"),
    ("evaluate", "out is a file", lambda w, t: ["evaluate", "--merl-dir", str(w.merl_dir),
                                                "--out", str(write(t, "f.txt", "x"))], "f.txt"),
    ("evaluate", "out is someone's folder", lambda w, t: [
        "evaluate", "--merl-dir", str(w.merl_dir), "--out", str(user_folder(t))], "mine"),
    # import-diligent
    ("import-diligent", "folder missing", lambda w, t: [
        "import-diligent", str(t / "none"), "--flash", "1", "--out", _out(t)], "none"),
    ("import-diligent", "intensities missing", lambda w, t: [
        "import-diligent", str(diligent_copy(w, t, lambda f: (f / "light_intensities.txt")
                                             .unlink())), "--flash", "1", "--out", _out(t)],
     "light_intensities.txt"),
    ("import-diligent", "Normal_gt.mat truncated", lambda w, t: [
        "import-diligent", str(diligent_copy(w, t, lambda f: (f / "Normal_gt.mat").write_bytes(
            truncated(f / "Normal_gt.mat")))), "--flash", "1", "--out", _out(t)], "Normal_gt.mat"),
    ("import-diligent", "photo garbage", lambda w, t: [
        "import-diligent", str(diligent_copy(w, t, lambda f: (f / "003.png").write_bytes(
            b"\x89PNG\r\n\x1a\n..."))), "--flash", "1", "--out", _out(t)], "003.png"),
    ("import-diligent", "light directions NaN", lambda w, t: [
        "import-diligent", str(diligent_copy(w, t, lambda f: (f / "light_directions.txt")
                                             .write_text("nan 0 1\n0 0 1\n0 0 1\n0 0 1\n"))),
        "--flash", "1", "--out", _out(t)], "light_directions.txt"),
    ("import-diligent", "light intensity 1e-50 (inf and NaN photos in float32)", lambda w, t: [
        "import-diligent", str(diligent_copy(w, t, lambda f: (f / "light_intensities.txt")
                                             .write_text("1e-50 1 1\n" + "1 1 1\n" * 3))),
        "--flash", "1", "--out", _out(t)], "light_intensities.txt"),
    ("import-diligent", "light intensity 1e308 (black photos in float32)", lambda w, t: [
        "import-diligent", str(diligent_copy(w, t, lambda f: (f / "light_intensities.txt")
                                             .write_text("1 1 1\n" * 3 + "1e308 1 1\n"))),
        "--flash", "1", "--out", _out(t)], "light_intensities.txt"),
    ("import-diligent", "a photo of 40000x40000", lambda w, t: [
        "import-diligent", str(diligent_copy(w, t, lambda f: (f / "003.png").write_bytes(
            png_bomb()))), "--flash", "1", "--out", _out(t)], "003.png"),
    ("import-diligent", "8-bit among 16-bit", lambda w, t: [
        "import-diligent", str(diligent_copy(w, t, png8)), "--flash", "1", "--out", _out(t)],
     "002.png"),
    ("import-diligent", "out is the folder", lambda w, t: [
        "import-diligent", str(w.diligent), "--flash", "1", "--out", str(w.diligent)], "obj"),
    ("import-diligent", "out holds the folder", lambda w, t: [
        "import-diligent", str(w.diligent), "--flash", "1", "--out", str(w.base)], "corpus"),
    ("import-diligent", "out is a capture folder", lambda w, t: [
        "import-diligent", str(w.diligent), "--flash", "1", "--out", str(scene_copy(w, t))],
     "scene"),
    ("import-diligent", "flash index 0", lambda w, t: [
        "import-diligent", str(w.diligent), "--flash", "0", "--out", _out(t)], "--flash"),
    ("import-diligent", "light directions empty (numpy warned on a second line)", lambda w, t: [
        "import-diligent", str(diligent_copy(w, t, lambda f: (f / "light_directions.txt")
                                             .write_text(""))), "--flash", "1", "--out", _out(t)],
     "light_directions.txt"),
    ("import-diligent", "Normal_gt a string", lambda w, t: [
        "import-diligent", str(diligent_copy(w, t, lambda f: scipy.io.savemat(
            f / "Normal_gt.mat", {"Normal_gt": "up"}))), "--flash", "1", "--out", _out(t)],
     "Normal_gt.mat"),
    ("import-diligent", "filenames.txt not UTF-8 (a traceback)", lambda w, t: [
        "import-diligent", str(diligent_copy(w, t, lambda f: (f / "filenames.txt").write_bytes(
            b"\xff\xfe0\x000\x001\x00"))), "--flash", "1", "--out", _out(t)], "filenames.txt"),
    ("import-diligent", "filenames.txt lists a photo twice (one EXR replaced the other)",
     lambda w, t: ["import-diligent", str(diligent_copy(w, t, lambda f: (
         f / "filenames.txt").write_text("001.png\n002.png\n003.png\n001.png\n"))), "--flash",
        "1", "--out", _out(t)], "filenames.txt"),
    ("import-diligent", "filenames.txt: a/x.png and b/x.png (both written as x.exr)",
     lambda w, t: ["import-diligent", str(diligent_copy(w, t, two_of_one_stem)), "--flash", "1",
                   "--out", _out(t)], "filenames.txt"),
    ("render", "two reference photos of one stem (one render replaced the other)", lambda w, t:
     _render(scene_copy(w, t, second_reference("ref_env.hdr")), w.brdf, _out(t)),
     "photos[2].file"),
    ("run", "two reference photos of one stem in two folders", lambda w, t: _run(
        scene_copy(w, t, second_reference("sub/ref_env.exr")), _out(t)), "photos[2].file"),
    ("render", "reference photos ref_env and ref_env_delta_e (both write ref_env_delta_e.png)",
     lambda w, t: _render(scene_copy(w, t, second_reference("ref_env_delta_e.exr")), w.brdf,
                          _out(t)), "photos[2].file"),
]


# ----- the multi-material and batch commands (issues 13 and 15) -------------------------------
def labels_png(w, tmp, name="labels.png", k=2, value=None, dtype=np.uint16, params=()):
    """The world scene's object pixels (its flash photo > 0) as labels 1..k in vertical bands
    (`value(labels) -> array` edits them), written as a PNG (or TIFF, JPEG, JPEG 2000 with OpenCV's
    `params`) in tmp."""
    import cv2
    from flashbrdf.render.images import read_image
    on = read_image(w.scene / "flash0.exr").sum(axis=2) > 0
    labels = np.where(on, 1 + np.arange(on.shape[1])[None, :] * k // on.shape[1], 0)
    path = tmp / name
    cv2.imwrite(str(path), (labels if value is None else value(labels)).astype(dtype), params)
    return path


def with_faces(png, faces):
    np.save(png.with_name(png.stem + ".faces.npy"), faces)
    return png


def marked_holding(tmp, source):
    """An earlier flashbrdf output folder holding a copy of `source` (an input of the case)."""
    folder = marked_folder(tmp)
    shutil.copy(source, folder / Path(source).name)
    return folder


def tiny_scene(tmp, radius):
    """A 16x16 capture of a sphere a few pixels wide (radius 0.03 m: 12 usable pixels; 0.004 m:
    none)."""
    return write_synthetic_scene(tmp / "tiny", sphere_mesh(radius=radius, subdivisions=2),
                                 ggx_lambert(), pinhole_camera(16, 16, 100.0),
                                 [point_light([0.02, 0, 0])])


def beside(path, suffix, data):
    """Write `data` as the sidecar of `path` with `suffix` (labels.png -> labels.faces.npy);
    return `path`."""
    write(path.parent, path.stem + suffix, data)
    return path


def npz_bytes(tmp):
    np.savez(tmp / "x.npz", faces=np.ones(3, np.int32))
    data = (tmp / "x.npz").read_bytes()
    (tmp / "x.npz").unlink()
    return data


def rgb_exr(tmp, name="albedo.exr", shape=(40, 40, 3), value=0.5):
    from flashbrdf.render.images import write_exr
    path = tmp / name
    write_exr(path, np.full(shape, value, np.float32))
    return path


def black_png(tmp):
    path = tmp / "m.png"
    cv2.imwrite(str(path), np.zeros((40, 40), np.uint8))
    return path


def model_with_params(w, tmp, params):
    """A copy of the shipped model whose `params` JSON is `params`."""
    path = tmp / "model.npz"
    with np.load(w.model, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    arrays["params"] = np.array(json.dumps(params))
    np.savez(path, **arrays)
    return path


def model_edited(w, tmp, key, edit):
    """A copy of the shipped model with array `key` replaced by edit(array)."""
    path = tmp / "model.npz"
    with np.load(w.model, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    arrays[key] = edit(arrays[key])
    np.savez(path, **arrays)
    return path


def links_to(folder, table, count):
    """`folder` holding t0.binary .. t<count-1>.binary, each a link to `table`."""
    for k in range(count):
        (folder / f"t{k}.binary").symlink_to(table)
    return folder


def no_theta_d_0(body):
    """A table's stored values (flat: per channel, phi_d fastest, then theta_d, then theta_h)
    with every theta_d = 0 value -1 (no data)."""
    table = body.copy()
    index = np.arange(body.size) % (90 * 90 * 180)
    table[(index // 180) % 90 == 0] = -1.0
    return table


def one_channel_exr(tmp, shape=(40, 40)):
    import OpenImageIO as oiio
    path = tmp / "albedo.exr"
    out = oiio.ImageOutput.create(str(path))
    out.open(str(path), oiio.ImageSpec(shape[1], shape[0], 1, oiio.FLOAT))
    out.write_image(np.full(shape, 0.5, np.float32))
    out.close()
    return path


def captures(w, tmp, *names):
    folder = tmp / "captures"
    for name in names:
        shutil.copytree(w.scene, folder / name)
    return folder


def _batch(folder, out, *extra):
    return ["batch", str(folder), "--out", str(out), "--methods", "chandraker", "--spp", "2",
            *extra]


def _two_tables(w):
    return f"{w.brdf},{w.merl_dir / f'{TABLES[1]}.binary'}"


SWEEP_CASES = [
    ("segment", "materials 0", lambda w, t: ["segment", str(w.scene), "--out", _out(t, "l.png"),
                                             "--materials", "0"], "--materials"),
    ("segment", "materials more than the pixels allow", lambda w, t: [
        "segment", str(tiny_scene(t, 0.03)), "--out", _out(t, "l.png"), "--materials", "8"],
     "--materials"),
    ("segment", "no object pixel", lambda w, t: ["segment", str(tiny_scene(t, 0.004)), "--out",
                                                 _out(t, "l.png")], "flash0.exr"),
    ("segment", "albedo's sidecar is the labels'", lambda w, t: [
        "segment", str(w.scene), "--out", _out(t, "l.png"), "--albedo", _out(t, "l.exr")],
     "l.json"),
    ("segment", "out is scene.png (its sidecar is scene.json)", lambda w, t: [
        "segment", str(w.scene), "--out", str(w.scene / "scene.png")], "scene.json"),
    ("extract", "labels wrong size", lambda w, t: [
        "extract", str(w.scene), "--labels", str(write(t, "l.png", b"")), "--out", _out(t)],
     "l.png"),
    ("extract", "labels is a folder", lambda w, t: [
        "extract", str(w.scene), "--labels", str(empty(t)), "--out", _out(t)], "empty"),
    ("extract", "labels a PNG of 40000x40000", lambda w, t: [
        "extract", str(w.scene), "--labels", str(write(t, "l.png", png_bomb())), "--out",
        _out(t)], "l.png"),
    ("extract", "labels float TIFF", lambda w, t: [
        "extract", str(w.scene), "--labels", str(labels_png(w, t, "l.tif", 1, dtype=np.float32)),
        "--out", _out(t)], "l.tif"),
    ("extract", "labels {1, 3}", lambda w, t: [
        "extract", str(w.scene), "--labels", str(labels_png(w, t, value=lambda a: a * 2 - (
            a > 0))), "--out", _out(t)], "labels.png"),
    ("extract", "labels JPEG (named .png)", lambda w, t: [
        "extract", str(w.scene), "--labels", str(labels_png(w, t, "l.jpg", dtype=np.uint8).rename(
            t / "l.png")), "--out", _out(t)], "l.png"),
    ("extract", "labels JPEG 2000", lambda w, t: [  # decodes to one channel: only its bytes tell
        "extract", str(w.scene), "--labels", str(labels_png(w, t, "l.jp2", dtype=np.uint8)),
        "--out", _out(t)], "l.jp2"),
    ("extract", "labels a JPEG-compressed TIFF", lambda w, t: [  # one channel: only its tags tell
        "extract", str(w.scene), "--labels", str(labels_png(w, t, "l.tif", dtype=np.uint8, params=(
            cv2.IMWRITE_TIFF_COMPRESSION, 7))), "--out", _out(t)], "l.tif"),
    ("extract", "labels unreadable", lambda w, t: [  # a regular file whose read fails (EIO)
        "extract", str(w.scene), "--labels", "/proc/self/mem", "--out", _out(t)], "mem"),
    ("extract", "labels RGB", lambda w, t: [
        "extract", str(w.scene), "--labels", str(labels_png(w, t, value=lambda a: np.dstack(
            [a] * 3), dtype=np.uint8)), "--out", _out(t)], "labels.png"),
    ("extract", "labels all zero", lambda w, t: [
        "extract", str(w.scene), "--labels", str(labels_png(w, t, value=lambda a: 0 * a)),
        "--out", _out(t)], "labels.png"),
    ("extract", "out is someone's folder", lambda w, t: [
        "extract", str(w.scene), "--labels", str(labels_png(w, t)), "--out", str(user_folder(t))],
     "mine"),
    ("extract", "labelled earlier output without --force", lambda w, t: [
        "extract", str(w.scene), "--labels", str(labels_png(w, t)), "--out", str(marked_folder(t))],
     "old"),
    ("render", "labels empty (read as not given)", lambda w, t: _render(
        w.scene, w.brdf, _out(t), "--labels", ""), "--labels"),
    ("evaluate", "test-dir empty (read as not given)", lambda w, t: [
        "evaluate", "--merl-dir", str(w.merl_dir), "--test-dir", "", "--out", _out(t)],
     "--test-dir"),
    ("render", "only commas in --brdf", lambda w, t: _render(w.scene, ",,", _out(t)), "--brdf"),
    ("render", "an empty item in --brdf", lambda w, t: _render(
        w.scene, f"{w.brdf},,{w.brdf}", _out(t), "--labels", str(labels_png(w, t))), "--brdf"),
    ("render", "more tables than labels", lambda w, t: _render(
        w.scene, f"{_two_tables(w)},{w.brdf}", _out(t), "--labels", str(labels_png(w, t))),
     "labels.png"),
    ("render", "label faces of another mesh", lambda w, t: _render(
        w.scene, _two_tables(w), _out(t), "--labels", str(with_faces(labels_png(w, t), np.ones(
            7, np.int32)))), "labels.faces.npy"),
    ("render", "label faces an empty file", lambda w, t: _render(
        w.scene, _two_tables(w), _out(t), "--labels", str(beside(labels_png(w, t), ".faces.npy",
                                                              b""))), "labels.faces.npy"),
    ("render", "label faces an .npz archive", lambda w, t: _render(
        w.scene, _two_tables(w), _out(t), "--labels", str(beside(labels_png(w, t), ".faces.npy",
                                                              npz_bytes(t)))),
     "labels.faces.npy"),
    ("render", "albedo faces an empty file", lambda w, t: _render(
        w.scene, w.brdf, _out(t), "--albedo", str(beside(rgb_exr(t), ".faces.npy", b""))),
     "albedo.faces.npy"),
    ("render", "albedo faces an .npz archive", lambda w, t: _render(
        w.scene, w.brdf, _out(t), "--albedo", str(beside(rgb_exr(t), ".faces.npy",
                                                         npz_bytes(t)))), "albedo.faces.npy"),
    ("render", "albedo floors an integer of 400 digits", lambda w, t: _render(
        w.scene, w.brdf, _out(t), "--albedo", str(beside(rgb_exr(t), ".json", '{"floors": [[1' +
                                                         "0" * 400 + ', 1, 1]]}'))),
     "albedo.json"),
    ("render", "--force onto a folder holding a listed table", lambda w, t: _render(
        w.scene, f"{w.brdf},{marked_holding(t, w.brdf) / w.brdf.name}", t / "old", "--labels",
        str(labels_png(w, t)), "--force"), "old"),
    ("render", "--force onto a folder holding the labels", lambda w, t: _render(
        w.scene, _two_tables(w), t / "old", "--labels",
        str(marked_holding(t, labels_png(w, t)) / "labels.png"), "--force"), "old"),
    ("render", "albedo of one channel", lambda w, t: _render(
        w.scene, w.brdf, _out(t), "--albedo", str(one_channel_exr(t))), "albedo.exr"),
    ("run", "materials abc", lambda w, t: _run(w.scene, _out(t), "--materials", "abc"),
     "--materials"),
    ("run", "spp 10**11 (out of memory)", lambda w, t: _run(w.scene, _out(t)) + [
        "--spp", str(10 ** 11)], "--spp"),
    ("run", "spp not a number (argparse, one line)", lambda w, t: _run(w.scene, _out(t)) + [
        "--spp", "x"], "--spp"),
    ("batch", "empty folder", lambda w, t: _batch(empty(t), _out(t)), "empty"),
    ("batch", "out empty", lambda w, t: _batch(captures(w, t, "a"), ""), "--out"),
    ("batch", "workers abc", lambda w, t: _batch(captures(w, t, "a"), _out(t), "--workers",
                                                 "abc"), "--workers"),
    ("batch", "materials 0", lambda w, t: _batch(captures(w, t, "a"), _out(t), "--materials",
                                                 "0"), "--materials"),
    ("batch", "scheduler with nothing listening", lambda w, t: _batch(
        captures(w, t, "a"), _out(t), "--scheduler", "tcp://127.0.0.1:1"), "--scheduler"),
    ("batch", "scheduler empty", lambda w, t: _batch(captures(w, t, "a"), _out(t),
                                                     "--scheduler", ""), "--scheduler"),
    ("batch", "out is someone's folder", lambda w, t: _batch(captures(w, t, "a"), user_folder(t)),
     "mine"),
    ("batch", "model truncated", lambda w, t: _batch(captures(w, t, "a"), _out(t), "--methods",
                                                     "pca", "--model", str(write(
                                                         t, "m.npz", truncated(w.model, 0.7)))),
     "m.npz"),
    ("batch", "out holds someone's summary.md", lambda w, t: _batch(
        captures(w, t, "a"), write(empty(t), "summary.md", "my notes").parent), "empty"),
    ("batch", "a capture named logs", lambda w, t: _batch(captures(w, t, "logs"), _out(t)),
     "logs"),
    ("train", "three tables (a fifth is held out)", lambda w, t: [
        "train", "--merl-dir", str(w.merl_dir), "--out", _out(t, "m.npz")], "merl"),
    ("train", "the same folder twice", lambda w, t: [
        "train", "--merl-dir", str(w.merl_dir), "--merl-dir", str(w.merl_dir) + os.sep, "--out",
        _out(t, "m.npz")], "given twice"),
    ("evaluate", "test-dir with --workers and --scheduler", lambda w, t: [
        "evaluate", "--merl-dir", str(w.merl_dir), "--test-dir", str(w.merl_dir), "--out",
        _out(t), "--workers", "2", "--scheduler", "tcp://127.0.0.1:1"], "--workers"),
    ("evaluate", "experiments 0", lambda w, t: ["evaluate", "--merl-dir", str(w.merl_dir),
                                                "--out", _out(t), "--experiments", "0"],
     "--experiments"),
    # a local cluster of 100000 processes (it forked until the machine gave out)
    ("evaluate", "workers 100000", lambda w, t: [
        "evaluate", "--merl-dir", str(w.merl_dir), "--out", _out(t), "--workers", "100000"],
     "--workers"),
    ("batch", "workers 100000", lambda w, t: _batch(captures(w, t, "a", "b"), _out(t),
                                                    "--workers", "100000"), "--workers"),
    ("train", "seed -1 (a traceback from numpy)", lambda w, t: [
        "train", "--merl-dir", str(merl_copy(w, t)), "--merl-dir", str(write(empty(t),
        "x.binary", w.brdf.read_bytes()[:12] + np.full(90 * 90 * 180 * 3, 0.01).tobytes()
        ).parent), "--out", _out(t, "m.npz"), "--seed=-1"], "--seed"),
    ("evaluate", "experiments 10**9 (it hung drawing the splits)", lambda w, t: [
        "evaluate", "--merl-dir", str(w.merl_dir), "--out", _out(t), "--experiments",
        str(10 ** 9)], "--experiments"),
    # outputs no file can be made at (tracebacks from mkstemp / mkdtemp)
    ("merl-slice", "out in /proc", lambda w, t: ["merl-slice", str(w.brdf), "--out",
                                                "/proc/flashbrdf-s.csv"], "/proc/flashbrdf-s.csv"),
    ("merl-slice", "out a name of 300 bytes", lambda w, t: [
        "merl-slice", str(w.brdf), "--out", str(t / ("a" * 300 + ".csv"))], "a" * 40),
    ("compare", "out a name of 300 bytes", lambda w, t: [
        "compare", str(w.pred), str(w.ref), "--out", str(t / ("a" * 300))], "a" * 40),
    ("render", "out in /proc", lambda w, t: _render(w.scene, w.brdf, "/proc/flashbrdf-out"),
     "/proc/flashbrdf-out"),
    # damaged model hyperparameters (tracebacks)
    ("infer", "model params of pca not an object", lambda w, t: [
        "infer", "--method", "pca", "--model", str(model_with_params(w, t, {"pca": "x"})),
        "--slice", str(w.slice), "--out", _out(t, "b.binary")], "model.npz"),
    ("infer", "model params with an unknown hyperparameter", lambda w, t: [
        "infer", "--method", "noll", "--model", str(model_with_params(w, t, {"noll": {"k": 1}})),
        "--slice", str(w.slice), "--out", _out(t, "b.binary")], "model.npz"),
    ("infer", "model slices of inf (noll: a traceback)", lambda w, t: [
        "infer", "--method", "noll", "--model", str(model_edited(
            w, t, "slices", lambda a: np.full_like(a, np.inf))), "--slice", str(w.slice),
        "--out", _out(t, "b.binary")], "model.npz"),
    ("infer", "model tables_2d all NaN (a table of NaN, exit 0)", lambda w, t: [
        "infer", "--method", "pca", "--model", str(model_edited(
            w, t, "tables_2d", lambda a: np.full_like(a, np.nan))), "--slice", str(w.slice),
        "--out", _out(t, "b.binary")], "model.npz"),
    # one table under several names (train: a LinAlgError traceback)
    ("train", "five links to one table", lambda w, t: [
        "train", "--merl-dir", str(links_to(empty(t), w.brdf, 5)), "--out", _out(t, "m.npz")],
     "t1.binary"),
    ("train", "a table with no data at theta_d = 0 (a LinAlgError traceback)", lambda w, t: [
        "train", "--merl-dir", str(w.merl_dir), "--merl-dir",
        str(write(empty(t), "m.binary", merl_body(w, no_theta_d_0)).parent), "--out",
        _out(t, "m.npz")], "m.binary"),
    ("merl-slice", "no data at theta_d = 0 (an empty slice, exit 0)", lambda w, t: [
        "merl-slice", str(write(t, "m.binary", merl_body(w, no_theta_d_0))), "--out",
        _out(t, "s.csv")], "m.binary"),
    # compare over no pixel (every metric null, exit 0)
    ("compare", "both images black", lambda w, t: [
        "compare", str(rgb_exr(t, value=0.0)), str(rgb_exr(t, "r.exr", value=0.0)), "--out",
        _out(t)], "r.exr"),
    ("compare", "mask of no pixel", lambda w, t: [
        "compare", str(w.pred), str(w.ref), "--mask", str(black_png(t)), "--out", _out(t)],
     "m.png"),
    # factors that turned float32 photos and rays to 0 or inf (a slice of zeros, exit 0)
    ("extract", "photos[0].scale 1e308", lambda w, t: ["extract", str(scene_copy(
        w, t, set_field(("photos", 0, "scale"), 1e308))), "--out", _out(t, "s.csv")],
     "photos[0].scale"),
    ("extract", "intensity_rgb 1e308", lambda w, t: ["extract", str(scene_copy(
        w, t, set_field(("photos", 0, "light", "intensity_rgb"), [1e308] * 3))), "--out",
        _out(t, "s.csv")], "photos[0].light.intensity_rgb"),
    ("extract", "exposure_s 1e-320", lambda w, t: ["extract", str(scene_copy(
        w, t, lambda d: d["photos"][0].update(file=None, brackets=[
            {"file": "flash0.exr", "exposure_s": 1e-320}]))), "--out", _out(t, "s.csv")],
     "photos[0].brackets[0].exposure_s"),
    ("extract", "camera.fx 1e308 (overflow warnings, exit 0)", lambda w, t: ["extract", str(
        scene_copy(w, t, set_field(("camera", "fx"), 1e308))), "--out", _out(t, "s.csv")],
     "camera.fx"),
    ("render", "envmap scale 1e308 (a render of inf)", lambda w, t: _render(scene_copy(
        w, t, lambda d: d["photos"][1]["light"].__setitem__("scale", 1e308)), w.brdf, _out(t)),
     "photos[1].light.scale"),
    ("extract", "flash photo of 3e38 (a slice infer refuses)", lambda w, t: ["extract", str(
        scene_with_file(w, t, "flash0.exr", rgb_exr(t, value=3e38).read_bytes())), "--out",
        _out(t, "s.csv")], "photos"),
    ("extract", "--labels, flash photo of 3e38 (empty slices, exit 0)", lambda w, t: [
        "extract", str(scene_with_file(w, t, "flash0.exr", rgb_exr(t, value=3e38).read_bytes())),
        "--labels", str(labels_png(w, t)), "--out", _out(t)], "photos"),
    ("extract", "intensity_rgb [true, 1, 1] (read as 1)", lambda w, t: ["extract", str(
        scene_copy(w, t, set_field(("photos", 0, "light", "intensity_rgb"), [True, 1, 1]))),
        "--out", _out(t, "s.csv")], "photos[0].light.intensity_rgb"),
    ("extract", "world_from_camera with true on its diagonal", lambda w, t: ["extract", str(
        scene_copy(w, t, set_field(("camera", "world_from_camera"), [
            [True, 0, 0, 0], [0, True, 0, 0], [0, 0, True, 0], [0, 0, 0, True]]))), "--out",
        _out(t, "s.csv")], "camera.world_from_camera"),
]
CASES += SWEEP_CASES


def link(path, target):
    path.symlink_to(target)
    return path


def empty(tmp):
    folder = tmp / "empty"
    folder.mkdir()
    return folder


def nan_slice(w):
    lines = w.slice.read_text().splitlines(True)
    k = next(i for i, line in enumerate(lines) if line[0].isdigit() and ",," not in line)
    fields = lines[k].split(",")
    fields[1] = "nan"
    lines[k] = ",".join(fields)
    return "".join(lines)


def slice_n(w, count, empty_bin=False):
    """The world's slice with `count` as n of its first filled bin (or its first bin, emptied)."""
    lines = w.slice.read_text().splitlines(True)
    k = next(i for i, line in enumerate(lines) if line[0].isdigit())
    fields = lines[k].rstrip("\n").split(",")
    if empty_bin:
        fields[1:4] = ["", "", ""]
    lines[k] = ",".join(fields[:4] + [count]) + "\n"
    return "".join(lines)


def flipped_byte(path):
    data = bytearray(Path(path).read_bytes())
    data[len(data) // 2] ^= 0xFF
    return bytes(data)


def test_corpus_size_and_spread():
    """The issue asks for >= 60 cases over every command."""
    by_command = {}
    for command, *_ in CASES:
        by_command[command] = by_command.get(command, 0) + 1
    assert len(CASES) >= 60 and len({name for _, name, *_ in CASES}) > 50
    assert set(by_command) == {"merl-slice", "extract", "infer", "train", "render", "compare",
                               "run", "evaluate", "import-diligent", "segment", "batch",
                               "export"}


@pytest.mark.parametrize("command,name,argv,names", CASES,
                         ids=[f"{c}: {n}" for c, n, *_ in CASES])
def test_bad_input_exits_2_cleanly(world, tmp_path, capfd, command, name, argv, names):
    args = argv(world, tmp_path)  # builds the broken inputs: part of the "before"
    assert args[0] == command
    roots = (world.base, tmp_path, world.proxy_dir)
    before = snapshot(*roots)
    capfd.readouterr()
    status = main([str(a) for a in args])
    err = capfd.readouterr().err
    lines = err.strip().splitlines()
    assert status == 2, err
    assert len(lines) == 1, err
    assert (str(tmp_path) if names == HERE else names) in lines[0], lines[0]
    assert snapshot(*roots) == before


def test_segment_keeps_no_albedo_map_when_its_labels_fail(world, tmp_path, capfd, monkeypatch):
    """segment --albedo writes the albedo map, then the labels: when the labels fail, the map
    already written is removed (all or nothing over both)."""
    from flashbrdf.files.errors import InputError

    def fail(out, *args, **kwargs):
        raise InputError(out, "cannot write a PNG there")
    monkeypatch.setattr("flashbrdf.pipeline.capture_jobs.write_labels", fail)
    assert main(["segment", str(world.scene), "--out", str(tmp_path / "l.png"), "--albedo",
                 str(tmp_path / "a.exr")]) == 2
    assert len(capfd.readouterr().err.strip().splitlines()) == 1
    assert list(tmp_path.iterdir()) == []


# ----- valid controls: the same harness passes good input -------------------------------------
CONTROLS = [
    ("merl-slice", lambda w, t: ["merl-slice", str(w.brdf), "--out", _out(t, "s.csv")],
     lambda w, t: [t / "s.csv"]),
    ("extract", lambda w, t: ["extract", str(w.scene), "--out", str(t / "s.csv")],
     lambda w, t: [t / "s.csv", t / "s.json"]),
    ("infer", lambda w, t: ["infer", "--method", "chandraker", "--slice", str(w.slice),
                            "--out", str(t / "b.binary")],
     lambda w, t: [t / "b.binary", t / "b.json"]),
    ("render", lambda w, t: _render(w.scene, w.brdf, t / "r"),
     lambda w, t: [t / "r" / "ref_env.exr", t / "r" / "ref_env_compare.json", t / "r" / MARKER]),
    ("compare", lambda w, t: ["compare", str(w.pred), str(w.ref), "--out", str(t / "c")],
     lambda w, t: [t / "c" / "compare.json"]),
    # a new subfolder inside the capture folder is allowed
    ("run", lambda w, t: _run(w.scene, w.scene / "out"),
     lambda w, t: [w.scene / "out" / "report.json", w.scene / "out" / "chandraker" /
                   "ref_env_compare.json"]),
    # a byte-order mark before scene.json's text (Windows editors write one)
    ("extract", lambda w, t: ["extract", str(scene_with_file(
        w, t, "scene.json", b"\xef\xbb\xbf" + (w.scene / "scene.json").read_bytes())), "--out",
        str(t / "s.csv")], lambda w, t: [t / "s.csv", t / "s.json"]),
    ("import-diligent", lambda w, t: ["import-diligent", str(diligent_copy(w, t, png8_all)),
                                      "--flash", "1", "--out", str(t / "s")],
     lambda w, t: [t / "s" / "scene.json", t / "s" / "001.exr"]),
]


def png8_all(folder):
    import cv2
    for path in folder.glob("0*.png"):
        png16 = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        cv2.imwrite(str(path), (png16 // 257).astype(np.uint8))


@pytest.mark.parametrize("command,argv,outputs", CONTROLS, ids=[c for c, *_ in CONTROLS])
def test_valid_control_exits_0_and_keeps_inputs(world, tmp_path, capfd, command, argv,
                                                 outputs):
    args = argv(world, tmp_path)
    roots = (world.base, tmp_path, world.proxy_dir)
    before = snapshot(*roots)
    try:
        status = main([str(a) for a in args])
        err = capfd.readouterr().err
        assert status == 0, err
        after = snapshot(*roots)
        assert {k: after.get(k) for k in before} == before  # every input unchanged
        for path in outputs(world, tmp_path):
            assert path.is_file(), path
        assert not [p for p in after if p not in before and ".part" in p]
        # nothing written names the temporary folder it was built in
        texts = [p for p in after if p not in before and p.endswith((".json", ".md", ".csv"))]
        assert texts and not [p for p in texts if ".part" in Path(p).read_text()]
    finally:
        shutil.rmtree(world.scene / "out", ignore_errors=True)  # keep the world as it was
