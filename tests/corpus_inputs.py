"""Broken inputs for the bad-input corpus (tests/test_bad_input_corpus.py): the world every
case starts from, and the helpers that break a copy of it in a case's tmp_path."""

import json
import os
import shutil
import zipfile
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from synthetic import ggx_lambert, pinhole_camera, point_light, sphere_mesh, write_synthetic_scene

from flashbrdf.files.outputs import MARKER

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


def out_path(tmp, name="out"):
    return str(tmp / name)


def run_argv(scene, out, *extra):
    return ["run", str(scene), "--out", str(out), "--methods", "chandraker", "--spp", "2", *extra]


def render_argv(scene, brdf, out, *extra):
    return ["render", str(scene), "--brdf", str(brdf), "--out", str(out), "--spp", "2", *extra]



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


def model_with_param(w, tmp, method, key, value):
    """A copy of the shipped model whose params[method][key] is `value`, the rest as stored."""
    with np.load(w.model, allow_pickle=False) as z:
        params = json.loads(str(z["params"]))
    params[method][key] = value
    return model_with_params(w, tmp, params)


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


def batch_argv(folder, out, *extra):
    return ["batch", str(folder), "--out", str(out), "--methods", "chandraker", "--spp", "2",
            *extra]


def two_tables(w):
    return f"{w.brdf},{w.merl_dir / f'{TABLES[1]}.binary'}"


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


def png8_all(folder):
    import cv2
    for path in folder.glob("0*.png"):
        png16 = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        cv2.imwrite(str(path), (png16 // 257).astype(np.uint8))

