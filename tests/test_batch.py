"""`flashbrdf batch` on Dask: tiny synthetic captures (48² spheres, 4 spp renders).

Most tests share one single-worker LocalCluster through `--scheduler` (a cluster starts in a few
seconds); one test uses `--workers 2`, the default local cluster. Together they check that a
capture's numbers do not depend on the worker or the number of workers (ΔE equal to a sequential
`run` to 1e-9: both are the same deterministic code on the same inputs), exit codes 0/1/2, resume
and --force, the summary, the per-worker model cache, and a killed worker's capture.
"""

import csv
import json
import os
import shutil
import sys
import time
from pathlib import Path

import cloudpickle
import dask
import pytest
from distributed import Client, LocalCluster
from distributed.diagnostics.plugin import WorkerPlugin

import flashbrdf.pipeline.run as run_module  # in a worker: the worker's copy, which `run` calls
from flashbrdf.files.errors import InputError
from flashbrdf.pipeline.batch import MARKER, capture_bytes, check_batch_folder
from flashbrdf.pipeline.batch_summary import failed_row, write_summary
from flashbrdf.cli.main import main
from flashbrdf.pipeline.dask_engine import ALLOWED_FAILURES, threads_per_worker
from sample_capture import make_sample_capture

MATERIALS = {"a": "red-specular-plastic", "b": "gold-paint"}
RUN_OPTIONS = ["--methods", "dsgplvm,chandraker", "--spp", "4"]

# The plugin below is defined here; workers cannot import this test module, so it travels by value.
cloudpickle.register_pickle_by_value(sys.modules[__name__])


@pytest.fixture(scope="module")
def captures(merl_proxy, tmp_path_factory):
    folder = tmp_path_factory.mktemp("captures")
    for name, material in MATERIALS.items():
        make_sample_capture(merl_proxy(material), folder / name, size=48, spp=16, shape="sphere",
                            envmaps={"ref_pisa": "pisa_latlong_256x128.hdr"})
    (folder / "notes").mkdir()  # a subfolder without scene.json is not a capture
    return folder


@pytest.fixture(scope="module")
def sequential(captures, tmp_path_factory):
    """{capture: out folder} of plain `flashbrdf run`, one after the other."""
    out = tmp_path_factory.mktemp("sequential")
    for name in MATERIALS:
        assert main(["run", str(captures / name), "--out", str(out / name), *RUN_OPTIONS]) == 0
    return {name: out / name for name in MATERIALS}


@pytest.fixture(scope="module")
def scheduler():
    """A one-worker, one-thread local cluster's address, with the batch's retry rule."""
    with dask.config.set({"distributed.scheduler.allowed-failures": ALLOWED_FAILURES}):
        cluster = LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                               dashboard_address=None, silence_logs=50)
    with cluster:
        yield cluster.scheduler_address


@pytest.fixture(scope="module")
def two_workers(captures, tmp_path_factory):
    """--workers 3 on 2 captures: a local cluster of 2 workers (never more than captures)."""
    out = tmp_path_factory.mktemp("batch") / "out"
    code = main(["batch", str(captures), "--out", str(out), "--workers", "3", *RUN_OPTIONS])
    return code, out


def _summary(out):
    with open(out / "summary.csv", newline="") as f:
        return {row["capture"]: row for row in csv.DictReader(f)}


def _delta_e(folder):
    report = json.loads((folder / "report.json").read_text())
    return {(r["method"], r["photo"]): r["delta_e_log_mean"] for r in report["references"]}


def _files(folder):
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if p.is_file())


def test_two_workers_equal_sequential_runs(two_workers, sequential):
    code, out = two_workers
    assert code == 0
    rows = _summary(out)
    assert set(rows) == set(MATERIALS)  # "notes" has no scene.json
    for name, seq in sequential.items():
        # Same files as `run` writes, plus the completion marker; nothing half-written beside.
        assert _files(out / name) == sorted(_files(seq) + [MARKER])
        got, want = _delta_e(out / name), _delta_e(seq)
        assert got.keys() == want.keys() == {("dsgplvm", "ref_pisa"), ("chandraker", "ref_pisa")}
        for key in want:
            assert got[key] == pytest.approx(want[key], abs=1e-9)
            column = f"delta_e_log {key[0]}/{key[1]}"
            assert float(rows[name][column]) == pytest.approx(want[key], abs=1e-9)
        assert rows[name]["status"] == "ok" and rows[name]["reason"] == ""
        assert float(rows[name]["seconds"]) > 0 and rows[name]["worker"]
        # CPU time of a worker over its capture: at most its threads (+1 for Dask's own) busy
        # for the whole wall time
        assert 0 < float(rows[name]["cpu_seconds"]) <= (
            (threads_per_worker(2) + 1) * float(rows[name]["seconds"]))
        slice_report = json.loads((out / name / "slice.json").read_text())
        assert slice_report["slice_csv"] == str((out / name / "slice.csv").resolve())
    assert not [p for p in out.iterdir() if p.name.startswith(".")]
    md = (out / "summary.md").read_text()
    assert "2 ok (0 skipped as complete), 0 failed" in md and md.count("| ok |") == 2
    assert "a local cluster of 2 worker process(es)" in md
    # each of the 2 local workers renders on its share of this machine's cores
    threads = threads_per_worker(2)
    for name in MATERIALS:
        log = (out / "logs" / f"{name}.log").read_text()
        assert f", {threads} thread(s)" in log
        # the page the log names is where the capture was published, not its staging folder
        assert f"report: {(out / name / 'report.html').resolve()} " in log and ".partial-" not in log


def test_cores_are_shared_out_between_local_workers():
    assert [threads_per_worker(w, cores=2) for w in (1, 2, 3, 4)] == [2, 1, 1, 1]
    assert [threads_per_worker(w, cores=8) for w in (1, 2, 3, 8)] == [8, 4, 2, 1]


def test_capture_size_counts_every_file(tmp_path):
    small, large = tmp_path / "small", tmp_path / "large"
    for folder, size in ((small, 10), (large, 1000)):
        (folder / "sub").mkdir(parents=True)
        (folder / "scene.json").write_text("{}")
        (folder / "sub" / "photo.exr").write_bytes(b"x" * size)
    assert capture_bytes(large) - capture_bytes(small) == 990


def test_resume_force_and_one_worker(two_workers, sequential, scheduler, captures):
    """A second call skips complete captures; a capture without its marker is rerun; --force
    reruns all. One worker then runs both captures, reading the model once, with the same ΔE."""
    code, out = two_workers
    before = {n: (out / n / "report.json").stat().st_mtime_ns for n in MATERIALS}
    assert main(["batch", str(captures), "--out", str(out), "--scheduler", scheduler,
                 *RUN_OPTIONS]) == 0
    assert {n: (out / n / "report.json").stat().st_mtime_ns for n in MATERIALS} == before
    assert all("skipped" in row["reason"] for row in _summary(out).values())

    (out / "b" / MARKER).unlink()  # as if b's output were from an older, unfinished batch
    assert main(["batch", str(captures), "--out", str(out), "--scheduler", scheduler,
                 *RUN_OPTIONS]) == 0
    assert (out / "a" / "report.json").stat().st_mtime_ns == before["a"]
    assert (out / "b" / "report.json").stat().st_mtime_ns != before["b"]
    assert (out / "b" / MARKER).is_file() and "skipped" not in _summary(out)["b"]["reason"]

    # a marker lists every file run wrote: a folder that lost one (a client that gave up on a
    # remote worker removed its staging folder under it) is not complete, and is rerun
    listed = json.loads((out / "a" / MARKER).read_text())["files"]
    assert "slice.csv" in listed and "report.json" in listed and MARKER not in listed
    (out / "a" / "slice.csv").unlink()
    assert main(["batch", str(captures), "--out", str(out), "--scheduler", scheduler,
                 *RUN_OPTIONS]) == 0
    assert (out / "a" / "slice.csv").is_file() and "skipped" not in _summary(out)["a"]["reason"]

    # an input changed since its output was made (a photo retaken): that capture is rerun, not
    # kept with the old photos' BRDF; the marker holds each input's size and mtime
    assert str((captures / "a" / "scene.json").resolve()) in json.loads(
        (out / "a" / MARKER).read_text())["inputs"]
    photo = next(p for p in (captures / "a").iterdir() if p.suffix == ".exr")
    stat = photo.stat()
    os.utime(photo, ns=(stat.st_atime_ns, stat.st_mtime_ns + 10 ** 9))
    try:
        assert main(["batch", str(captures), "--out", str(out), "--scheduler", scheduler,
                     *RUN_OPTIONS]) == 0
        rows = _summary(out)
        assert "skipped" not in rows["a"]["reason"] and "skipped" in rows["b"]["reason"]
    finally:
        os.utime(photo, ns=(stat.st_atime_ns, stat.st_mtime_ns))

    for log in (out / "logs").glob("*.log"):
        log.unlink()
    assert main(["batch", str(captures), "--out", str(out), "--scheduler", scheduler, "--force",
                 *RUN_OPTIONS]) == 0
    rows = _summary(out)
    assert all(row["reason"] == "" and row["status"] == "ok" for row in rows.values())
    assert len({row["worker"] for row in rows.values()}) == 1
    logs = "".join((out / "logs" / f"{n}.log").read_text() for n in MATERIALS)
    assert logs.count("model: reading") <= 1 and logs.count("model: already read") >= 1
    for name, seq in sequential.items():
        got, want = _delta_e(out / name), _delta_e(seq)
        assert all(got[k] == pytest.approx(want[k], abs=1e-9) for k in want)


def test_one_capture_to_run_runs_in_process(two_workers, sequential, captures, tmp_path,
                                            monkeypatch):
    """One capture left to run and no --scheduler: the batch runs it in its own process (no
    cluster to start), with the same files, ΔE, summary row and log; a raising task is retried
    once, then failed, as Dask's retries=1 would."""
    out = tmp_path / "out"
    out.mkdir()
    shutil.copytree(two_workers[1] / "b", out / "b")  # complete: skipped, so `a` is alone
    threads = os.environ.get("FLASHBRDF_THREADS")
    assert main(["batch", str(captures), "--out", str(out), "--workers", "2",
                 *RUN_OPTIONS]) == 0
    assert os.environ.get("FLASHBRDF_THREADS") == threads
    rows = _summary(out)
    assert rows["a"]["status"] == "ok" and rows["a"]["worker"].endswith(f":{os.getpid()}")
    assert "skipped" in rows["b"]["reason"]
    assert _files(out / "a") == sorted(_files(sequential["a"]) + [MARKER])
    got, want = _delta_e(out / "a"), _delta_e(sequential["a"])
    assert got.keys() == want.keys() and len(want) == 2
    assert all(got[k] == pytest.approx(want[k], abs=1e-9) for k in want)
    assert "the batch's own process" in (out / "summary.md").read_text()
    # every core, as a one-worker local cluster's worker
    assert f", {threads_per_worker(1)} thread(s)" in (out / "logs" / "a.log").read_text()
    assert not [p for p in out.iterdir() if p.name.startswith(".")]

    (out / "a" / MARKER).unlink()
    attempts = []

    def crash(*args):
        attempts.append(args)
        raise RuntimeError("disk on fire")

    monkeypatch.setattr("flashbrdf.pipeline.batch.run_capture", crash)
    assert main(["batch", str(captures), "--out", str(out), *RUN_OPTIONS]) == 1
    assert len(attempts) == 2
    assert _summary(out)["a"]["reason"] == "RuntimeError: disk on fire"


def test_run_options_reach_run_export(merl_proxy, tmp_path):
    """Contract: "Each capture's output is `OUT_DIR/<subfolder>/` exactly as `run` writes it",
    with `[run options]`: `batch --export` writes what `run --export` does (export/ and the
    Principled fit's renders), not a plain `run`'s folder."""
    one = tmp_path / "captures"
    make_sample_capture(merl_proxy(MATERIALS["a"]), one / "a", size=48, spp=16, shape="sphere",
                        envmaps={"ref_pisa": "pisa_latlong_256x128.hdr"})
    options = ["--methods", "dsgplvm", "--spp", "4", "--export"]
    assert main(["run", str(one / "a"), "--out", str(tmp_path / "run"), *options]) == 0
    out = tmp_path / "out"
    # A capture completed by a batch without --export is not complete for one with it: its
    # folder is not what `run --export` writes, so it runs again (it was skipped before).
    assert main(["batch", str(one), "--out", str(out), *options[:-1]]) == 0
    assert not (out / "a" / "export").exists()
    assert main(["batch", str(one), "--out", str(out), *options]) == 0
    assert "skipped" not in _summary(out)["a"]["reason"]
    assert (out / "a" / "export" / "principled.json").is_file()
    assert (out / "a" / "dsgplvm-principled").is_dir()
    assert _files(out / "a") == sorted(_files(tmp_path / "run") + [MARKER])
    assert ", export." in (out / "summary.md").read_text()
    # The export names the table where it is now, not in the batch's or run's staging folder.
    table = str((out / "a" / "dsgplvm" / "brdf.binary").absolute())
    assert f'value="{table}"' in (out / "a" / "export" / "mitsuba_tabulated.xml").read_text()
    assert json.loads((out / "a" / "export" / "principled.json").read_text())["table"] == table
    # the same options again: complete, skipped
    before = (out / "a" / "report.json").stat().st_mtime_ns
    assert main(["batch", str(one), "--out", str(out), *options]) == 0
    assert (out / "a" / "report.json").stat().st_mtime_ns == before
    assert "skipped" in _summary(out)["a"]["reason"]


def test_summary_columns_in_the_contract_order(tmp_path):
    """Contract: summary.csv and summary.md have one row per capture "(`capture`, `status`
    ok|failed, `reason`, per-method ΔE-log, seconds)": the ΔE-log columns come before seconds."""
    rows = [{"capture": "a", "status": "ok", "reason": "", "seconds": 1.5, "cpu_seconds": 2.0,
             "worker": "w:1", "delta_e_log": {"dsgplvm": 3.0, "dsgplvm/ref_pisa": 3.0}},
            failed_row("b", "bad scene.json")]
    write_summary(tmp_path, rows)
    with open(tmp_path / "summary.csv", newline="") as f:
        header = next(csv.reader(f))
    # per-photo columns are ours: after the contract's, not between the per-method ΔE-log and
    # seconds
    assert header == ["capture", "status", "reason", "delta_e_log dsgplvm", "seconds",
                      "cpu_seconds", "worker", "delta_e_log dsgplvm/ref_pisa"]
    assert _summary(tmp_path)["a"]["seconds"] == "1.5"
    assert _summary(tmp_path)["a"]["delta_e_log dsgplvm/ref_pisa"] == "3.0"
    assert _summary(tmp_path)["b"]["status"] == "failed"
    table = [line for line in (tmp_path / "summary.md").read_text().splitlines()
             if line.startswith("| capture")][0]
    assert [c.strip() for c in table.strip("|").split("|")][:5] == [
        "capture", "status", "reason", "ΔE-log dsgplvm", "seconds"]
    # A batch recognises the summaries (and index.html) it wrote, in either order, and no one
    # else's.
    assert (tmp_path / "index.html").is_file()
    check_batch_folder(tmp_path)
    # every --methods column is there even when no capture succeeded
    write_summary(tmp_path, [failed_row("b", "bad scene.json")], methods=["dsgplvm", "pca"])
    with open(tmp_path / "summary.csv", newline="") as f:
        assert next(csv.reader(f))[:6] == ["capture", "status", "reason",
                                           "delta_e_log dsgplvm", "delta_e_log pca", "seconds"]
    check_batch_folder(tmp_path)
    write_summary(tmp_path, [failed_row("b", "bad scene.json")])  # no ΔE-log column
    check_batch_folder(tmp_path)
    (tmp_path / "summary.csv").write_text("capture,status,reason,notes\n")
    with pytest.raises(InputError):
        check_batch_folder(tmp_path)


class KillMidRun(WorkerPlugin):
    """Test-only: kill the worker process (os._exit) when capture `name`'s `run` reaches its
    first render, on every worker and every attempt. `run` has then written the slice, the
    labels and the inferred tables into its temporary folder, so the kill leaves a half-written
    capture behind. The kill happens in the task's own thread at that fixed point: a watcher
    thread polling the output folder raced the task, and lost under load (the capture was then
    published before the kill and the test failed)."""

    def __init__(self, name):
        self.name = name

    def setup(self, worker):
        self.original = original = run_module.render_and_compare
        marker = f"..{self.name}.partial-"  # run's temporary folder of the capture's staging

        def render_or_die(*args, **kwargs):
            staged = [a for a in args if isinstance(a, Path) and marker in str(a)]
            if staged:
                folder = next(p for p in (staged[0], *staged[0].parents)
                              if p.name.startswith(marker))
                files = sorted(p.name for p in folder.rglob("*") if p.is_file())
                print(f"test: killing the worker mid-run; staged files: {' '.join(files)}",
                      flush=True)
                os._exit(1)
            return original(*args, **kwargs)

        run_module.render_and_compare = render_or_die

    def teardown(self, worker):
        run_module.render_and_compare = self.original


def test_failures_exit_1_killed_worker_retried_once(captures, scheduler, tmp_path, capsys):
    folder = tmp_path / "captures"
    folder.mkdir()
    shutil.copytree(captures / "a", folder / "crash", symlinks=True)
    # the copy sits at another depth: its relative envmap paths are made absolute, or run's
    # input check would fail it (bad input) before the worker is killed
    scene = json.loads((folder / "crash" / "scene.json").read_text())
    for photo in scene["photos"]:
        light = photo.get("light") or {}
        if light.get("type") == "envmap":
            light["file"] = str((captures / "a" / light["file"]).resolve())
    (folder / "crash" / "scene.json").write_text(json.dumps(scene))
    (folder / "broken").mkdir()
    (folder / "broken" / "scene.json").write_text("{not json")
    out = tmp_path / "out"
    with Client(scheduler) as client:
        client.register_plugin(KillMidRun("crash"), name="kill-mid-run")
        try:
            code = main(["batch", str(folder), "--out", str(out), "--scheduler", scheduler,
                         *RUN_OPTIONS])
        finally:
            client.unregister_worker_plugin("kill-mid-run")
    assert code == 1
    rows = _summary(out)
    assert rows["broken"]["status"] == "failed" and "scene.json" in rows["broken"]["reason"]
    assert rows["crash"]["status"] == "failed" and "KilledWorker" in rows["crash"]["reason"]
    # Retried once: two attempts started, each killed with its output half-written (the slice
    # and the labels written, the report not), and nothing of either left in OUT_DIR.
    log = (out / "logs" / "crash.log").read_text()
    assert log.count(": started on ") == 2
    kills = [line for line in log.splitlines() if line.startswith("test: killing")]
    assert len(kills) == 2
    assert all("slice.csv" in k and "labels.png" in k and "report.json" not in k for k in kills)
    assert sorted(p.name for p in out.iterdir()) == ["index.html", "logs", "summary.csv",
                                                     "summary.md"]
    err = capsys.readouterr().err
    assert "crash failed" in err and "broken failed" in err


def test_no_capture_or_bad_options_exit_2(captures, tmp_path, capsys, monkeypatch):
    empty = tmp_path / "empty"
    empty.mkdir()
    (empty / "notes").mkdir()
    out = tmp_path / "out"
    assert main(["batch", str(empty), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no capture" in err[0] and not out.exists()
    assert main(["batch", str(captures), "--out", str(out), "--workers", "0"]) == 2
    assert "--workers" in capsys.readouterr().err and not out.exists()
    assert main(["batch", str(captures), "--out", str(out), "--methods", "magic"]) == 2
    assert "magic" in capsys.readouterr().err and not out.exists()
    # An --out that would put an output folder onto an input capture.
    assert main(["batch", str(captures), "--out", str(captures)]) == 2
    assert "overwrite" in capsys.readouterr().err
    monkeypatch.setattr("flashbrdf.pipeline.dask_engine.CONNECT_TIMEOUT", "1s")
    assert main(["batch", str(captures), "--out", str(out), "--scheduler",
                 "tcp://127.0.0.1:9"]) == 2
    assert "--scheduler" in capsys.readouterr().err


def test_out_dir_that_cannot_be_written_is_bad_input(captures, tmp_path, capsys, monkeypatch):
    """A read-only OUT_DIR (or a new one in a read-only folder) was a traceback at the first write
    (exit 1); it is bad input, found before any capture runs. os.access answers as on a
    read-only filesystem: as root (CI) a chmod would not stop a write."""
    out = tmp_path / "out"
    out.mkdir()
    real_access = os.access
    monkeypatch.setattr(os, "access", lambda path, mode, **kw: (
        False if os.fspath(path) == str(out) and mode & os.W_OK else real_access(path, mode, **kw)))
    options = ["--methods", "chandraker", "--spp", "2", "--workers", "1"]
    assert main(["batch", str(captures), "--out", str(out), *options]) == 2
    assert capsys.readouterr().err.splitlines() == [
        f"flashbrdf batch: error: {out}: cannot be written: no permission to write in it"]
    assert main(["batch", str(captures), "--out", str(out / "new"), *options]) == 2
    assert capsys.readouterr().err.splitlines() == [
        f"flashbrdf batch: error: {out / 'new'}: cannot be made: no permission to write in {out}"]
    assert os.listdir(out) == []


def test_a_second_batch_into_a_busy_out_dir_is_refused(captures, tmp_path, capsys):
    """Another batch writing into OUT_DIR (it holds the folder's lock, here taken by hand) and
    mid-capture (its staging folder): a second batch into the same OUT_DIR exits 2 with one line
    naming it and leaves the other's staging folder alone. Two batches at once each removed the
    other's staging folders as a killed batch's leftovers, failing its captures mid-run."""
    import fcntl
    one = tmp_path / "one"
    one.mkdir()
    (one / "a").symlink_to(captures / "a")  # one capture: the batch runs in its own process
    out = tmp_path / "out"
    staging = out / ".a.partial-0123abcd"
    staging.mkdir(parents=True)
    fd = os.open(out, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        assert main(["batch", str(one), "--out", str(out), *RUN_OPTIONS]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and str(out) in err[0] and "another flashbrdf batch" in err[0], err
        assert staging.is_dir() and sorted(os.listdir(out)) == [staging.name]
    finally:
        os.close(fd)
    # the lock gone (that batch ended or was killed): this one runs, and removes the leftover
    assert main(["batch", str(one), "--out", str(out), *RUN_OPTIONS]) == 0
    assert not staging.exists() and (out / "a" / MARKER).is_file()
    # with nothing left to run, the summary is still written under the lock
    written = (out / "summary.md").stat().st_mtime_ns
    fd = os.open(out, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        assert main(["batch", str(one), "--out", str(out), *RUN_OPTIONS]) == 2
        assert (out / "summary.md").stat().st_mtime_ns == written
    finally:
        os.close(fd)


def test_scheduler_with_nothing_listening_fails_at_once(captures, tmp_path, capsys):
    """Nothing listens at --scheduler: one line naming it, exit 2, long before Dask's 20 s connect
    timeout (a refused TCP probe takes milliseconds; 5 s leaves room for a loaded machine)."""
    out = tmp_path / "out"
    start = time.perf_counter()
    assert main(["batch", str(captures), "--out", str(out), "--scheduler",
                 "tcp://127.0.0.1:1"]) == 2
    assert time.perf_counter() - start < 5
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--scheduler" in err[0] and not out.exists()


def test_batch_export_repoints_the_table_in_an_out_dir_that_json_or_xml_escape(merl_proxy,
                                                                               tmp_path):
    # principled.json escapes non-ASCII (\u00e9) and mitsuba_tabulated.xml escapes & (&amp;):
    # the staging folder's path must still be replaced by the final one
    one = tmp_path / "captures"
    make_sample_capture(merl_proxy(MATERIALS["a"]), one / "a", size=48, spp=16, shape="sphere")
    out = tmp_path / "out é&"
    assert main(["batch", str(one), "--out", str(out), "--methods", "chandraker", "--spp", "1",
                 "--export"]) == 0
    table = str((out / "a" / "chandraker" / "brdf.binary").absolute())
    assert json.loads((out / "a" / "export" / "principled.json").read_text())["table"] == table
    xml = (out / "a" / "export" / "mitsuba_tabulated.xml").read_text()
    assert ".a.partial" not in xml, xml
