"""files.outputs: outputs never touch inputs, folder outputs appear whole or not at all, --force
replaces only folders flashbrdf made, Ctrl-C / SIGTERM leave nothing, concurrent runs keep apart.
"""

import json
import os
import shutil
import signal
import stat
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from flashbrdf.cli.main import main
from flashbrdf.files.errors import InputError
from flashbrdf.files.outputs import MARKER, check_outputs, staged_output_dir
from test_bad_input_corpus import snapshot, world  # noqa: F401  (the corpus's tiny capture)

REPO = Path(__file__).resolve().parents[1]


def test_check_outputs_sees_through_symlinks_and_hard_links(tmp_path):
    data = tmp_path / "data"
    data.mkdir()
    table = data / "t.binary"
    table.write_bytes(b"x")
    (tmp_path / "alias").symlink_to(data)
    os.link(table, tmp_path / "hard.binary")
    for out in (tmp_path / "alias" / "t.binary", tmp_path / "hard.binary"):
        with pytest.raises(InputError, match="is an input"):
            check_outputs(inputs=[table], outputs=[out])
    # a folder output that holds an input, seen through the link
    with pytest.raises(InputError, match="contains an input"):
        check_outputs(inputs=[tmp_path / "alias" / "t.binary"], outputs=[data], folders=[data])
    # a new file or subfolder inside an input folder is fine
    check_outputs(inputs=[data, table], outputs=[data / "new.csv", data / "sub"],
                  folders=[data / "sub"])


def test_staged_output_dir_is_all_or_nothing_and_force_replaces_only_its_own(tmp_path):
    out = tmp_path / "out"
    with pytest.raises(RuntimeError):
        with staged_output_dir(out) as tmp:
            (Path(tmp) / "half.txt").write_text("half")
            raise RuntimeError("a bug part-way")
    assert sorted(os.listdir(tmp_path)) == []  # neither the output nor its temporary sibling
    with staged_output_dir(out, command="test") as tmp:
        (Path(tmp) / "a.txt").write_text("first")
    assert json.loads((out / MARKER).read_text())["command"] == "test"
    with pytest.raises(InputError, match="--force"):
        with staged_output_dir(out):
            pass
    with staged_output_dir(out, force=True) as tmp:
        (Path(tmp) / "b.txt").write_text("second")
    assert sorted(os.listdir(out)) == sorted([MARKER, "b.txt"])
    assert sorted(os.listdir(tmp_path)) == ["out"]
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("keep")
    with pytest.raises(InputError, match="not made by flashbrdf"):
        with staged_output_dir(tmp_path / "mine", force=True):
            pass
    # Another process wrote the output meanwhile: refused at the rename, the newcomer's is kept.
    with pytest.raises(InputError):
        with staged_output_dir(tmp_path / "late") as tmp:
            (tmp_path / "late").mkdir()
            (tmp_path / "late" / "theirs.txt").write_text("theirs")
    assert os.listdir(tmp_path / "late") == ["theirs.txt"]
    assert not [p for p in os.listdir(tmp_path) if p.endswith(".part")]
    # Another process removed the folder under construction (a batch client cleaning up after a
    # remote worker), the body wrote on into a recreated one: what is left is not published.
    with pytest.raises(RuntimeError, match="removed by another process"):
        with staged_output_dir(tmp_path / "gone") as tmp:
            shutil.rmtree(tmp)
            (Path(tmp) / "figures").mkdir(parents=True)
            (Path(tmp) / "report.json").write_text("{}")
    assert not (tmp_path / "gone").exists()
    assert not [p for p in os.listdir(tmp_path) if p.endswith(".part")]


def test_an_out_dir_that_is_a_mount_point_is_bad_input(tmp_path, monkeypatch):
    """A mount point (docker run -v HOST:/out, then --out /out) cannot be renamed over: the
    rename failed with EBUSY after all the work, a traceback and exit 1. Refused before the work
    when os.path.ismount sees it, and at the rename when it does not (a bind mount within one
    filesystem), both times with nothing left beside it."""
    import errno
    mount = tmp_path / "mnt"
    mount.mkdir()
    monkeypatch.setattr(os.path, "ismount", lambda p: os.fspath(p) == str(mount))
    with pytest.raises(InputError, match=r"mnt: is a mount point"):
        with staged_output_dir(mount):
            raise AssertionError("the body must not run")
    monkeypatch.setattr(os.path, "ismount", lambda p: False)
    real_replace = os.replace

    def replace(src, dst):
        if os.fspath(dst) == str(mount):
            raise OSError(errno.EBUSY, "Device or resource busy")
        return real_replace(src, dst)
    monkeypatch.setattr(os, "replace", replace)
    with pytest.raises(InputError, match=r"mnt: is a mount point \(or in use\)"):
        with staged_output_dir(mount) as tmp:
            (Path(tmp) / "a.txt").write_text("work")
    assert sorted(os.listdir(tmp_path)) == ["mnt"] and os.listdir(mount) == []


def _run_command(world, out):
    return [sys.executable, "-m", "flashbrdf", "run", str(world.scene), "--out", str(out),
            "--methods", "chandraker", "--spp", "2"]


def test_two_runs_of_one_scene_at_once_do_not_interfere(world, tmp_path):  # noqa: F811
    """Both succeed, each output is whole, and the two predictions are byte-identical (the run
    is deterministic, so any cross-talk through a shared temporary file would show)."""
    procs = [subprocess.Popen(_run_command(world, tmp_path / name), cwd=REPO,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE)
             for name in ("a", "b")]
    results = [p.communicate(timeout=300) for p in procs]
    assert [p.returncode for p in procs] == [0, 0], [r[1].decode() for r in results]
    a, b = tmp_path / "a", tmp_path / "b"
    assert (a / "chandraker" / "brdf.binary").read_bytes() == \
        (b / "chandraker" / "brdf.binary").read_bytes()
    assert (a / "slice.csv").read_text().splitlines()[1:] == \
        (b / "slice.csv").read_text().splitlines()[1:]
    rows = [json.loads((x / "report.json").read_text())["references"] for x in (a, b)]
    assert [r["delta_e_log_mean"] for r in rows[0]] == [r["delta_e_log_mean"] for r in rows[1]]
    assert sorted(os.listdir(tmp_path)) == ["a", "b"]  # no temporary folder left


def test_interrupted_run_leaves_nothing(world, tmp_path):  # noqa: F811
    """Sent SIGTERM while it works in its temporary folder, `run` exits 143 and leaves neither the
    output nor the temporary folder, and the scene is unchanged."""
    before = snapshot(world.scene)
    proc = subprocess.Popen(_run_command(world, tmp_path / "out"), cwd=REPO,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 120
    while not [p for p in os.listdir(tmp_path) if p.endswith(".part")]:
        assert proc.poll() is None and time.monotonic() < deadline, proc.stderr.read().decode()
        time.sleep(0.02)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 143, err.decode()
    assert os.listdir(tmp_path) == []
    assert snapshot(world.scene) == before


@pytest.mark.parametrize("sig,status", [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_signal_inside_a_command_exits_130_or_143_with_nothing_written(tmp_path, monkeypatch,
                                                                       capsys, sig, status):
    """In-process: the signal arrives while a command writes its staged folder."""
    import flashbrdf.pipeline.render_jobs as render_jobs
    from flashbrdf.cli.main import main

    def interrupted_compare(pred, ref, out, **options):
        with staged_output_dir(out) as tmp:
            (Path(tmp) / "half.json").write_text("{}")
            os.kill(os.getpid(), sig)
            time.sleep(5)  # the handler raises before this ends
        return 0

    monkeypatch.setattr(render_jobs, "compare", interrupted_compare)
    assert main(["compare", "a.exr", "b.exr", "--out", str(tmp_path / "out")]) == status
    assert os.listdir(tmp_path) == []
    assert "no output written" in capsys.readouterr().err
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL or sig == signal.SIGINT


@pytest.mark.parametrize("sig,status", [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
@pytest.mark.parametrize("output", ["folder", "file"])
def test_a_signal_a_library_swallows_still_stops_the_command(tmp_path, monkeypatch, capsys, sig,
                                                             status, output):
    """trimesh's optional imports catch BaseException: a SIGTERM or Ctrl-C landing there raised
    an exception nobody saw, and the command ran on to exit 0 with its output written (one run
    in three under load in the interrupted-run test above). The signal is remembered: neither a
    staged folder nor an atomic file is committed, and the command exits 130 or 143."""
    import flashbrdf.pipeline.render_jobs as render_jobs
    from flashbrdf.cli.main import main
    from flashbrdf.files.atomic import atomic_path

    def compare_under_a_broad_except(pred, ref, out, **options):
        with (staged_output_dir(out) if output == "folder" else atomic_path(out)) as tmp:
            try:  # what `try: from PIL import Image / except BaseException` does
                signal.raise_signal(sig)
            except BaseException:
                pass
            Path(tmp, "done.json").write_text("{}") if output == "folder" else \
                Path(tmp).write_text("{}")
        return 0

    monkeypatch.setattr(render_jobs, "compare", compare_under_a_broad_except)
    assert main(["compare", "a.exr", "b.exr", "--out", str(tmp_path / "out")]) == status
    assert os.listdir(tmp_path) == []
    assert "no output written" in capsys.readouterr().err
    # the next command, and library use outside one, are not haunted by it
    assert main(["--version"]) == 0
    with atomic_path(tmp_path / "later.txt") as tmp:
        Path(tmp).write_text("x")
    assert os.listdir(tmp_path) == ["later.txt"]


@pytest.mark.parametrize("name,suffix", [("..exr", ".exr"), ("a.b.exr", ".exr"),
                                         (".hidden", ""), ("plain", "")])
def test_atomic_path_keeps_the_extension_of_a_dotted_name(tmp_path, name, suffix):
    """The temporary file ends in the target's extension, from the name's last dot: a reference
    photo "..exr" renders to OUT_DIR/..exr, whose extension os.path.splitext does not see (it
    skips leading dots), and OpenImageIO, which picks the format from the name, found none (a
    traceback from render and run)."""
    from flashbrdf.files.atomic import atomic_path
    from flashbrdf.render.images import read_image, write_exr
    with atomic_path(tmp_path / name) as tmp:
        assert tmp.endswith(".part" + suffix)
    if suffix == ".exr":
        write_exr(tmp_path / name, np.ones((2, 3, 3), np.float32))
        assert read_image(tmp_path / name).shape == (2, 3, 3)


def test_name_length_counts_the_temporary_suffix_on_the_last_name_only(tmp_path):
    """A folder on the way to an output is made as named, so it may use the filesystem's whole
    NAME_MAX (255 here); only the output itself is built beside its final name as
    ".NAME.XXXXXXXX.part" + extension, which needs 16 bytes and the extension more."""
    from flashbrdf.files.outputs import check_outputs
    limit = os.pathconf(tmp_path, "PC_NAME_MAX")
    check_outputs([], [tmp_path / ("d" * limit) / "slice.csv"])          # a long folder: fine
    check_outputs([], [tmp_path / ("s" * (limit - 16 - 8) + ".csv")])    # the longest file
    with pytest.raises(InputError, match="bytes long"):
        check_outputs([], [tmp_path / ("s" * (limit - 16 - 7) + ".csv")])
    assert not any(tmp_path.iterdir())                                   # nothing was made


def test_a_sidecar_another_command_wrote_is_not_replaced(world, tmp_path, capsys):  # noqa: F811
    """`extract --out x.csv` then `infer x.csv --out x.binary`: both sidecars are x.json, and
    infer's BRDF.json would silently replace extract's slice report; a re-run of either command
    onto its own earlier output is still allowed."""
    slice_csv = tmp_path / "x.csv"
    assert main(["extract", str(world.scene), "--out", str(slice_csv)]) == 0
    report = (tmp_path / "x.json").read_bytes()
    infer = ["infer", "--slice", str(slice_csv), "--model", str(world.model), "--method", "chandraker"]
    capsys.readouterr()
    assert main(infer + ["--out", str(tmp_path / "x.binary")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "x.json" in err[0] and "not an earlier BRDF.json" in err[0], err
    assert (tmp_path / "x.json").read_bytes() == report and not (tmp_path / "x.binary").exists()
    assert main(infer + ["--out", str(tmp_path / "y.binary")]) == 0
    assert main(infer + ["--out", str(tmp_path / "y.binary")]) == 0  # its own record: replaced
    assert main(["extract", str(world.scene), "--out", str(tmp_path / "y.csv")]) == 2
    assert json.loads((tmp_path / "y.json").read_text())["method"] == "chandraker"
    assert main(["extract", str(world.scene), "--out", str(slice_csv)]) == 0  # its own: replaced


def test_files_fingerprint_sees_one_file_through_links_and_a_missing_one(tmp_path):
    """A batch compares its markers' input fingerprints with the capture's: a link or a `..`
    must name the same file (the client and the worker spell the model's path differently),
    and a file that is not there (an optional reference photo) is recorded as such, not void
    the whole fingerprint (then a changed photo beside it went unseen)."""
    from flashbrdf.files.outputs import files_fingerprint
    real = tmp_path / "models" / "m.npz"
    real.parent.mkdir()
    real.write_bytes(b"x" * 10)
    (tmp_path / "link.npz").symlink_to(real)
    by_link = files_fingerprint([tmp_path / "link.npz", tmp_path / "gone.exr"])
    by_dots = files_fingerprint([tmp_path / "models" / ".." / "models" / "m.npz",
                                 tmp_path / "gone.exr"])
    assert by_link == by_dots and by_link[os.path.realpath(real)][0] == 10
    assert by_link[os.path.realpath(tmp_path / "gone.exr")] is None
    os.utime(real, ns=(0, 10 ** 9))
    assert files_fingerprint([real, tmp_path / "gone.exr"]) != by_link


def test_an_out_file_that_is_a_pipe_or_device_is_bad_input(world, tmp_path, capsys):  # noqa: F811
    """Files are renamed into place, so `--out /dev/stdout` (or a named pipe) was replaced by a
    regular file, exit 0: as root that swapped the container's /dev/stdout for a file."""
    pipe = tmp_path / "pipe.csv"
    os.mkfifo(pipe)
    capsys.readouterr()
    assert main(["merl-slice", str(world.brdf), "--out", str(pipe)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "pipe.csv" in err[0] and "not a regular file" in err[0], err
    assert stat.S_ISFIFO(os.lstat(pipe).st_mode)
    assert sorted(os.listdir(tmp_path)) == ["pipe.csv"]  # no temporary file left beside it
