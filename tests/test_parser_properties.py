"""Property tests (hypothesis) for the readers of user files: whatever the bytes, a reader returns
a valid result or raises InputError with one line naming the file (or field) - never another
exception, which the CLI would show as a traceback.

The corpus (test_bad_input_corpus.py) lists the bad inputs we thought of; these generate the
ones we did not: any JSON value in any scene.json field, any damage to a slice.csv, any MERL
header, any cut or flipped byte of a model file.
"""

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from flashbrdf.files.errors import InputError
from flashbrdf.brdf.merl import MERL_FILE_SIZE, MERL_SHAPE, read_merl
from flashbrdf.brdf.views import read_slice_csv, write_slice_csv
from flashbrdf.capture import load_scene
from flashbrdf.pipeline.options import DEFAULT_MODEL

SETTINGS = settings(deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])

# Values that broke readers before (NaN, Infinity, huge numbers), weighted up: hypothesis would
# otherwise rarely put one in the one field that mishandles it.
SPECIAL = st.sampled_from([float("nan"), float("inf"), -float("inf"), 1e308, -1e-308, 10 ** 30,
                           0, -1, 0.5, "", "\0", [], {}, True, None, [[1, 2], [3]]])
JSON_VALUES = SPECIAL | st.recursive(
    SPECIAL | st.booleans() | st.integers() | st.floats() | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=5) | st.dictionaries(st.text(max_size=6), inner,
                                                                 max_size=4),
    max_leaves=12)

VALID_SCENE = {
    "camera": {"model": "pinhole", "width": 8, "height": 6, "fx": 10.0, "fy": 10.0, "cx": 3.5,
               "cy": 2.5, "world_from_camera": np.eye(4).tolist(), "distortion": [0, 0, 0, 0, 0]},
    "geometry": {"mesh": "object.ply"},
    "level": {"target": {"mesh": "card.ply", "reflectance": [0.18, 0.18, 0.18]}},
    "photos": [
        {"file": "flash.exr", "role": "flash", "scale": 2.0,
         "light": {"type": "point", "position": [0.01, 0, 0], "intensity_rgb": [1, 1, 1]}},
        {"brackets": [{"file": "a.exr", "exposure_s": 0.01}], "role": "ambient"},
        {"file": "ref.exr", "role": "reference", "encoding": "linear", "saturation": 4.0,
         "light": {"type": "envmap", "file": "env.hdr", "world_from_envmap": np.eye(3).tolist(),
                   "scale": 1.0}},
        {"file": "sun.exr", "role": "reference",
         "light": {"type": "directional", "direction": [0, 0, -1], "irradiance_rgb": [1, 1, 1]}},
    ],
}
FIELDS = [("camera",), ("camera", "model"), ("camera", "width"), ("camera", "height"),
          ("camera", "fx"), ("camera", "cx"), ("camera", "world_from_camera"),
          ("camera", "distortion"), ("camera", "pixel_size"), ("geometry",), ("geometry", "mesh"),
          ("geometry", "normal_map"), ("photos",), ("photos", 0), ("photos", 0, "file"),
          ("photos", 0, "role"), ("photos", 0, "scale"), ("photos", 0, "light"),
          ("photos", 0, "light", "type"), ("photos", 0, "light", "position"),
          ("photos", 0, "light", "intensity_rgb"), ("photos", 1, "brackets"),
          ("photos", 1, "brackets", 0, "exposure_s"), ("photos", 2, "encoding"),
          ("photos", 2, "saturation"), ("photos", 2, "camera"),
          ("photos", 2, "light", "world_from_envmap"), ("photos", 2, "light", "scale"),
          ("photos", 2, "light", "file"), ("photos", 3, "light", "direction"),
          ("photos", 3, "light", "irradiance_rgb"), ("level",), ("level", "target"),
          ("level", "target", "mesh"), ("level", "target", "reflectance"), ("level", "calibrated")]


def _scene_with(tmp_path, field, value):
    doc = json.loads(json.dumps(VALID_SCENE))
    target = doc
    for key in field[:-1]:
        target = target[key]
    target[field[-1]] = value
    (tmp_path / "scene.json").write_text(json.dumps(doc))
    return tmp_path


def _one_line_naming(err, name):
    text = str(err)
    assert "\n" not in text and name in text, text


@settings(deadline=None, max_examples=400,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(field=st.sampled_from(FIELDS), value=JSON_VALUES)
def test_any_value_in_any_scene_field(tmp_path, field, value):
    # json.dumps allows NaN: NaN / Infinity reach the reader as Python writes them
    try:
        scene = load_scene(_scene_with(tmp_path, field, value))
    except InputError as err:
        _one_line_naming(err, "scene.json")
        return
    assert scene.camera.width >= 1 and np.all(np.isfinite(scene.camera.world_from_camera))


def _pose(centre_x, rotation_xx=1.0):
    return [[rotation_xx, 0, 0, centre_x], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]


@pytest.mark.parametrize("field, value, named", [
    (("camera", "world_from_camera"), _pose(1e31), r"camera\.world_from_camera: 1e\+31 is beyond"),
    (("camera", "world_from_camera"), _pose(0, 1e308), r"camera\.world_from_camera: rotation"),
    (("camera", "cx"), 1e308, r"camera\.cx: 1e\+308 is beyond"),
    (("camera", "fx"), 1e-30, r"camera\.cx: 3\.5 with a focal length of 1e-30 px puts ray slopes"),
    (("photos", 0, "light", "position"), [0, -1e31, 0], r"photos\[0\]\.light\.position: -1e\+31"),
])
def test_coordinates_past_float32_rays_are_named(tmp_path, field, value, named):
    """A camera centre, principal point or light position past ±1e30, a principal point whose
    ray slopes pass it (rays and pixel coordinates are float32: they would turn to inf), or a
    rotation entry of 1e308 (whose square overflows) is bad input naming the field."""
    with pytest.raises(InputError, match=named):
        load_scene(_scene_with(tmp_path, field, value))


def test_far_cameras_and_huge_directions_load(tmp_path):
    """A camera 1e29 away loads; a directional light's direction of 1e200 entries is normalised
    (its squares would overflow)."""
    scene = load_scene(_scene_with(tmp_path, ("camera", "world_from_camera"), _pose(1e29)))
    assert scene.camera.centre_world[0] == 1e29
    scene = load_scene(_scene_with(tmp_path, ("photos", 3, "light", "direction"),
                                   [1e200, 1e200, 0]))
    assert np.allclose(scene.photos[3].light.direction, [0.5 ** 0.5, 0.5 ** 0.5, 0])


def test_the_valid_scene_loads(tmp_path):
    """The base document of the property above is valid, so the property tests changes to it."""
    (tmp_path / "scene.json").write_text(json.dumps(VALID_SCENE))
    scene = load_scene(tmp_path)
    assert [p.role for p in scene.photos] == ["flash", "ambient", "reference", "reference"]


@pytest.fixture(scope="module")
def slice_text(tmp_path_factory):
    path = tmp_path_factory.mktemp("slice") / "s.csv"
    rho = np.linspace(0.01, 3.0, 270).reshape(90, 3)
    rho[:5] = np.nan
    write_slice_csv(path, rho, np.arange(90) % 7, comments=["a comment"])
    return path.read_text()


@SETTINGS
@given(data=st.data())
def test_any_damage_to_a_slice_csv(tmp_path, slice_text, data):
    lines = slice_text.splitlines(True)
    how = data.draw(st.sampled_from(["replace", "cut", "insert"]))
    k = data.draw(st.integers(0, len(lines) - 1))
    junk = data.draw(st.text(alphabet=st.sampled_from(list("0123456789.,-+eEnaNIfity #\"\n")),
                             max_size=30))
    if how == "replace":
        lines[k] = junk
    elif how == "insert":
        lines.insert(k, junk)
    text = "".join(lines)
    if how == "cut":
        text = text[:data.draw(st.integers(0, len(text)))]
    path = tmp_path / "s.csv"
    path.write_text(text)
    try:
        rho, n = read_slice_csv(path)
    except InputError as err:
        _one_line_naming(err, "s.csv")
        return
    assert rho.shape == (90, 3) and n.shape == (90,) and np.all(np.nan_to_num(rho) >= 0)


@pytest.fixture(scope="module")
def merl_body():
    return np.full(MERL_FILE_SIZE - 12, 0, np.uint8).tobytes()


@settings(deadline=None, max_examples=12,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(header=st.tuples(*[st.integers(-2 ** 31, 2 ** 31 - 1)] * 3), extra=st.integers(-16, 16))
def test_any_merl_header_or_size(tmp_path, merl_body, header, extra):
    path = tmp_path / "m.binary"
    body = merl_body[:len(merl_body) + extra] if extra < 0 else merl_body + b"\0" * extra
    path.write_bytes(np.array(header, "<i4").tobytes() + body)
    try:
        table = read_merl(path)
    except InputError as err:
        _one_line_naming(err, "m.binary")
        assert tuple(header) != MERL_SHAPE or extra != 0
        return
    assert tuple(header) == MERL_SHAPE and extra == 0 and table.shape == MERL_SHAPE + (3,)


@settings(deadline=None, max_examples=10,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(cut=st.floats(0.0, 0.999), flip=st.one_of(st.none(), st.floats(0.0, 0.999)))
def test_any_cut_or_flipped_model(tmp_path, cut, flip):
    from flashbrdf.infer.model_file import check_model_file, read_model
    data = bytearray(Path(DEFAULT_MODEL).read_bytes())
    if flip is not None:
        data[int(flip * len(data))] ^= 0x5A
    else:
        data = data[:int(cut * len(data))]
    path = tmp_path / "m.npz"
    path.write_bytes(bytes(data))
    try:
        check_model_file(path)
        read_model(path)
    except InputError as err:
        _one_line_naming(err, "m.npz")
