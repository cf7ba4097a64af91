"""A corpus of bad inputs for every command: each must exit 2 with one stderr line naming the file
or field, leave no new file anywhere, and leave every input byte-identical.

The world (a tiny 40x40 sphere capture with a flash photo and an envmap-lit reference, one MERL
(NBRDF proxy) table, its slice, two EXRs, a DiLiGenT folder, a folder of three MERL tables and
the shipped model) is built once; a case that needs a broken file breaks a copy in its own
tmp_path. Before and after each case every file under the world, the case's tmp_path and the
proxy tables is hashed (sha256; symlinks by their target text): a new file, a removed file, a
temporary folder left behind or a changed byte fails the case. The valid controls at the end run
the same commands on good input (exit 0), so a harness that passes everything would fail them.
The cases are in corpus_cases.py and corpus_sweep_cases.py, the helpers that break a copy of the
world in corpus_inputs.py.
"""

import hashlib
import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest
from corpus_cases import CASES
from corpus_inputs import (
    ENVMAP,
    HERE,
    TABLES,
    World,
    diligent_copy,
    out_path,
    png8_all,
    render_argv,
    run_argv,
    scene_with_file,
)
from corpus_sweep_cases import SWEEP_CASES
from synthetic import ggx_lambert, pinhole_camera, point_light, sphere_mesh, write_synthetic_scene
from test_diligent_import import make_diligent

from flashbrdf.cli.main import main
from flashbrdf.files.outputs import MARKER
from flashbrdf.pipeline.options import DEFAULT_MODEL


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


CASES = CASES + SWEEP_CASES


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
    ("merl-slice", lambda w, t: ["merl-slice", str(w.brdf), "--out", out_path(t, "s.csv")],
     lambda w, t: [t / "s.csv"]),
    ("extract", lambda w, t: ["extract", str(w.scene), "--out", str(t / "s.csv")],
     lambda w, t: [t / "s.csv", t / "s.json"]),
    ("infer", lambda w, t: ["infer", "--method", "chandraker", "--slice", str(w.slice),
                            "--out", str(t / "b.binary")],
     lambda w, t: [t / "b.binary", t / "b.json"]),
    ("render", lambda w, t: render_argv(w.scene, w.brdf, t / "r"),
     lambda w, t: [t / "r" / "ref_env.exr", t / "r" / "ref_env_compare.json", t / "r" / MARKER]),
    ("compare", lambda w, t: ["compare", str(w.pred), str(w.ref), "--out", str(t / "c")],
     lambda w, t: [t / "c" / "compare.json"]),
    # a new subfolder inside the capture folder is allowed
    ("run", lambda w, t: run_argv(w.scene, w.scene / "out"),
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
