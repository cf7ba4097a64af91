"""Property tests (hypothesis) for import-colmap's readers: whatever a COLMAP text model holds,
reading it (pycolmap, then our checks) and importing it gives a result or an InputError with
one line naming a file or field, never another exception (a traceback at the command line).

Also the scene.json that import-colmap writes, damaged as text or with any value in a
per-photo camera's fields (test_parser_properties.py covers the top-level fields and slice.csv).
"""

import json
import shutil

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from colmap_synthetic import make_colmap_capture
from flashbrdf.files.errors import InputError
from flashbrdf.capture import load_scene
from flashbrdf.capture.importers.colmap import import_colmap
from flashbrdf.capture.importers.colmap_model import read_colmap_model

pytest.importorskip("pycolmap")

FILES = ["cameras.txt", "images.txt", "points3D.txt", "rigs.txt", "frames.txt"]
TOKENS = st.sampled_from(["nan", "inf", "-inf", "1e308", "-1", "0", "-0", "2", "1.5",
                          "99999999999999999999", "", "x", "#", "OPENCV", "FULL_OPENCV",
                          "SIMPLE_PINHOLE", "PINHOLE", "FOV", "CAMERA", "1", "3"]) | \
    st.integers(-5, 10 ** 6).map(str) | st.floats().map(repr) | \
    st.text(alphabet=st.sampled_from(list("0123456789.-+eE #x\t")), max_size=6)


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    return make_colmap_capture(tmp_path_factory.mktemp("fuzz_world"), views=3, points=60)


def _damage(text, data):
    """A random edit of a model file's text: a token replaced, a line removed, repeated, cut,
    swapped with another or replaced by junk, or the file cut anywhere."""
    lines = text.splitlines(True) or ["\n"]
    how = data.draw(st.sampled_from(["token", "token", "token", "drop", "repeat", "junk",
                                     "swap", "cut"]))
    k = data.draw(st.integers(0, len(lines) - 1))
    if how == "token":
        words = lines[k].split() or [""]
        words[data.draw(st.integers(0, len(words) - 1))] = data.draw(TOKENS)
        lines[k] = " ".join(words) + "\n"
    elif how == "drop":
        del lines[k]
    elif how == "repeat":
        lines.insert(k, lines[k])
    elif how == "junk":
        lines[k] = " ".join(data.draw(st.lists(TOKENS, max_size=12))) + "\n"
    elif how == "swap":
        j = data.draw(st.integers(0, len(lines) - 1))
        lines[k], lines[j] = lines[j], lines[k]
    else:
        text = "".join(lines)
        return text[:data.draw(st.integers(0, len(text)))]
    return "".join(lines)


def _one_line_naming(err, folder):
    text = str(err)
    assert "\n" not in text, text
    assert str(folder) in text or text.startswith("--"), text


@settings(deadline=None, max_examples=300,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_any_damage_to_a_text_model(world, tmp_path_factory, data):
    folder = tmp_path_factory.mktemp("m") / "model"
    shutil.copytree(world["sparse"], folder)
    for _ in range(data.draw(st.integers(1, 3))):
        name = data.draw(st.sampled_from(FILES))
        path = folder / name
        path.write_text(_damage(path.read_text(), data))
    try:
        model = read_colmap_model(folder)
        for image in model.images:
            model.contract_camera(image.camera_id, image.world_from_camera)
        points, observed, observers = model.sight_lines()
    except InputError as err:
        _one_line_naming(err, folder)
        return
    assert all(np.all(np.isfinite(im.world_from_camera)) for im in model.images)
    assert np.all(np.isfinite(points)) and len(observed) == len(observers)


@settings(deadline=None, max_examples=40,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_any_damage_then_the_whole_import(world, tmp_path_factory, data):
    """The same damage through import_colmap: photos matched and measured, the mesh checked,
    scene.json written and loadable."""
    base = tmp_path_factory.mktemp("i")
    folder = base / "model"
    shutil.copytree(world["sparse"], folder)
    name = data.draw(st.sampled_from(FILES))
    (folder / name).write_text(_damage((folder / name).read_text(), data))
    try:
        import_colmap(folder, world["images"], world["mesh"], base / "scene")
    except InputError as err:
        text = str(err)
        assert "\n" not in text and (str(base) in text or str(world["out"]) in text), text
        assert not (base / "scene").exists()
        return
    scene = load_scene(base / "scene")
    assert scene.photos and all(p.camera.width > 0 for p in scene.photos)


@pytest.fixture(scope="module")
def imported(world, tmp_path_factory):
    out = tmp_path_factory.mktemp("imported") / "scene"
    import_colmap(world["sparse"], world["images"], world["mesh"], out)
    return out


@settings(deadline=None, max_examples=150,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_any_text_damage_to_an_imported_scene_json(imported, tmp_path_factory, data):
    text = (imported / "scene.json").read_text()
    how = data.draw(st.sampled_from(["cut", "insert", "flip"]))
    k = data.draw(st.integers(0, len(text)))
    if how == "cut":
        text = text[:k]
    elif how == "insert":
        text = text[:k] + data.draw(st.text(max_size=6)) + text[k:]
    else:
        k = min(k, len(text) - 1)
        text = text[:k] + chr((ord(text[k]) + data.draw(st.integers(1, 90))) % 0x2FFF) + \
            text[k + 1:]
    folder = tmp_path_factory.mktemp("j")
    (folder / "scene.json").write_text(text, encoding="utf-8", errors="surrogatepass")
    try:
        scene = load_scene(folder)
    except InputError as err:
        assert "\n" not in str(err) and "scene.json" in str(err), str(err)
        return
    assert all(np.all(np.isfinite(p.camera.world_from_camera)) for p in scene.photos)


CAMERA_FIELDS = ["fx", "fy", "cx", "cy", "width", "height", "distortion", "world_from_camera",
                 "model"]
VALUES = st.sampled_from([float("nan"), float("inf"), 1e308, 0, -1, 0.5, "", [], {}, True, None,
                          [0.1] * 4, [0.1] * 5, [0.1] * 8, [0.1] * 6, [[1, 0], [0, 1]],
                          np.eye(4).tolist(), (2 * np.eye(4)).tolist(), "orthographic"])


@settings(deadline=None, max_examples=150,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(field=st.sampled_from(CAMERA_FIELDS), value=VALUES, photo=st.integers(0, 2))
def test_any_value_in_a_photos_camera(imported, tmp_path_factory, field, value, photo):
    doc = json.loads((imported / "scene.json").read_text())
    doc["photos"][photo]["camera"][field] = value
    folder = tmp_path_factory.mktemp("k")
    (folder / "scene.json").write_text(json.dumps(doc))
    try:
        scene = load_scene(folder)
    except InputError as err:
        assert "\n" not in str(err) and f"photos[{photo}].camera" in str(err), str(err)
        return
    cam = scene.photos[photo].camera
    assert cam.width >= 1 and np.all(np.isfinite(cam.world_from_camera))


@settings(deadline=None, max_examples=15,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(name=st.sampled_from(["cameras.bin", "images.bin", "points3D.bin", "rigs.bin",
                             "frames.bin"]),
       cut=st.floats(0.0, 0.999), flips=st.lists(st.tuples(st.floats(0.0, 0.999),
                                                           st.integers(0, 255)), max_size=4))
def test_any_cut_or_flipped_binary_model(world, tmp_path_factory, monkeypatch, name, cut, flips):
    """Binary files cut or with bytes changed: a result or an InputError naming the model,
    never a hang or a crash (the child-process read, with its limit at 3 s here)."""
    monkeypatch.setattr("flashbrdf.capture.importers.colmap_model.READ_TIMEOUT_S", 3.0)
    folder = tmp_path_factory.mktemp("b") / "model"
    shutil.copytree(world["sparse_bin"], folder)
    data = bytearray((folder / name).read_bytes())
    for where, value in flips:
        data[int(where * len(data))] = value
    if not flips:
        data = data[:int(cut * len(data))]
    (folder / name).write_bytes(bytes(data))
    try:
        model = read_colmap_model(folder)
    except InputError as err:
        _one_line_naming(err, folder)
        return
    assert all(np.all(np.isfinite(im.world_from_camera)) for im in model.images)
