"""`flashbrdf batch CAPTURES_DIR --out OUT_DIR [--workers N] [--scheduler ADDRESS] [run options]`.

Every subfolder of CAPTURES_DIR that holds a scene.json is one capture. Each capture is one Dask
task that calls `run` in the worker process (pipeline/run.py, the same function as
`flashbrdf run`), so OUT_DIR/<subfolder>/ is exactly what `run` writes, plus the completion marker.

All or nothing per capture: the task builds the capture in a hidden staging folder inside OUT_DIR
(`.<subfolder>.partial-<id>`), writes the marker `.batch_complete.json` (its summary row and the
size of every file run wrote) last, and renames the folder into place. A capture is complete when
OUT_DIR/<subfolder>/ holds a readable marker whose files are all there at those sizes; a second
call skips complete captures unless --force. Staging folders left by a killed worker are removed
by the client when the batch ends on its own cluster (a remote scheduler's workers may still be
writing), and at the start of the next batch. One batch at a time writes into an OUT_DIR: it
holds a lock on the folder (files.folder_lock), and a second one is refused (exit 2).

A task that raises is retried once by Dask (retries=1), and a task whose worker dies is retried
once on another worker (dask_engine.ALLOWED_FAILURES); then the capture is recorded as failed. Bad
input in one capture (InputError) is recorded as failed at once, since a retry would fail the same.

A batch with exactly one capture to run and no --scheduler runs that task in its own process
(_run_here): a cluster's start and close cost more than the 5 s the issue allows over one `run`.
`run`'s option checks import every stage, so on a cluster they run as its first task
(check_run_options), not in the client.

Each worker process reads the model once (cached on path, size and mtime) and keeps it for its
next captures. A local cluster has at most one worker per capture to run, and shares the cores
out between its workers (dask_engine); the largest captures are submitted with the highest
priority, so that the last one to finish is a small one. What `run` prints goes to OUT_DIR/logs/<subfolder>.log, not to the terminal; the
terminal shows one progress bar over captures. OUT_DIR/summary.csv and summary.md give one row per
capture. Exit 0 when all succeeded, 1 when any failed, 2 when CAPTURES_DIR holds no capture.
"""

import contextlib
import json
import os
import shutil
import socket
import sys
import threading
import time
import traceback
import uuid
from pathlib import Path

from flashbrdf.files.atomic import write_text
from flashbrdf.files.folder_lock import sole_writer
from flashbrdf.files.errors import InputError
from flashbrdf.pipeline import dask_engine
from flashbrdf.pipeline.batch_logs import output_to
from flashbrdf.pipeline.batch_summary import (SUMMARY_HEADS, failed_row, row_from_report,
                                              write_summary)
from flashbrdf.pipeline.options import inputs_fingerprint
from flashbrdf.pipeline.report_index import INDEX_NAME, LOG_DIR
from flashbrdf.files.outputs import MARKER as RUN_MARKER, folder_inventory
from flashbrdf.files.outputs import check_writable_folder

MARKER = ".batch_complete.json"
RUN_OPTIONS = ("model", "methods", "spp", "no_anchor", "materials", "albedo_map", "export",
               "envmap", "refine_poses")
OWN_NAMES = (LOG_DIR, "summary.csv", "summary.md", INDEX_NAME)  # what a batch writes in OUT_DIR


def find_captures(captures_dir):
    """Sorted subfolders of `captures_dir` that hold a scene.json ([Path]); InputError if none."""
    folder = Path(captures_dir)
    if not folder.is_dir():
        raise InputError(captures_dir, "not a folder")
    captures = sorted(p for p in folder.iterdir() if p.is_dir() and (p / "scene.json").is_file())
    if not captures:
        hint = (" (it is itself a capture: give the folder that holds it, or use `run`)"
                if (folder / "scene.json").is_file() else "")
        raise InputError(captures_dir, f"no capture: no subfolder holds a scene.json{hint}")
    return captures


def completed_row(folder, requested=None, inputs=None):
    """The summary row in `folder`'s marker when a batch finished it with the run options
    `requested` (a dict of RUN_OPTIONS as the batch was asked them; None: any) from the inputs
    `inputs()` (a callable giving options.inputs_fingerprint, asked only of a marker that matches
    so far: it reads the scene; None: any), else None (no marker, one that cannot be read, other
    options or changed inputs: the capture is run again, since its folder is not what `run`
    with these options writes from these files, e.g. no export/ for a later --export, or the
    BRDF of photos since retaken)."""
    try:
        row = json.loads((Path(folder) / MARKER).read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(row, dict) or row.get("status") != "ok":
        return None
    asked = row.get("run_options")
    if isinstance(asked, dict):  # a marker from before --refine-poses ran without it
        asked = {"refine_poses": False} | asked
    if requested is not None and asked != requested:
        return None
    files = row.get("files")
    if isinstance(files, dict) and files != folder_inventory(folder, files):
        return None      # a file the marker lists is gone or changed: not what run wrote
    if inputs is not None and row.get("inputs") != inputs():
        return None
    return row


def _leftovers(out_dir, name):
    """Hidden folders a batch leaves for capture `name` if its worker is killed: the staging
    folder (`.<name>.partial-<id>`), `run`'s own temporary folder beside it (`run` builds the
    staging folder as `..<name>.partial-<id>.<random>.part`, see safety.staged_output_dir, so a
    worker killed mid-run leaves that one) and a replaced output (`.<name>.old-<id>`)."""
    out_dir = Path(out_dir)
    patterns = (f".{name}.partial-*", f"..{name}.partial-*", f".{name}.old-*")
    return [p for pattern in patterns for p in out_dir.glob(pattern)]


def _publish(staging, target):
    """Rename the finished `staging` folder to `target`, replacing an earlier output there."""
    target = Path(target)
    old = None
    if target.exists():
        old = target.with_name(f".{target.name}.old-{uuid.uuid4().hex[:8]}")
        os.replace(target, old)
    os.replace(staging, target)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


# --- worker side -------------------------------------------------------------------------------

_MODELS = {}              # this worker process's fitted methods: {(model file, size, mtime, ...): …}
_MODELS_LOCK = threading.Lock()


def cached_load_methods(names, model_path, anchor):
    """run_steps.load_methods, read once per worker process: cached on the model file's path,
    size and modification time (a retrained model is read again), the method names and anchor."""
    from flashbrdf.pipeline.run_steps import load_methods
    stat = None if model_path is None else Path(model_path).stat()
    key = (None if model_path is None else str(Path(model_path).resolve()),
           None if stat is None else (stat.st_size, stat.st_mtime_ns), tuple(names), bool(anchor))
    with _MODELS_LOCK:
        if key not in _MODELS:
            print(f"model: reading {model_path} in worker process {os.getpid()}", file=sys.stderr)
            _MODELS.clear()  # one model at a time: a worker serves one batch
            _MODELS[key] = load_methods(names, model_path, anchor)
        else:
            print(f"model: already read by worker process {os.getpid()}", file=sys.stderr)
        return _MODELS[key]


def check_run_options(options, as_text=False):
    """`run`'s checks of the run options (RUN_OPTIONS dict): method names, the model file (the
    default one when none is given and a method needs it; whole and of our format), --spp,
    --materials. -> the options with the model as an absolute path or None. Bad options raise
    InputError, or with `as_text` (a Dask task) are returned as its (where, problem) tuple."""
    from flashbrdf.infer.model_file import check_model_file
    from flashbrdf.pipeline.options import (materials_option, method_names, model_path,
                                            samples_per_pixel)
    try:
        model = model_path(options["model"], method_names(options["methods"]))
        if model is not None:  # a truncated model would fail every capture, not the batch
            check_model_file(model)
        samples_per_pixel(options["spp"])
        materials_option(options["materials"])
        if options.get("envmap") is not None:
            from flashbrdf.render.envmap import read_envmap_pixels
            read_envmap_pixels(options["envmap"])
    except InputError as err:
        if as_text:
            return err.where, err.problem
        raise
    return options | {"model": None if model is None else str(model.resolve())}


def run_capture(scene_dir, out_dir, options):
    """The Dask task: `run` one capture into OUT_DIR/<name>/, all or nothing. -> summary row dict.

    options: the run options (RUN_OPTIONS: model, methods, spp, no_anchor, materials,
    albedo_map, export, envmap, refine_poses). Raises on unexpected errors (Dask
    retries once); bad input in the capture is returned as a failed row.
    """
    from flashbrdf.pipeline.run import run_capture as run
    options = dict(options)
    requested = options.pop("requested", None)  # the options as asked, kept in the marker
    name = Path(scene_dir).name
    out_dir = Path(out_dir)
    worker = f"{socket.gethostname()}:{os.getpid()}"
    staging = out_dir / f".{name}.partial-{uuid.uuid4().hex[:8]}"
    start, cpu_start = time.perf_counter(), time.process_time()
    with output_to(out_dir / LOG_DIR / f"{name}.log") as log, \
            dask_engine.worker_threads() as threads:
        print(f"--- {time.strftime('%Y-%m-%d %H:%M:%S')} {name}: started on {worker}, "
              f"{threads} thread(s)", file=log)
        try:
            inputs = inputs_fingerprint(scene_dir, options)
            # final_out: the paths run records (slice.json's slice.csv, --export's table) are
            # those of the capture's folder once published, not of this staging folder
            run(str(scene_dir), str(staging), model=options["model"],
                methods=options["methods"], spp=options["spp"], materials=options["materials"],
                albedo_map=options["albedo_map"], anchor=not options["no_anchor"],
                export=options["export"], envmap=options.get("envmap"),
                refine_poses=options.get("refine_poses", False),
                final_out=str(out_dir / name),
                read_methods=cached_load_methods)
            seconds = time.perf_counter() - start
            report = json.loads((staging / "report.json").read_text())
            row = row_from_report(name, report, seconds, time.process_time() - cpu_start,
                                   worker)
            # run refuses to publish a folder removed under it (files.outputs), and the marker
            # lists every file run wrote, so one that loses a file later is not taken as complete
            files = folder_inventory(staging, skip=(MARKER,))
            write_text(staging / MARKER, json.dumps(
                row | {"run_options": requested, "files": files, "inputs": inputs},
                indent=1) + "\n")
            _publish(staging, out_dir / name)
        except InputError as err:
            shutil.rmtree(staging, ignore_errors=True)
            print(f"failed (bad input): {err}", file=log)
            return failed_row(name, err, time.perf_counter() - start, worker)
        except BaseException:
            shutil.rmtree(staging, ignore_errors=True)
            traceback.print_exc(file=log)
            raise
        print(f"done in {seconds:.1f} s ({row['cpu_seconds']:.1f} s of CPU)", file=log)
    return row


# --- client side -------------------------------------------------------------------------------

def _check_outputs(out_dir, captures_dir, captures):
    """InputError if an output folder OUT_DIR/<name> would be, or hold, an input, if a capture's
    name is one of the batch's own files, or if OUT_DIR holds what no batch made (a batch adds
    to its OUT_DIR, so it never writes into someone's folder)."""
    given = out_dir
    out_dir, captures_dir = Path(out_dir).resolve(), Path(captures_dir).resolve()
    inputs = [captures_dir] + [c.resolve() for c in captures]
    for c in captures:
        if c.name in OWN_NAMES:
            raise InputError(c, f"a capture named {c.name!r} would collide with the batch's own "
                                f"OUT_DIR/{c.name}; rename the capture folder")
        target = out_dir / c.name
        if any(p.is_relative_to(target) for p in inputs) or any(
                target.is_relative_to(p) for p in inputs[1:]):
            raise InputError(out_dir, f"output {target} would overwrite the input capture(s); "
                                      "choose an --out outside CAPTURES_DIR's captures")
    check_batch_folder(given)
    check_writable_folder(given)  # before the cluster starts, not a traceback at the first write


def check_batch_folder(out_dir):
    """InputError unless OUT_DIR is missing, empty, or holds only what a batch writes: its
    summary and logs, captures' output folders (a `run` output: safety.MARKER, or MARKER) and
    hidden staging folders."""
    out_dir = Path(out_dir)
    if not out_dir.is_dir():
        return
    for entry in sorted(out_dir.iterdir()):
        if entry.name in SUMMARY_HEADS:  # a summary is ours if it starts as write_summary writes
            ours = entry.is_file() and any(_starts_with(entry, head)
                                           for head in SUMMARY_HEADS[entry.name])
        else:
            ours = entry.name.startswith(".") or (entry.is_dir() and (
                entry.name == LOG_DIR or (entry / MARKER).is_file() or
                (entry / RUN_MARKER).is_file()))
        if not ours:
            raise InputError(out_dir, f"holds {entry.name}, which no flashbrdf batch made; "
                                      "refusing to write into someone's folder (give a new or "
                                      "empty --out)")


def _starts_with(path, head):
    try:
        with open(path, "rb") as f:
            return f.read(len(head)) == head
    except OSError:
        return False


def _reason(err):
    from distributed import KilledWorker
    if isinstance(err, KilledWorker):
        return (f"the worker died while running it, {dask_engine.ALLOWED_FAILURES + 1} times "
                "(KilledWorker)")
    text = str(err).strip().splitlines()
    return f"{type(err).__name__}: {text[0] if text else ''}".rstrip(": ")


def capture_bytes(capture_dir):
    """Bytes of the files in a capture folder (int): its photos dominate, and a capture's run
    time grows with its pixels and photos, so this orders the captures largest first."""
    return sum(p.stat().st_size for p in Path(capture_dir).rglob("*") if p.is_file())


@contextlib.contextmanager
def _progress(total):
    """Yield done(name, row), called as each capture finishes: a progress bar over captures on a
    terminal, else one line per capture on stderr."""
    from tqdm import tqdm
    finished = 0
    with tqdm(total=total, unit="capture", file=sys.stderr,
              disable=not sys.stderr.isatty()) as bar:
        def done(name, row):
            nonlocal finished
            finished += 1
            bar.set_postfix_str(f"{name}: {row['status']}")
            bar.update(1)
            if bar.disable:
                print(f"[{finished}/{total}] {name}: {row['status']}", file=sys.stderr,
                      flush=True)
        yield done


def _run_tasks(client, todo, out_dir, options):
    """Submit one task per capture, the largest first (a large one started last would leave
    the other workers idle at the end); -> {name: row} as they finish, with a progress bar."""
    from distributed import as_completed
    token = uuid.uuid4().hex[:8]
    # Absolute paths (not resolved: a symlinked capture keeps its name): workers elsewhere see
    # the same shared filesystem, not our working directory.
    futures = {client.submit(run_capture, str(c.absolute()), str(Path(out_dir).absolute()),
                             options, retries=1, pure=False, priority=capture_bytes(c),
                             key=f"batch-{c.name}-{token}"): c.name for c in todo}
    rows = {}
    with _progress(len(futures)) as done:
        # On this client's loop: the user (or a test) may hold another client in this process.
        for future in as_completed(futures, loop=client.loop):
            name = futures.pop(future)
            try:
                rows[name] = future.result()
            except Exception as err:  # the task failed twice, or its worker died twice
                rows[name] = failed_row(name, _reason(err))
            # Let the worker drop the result: a result still held would be recomputed (the
            # capture run again) if that worker died later.
            future.release()
            done(name, rows[name])
    return rows


def _run_here(capture, out_dir, options):
    """A batch of one capture, in this process: the task of _run_tasks, retried once if it
    raises (as Dask's retries=1), with the threads of a one-worker local cluster (every core);
    -> {name: row}. A local cluster's start and close cost seconds of CPU (client and worker
    each import distributed): +12.7 s of wall over one `run` of the sample capture at load ~4,
    against +0.8 s this way (benchmarks/results/batch_speed.md)."""
    threads = str(dask_engine.threads_per_worker(1))
    before = os.environ.get("FLASHBRDF_THREADS")
    os.environ["FLASHBRDF_THREADS"] = threads  # read by worker_threads, as in a local worker
    try:
        with _progress(1) as done:
            for _ in range(2):
                try:
                    row = run_capture(str(capture.absolute()), str(Path(out_dir).absolute()),
                                      options)
                    break
                except Exception as err:  # failed twice: recorded as failed, as on Dask
                    row = failed_row(capture.name, _reason(err))
            done(capture.name, row)
    finally:
        if before is None:
            os.environ.pop("FLASHBRDF_THREADS", None)
        else:
            os.environ["FLASHBRDF_THREADS"] = before
    return {capture.name: row}


def _check_options_on(client, options):
    """check_run_options(options) as a task on `client`'s cluster; InputError raised here if
    they are bad. InputError does not survive pickling (its constructor takes two arguments),
    so the task returns it as text."""
    checked = client.submit(check_run_options, options, pure=False, retries=0,
                            key=f"batch-options-{uuid.uuid4().hex[:8]}", as_text=True).result()
    if isinstance(checked, tuple):
        raise InputError(*checked)
    return checked


def _prepare(out, captures, held):
    """Make OUT_DIR, hold it for this batch (held: a contextlib.ExitStack that keeps it until
    the batch ends), and remove what a batch killed earlier left there for these captures."""
    out.mkdir(parents=True, exist_ok=True)
    # Two batches in one OUT_DIR at once took each other's staging folders for a killed
    # batch's leftovers and removed them under each other (here and at the end)
    held.enter_context(sole_writer(out, "another flashbrdf batch is writing into it; let it "
                                        "finish (a rerun then skips what it completed) or give "
                                        "another --out"))
    for c in captures:
        for leftover in _leftovers(out, c.name):
            shutil.rmtree(leftover, ignore_errors=True)
    return True


def batch(captures_dir, out, *, workers=None, scheduler=None, force=False, model=None,
          methods="dsgplvm", spp=64, anchor=True, materials="auto", albedo_map=False,
          export=False, envmap=None, refine_poses=False):
    """`flashbrdf batch`: `run` on every capture of captures_dir into out/<capture>/, and the
    summary. Returns the exit status: 0 all ok, 1 any failed."""
    captures = find_captures(captures_dir)
    dask_engine.check_engine_options(workers, scheduler)
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise InputError(out, "exists and is not a folder")
    _check_outputs(out, captures_dir, captures)
    # Absolute paths (not resolved: a symlinked file keeps its name): workers elsewhere see the
    # same shared filesystem, not our working directory.
    options = {"model": None if model is None else str(Path(model).absolute()),
               "methods": methods, "spp": spp, "no_anchor": not anchor, "materials": materials,
               "albedo_map": bool(albedo_map), "export": bool(export),
               "envmap": None if envmap is None else str(Path(envmap).absolute()),
               "refine_poses": bool(refine_poses)}
    requested = dict(options)  # what a capture's output depends on, as asked
    rows, todo = {}, []
    for c in captures:
        row = None if force else completed_row(out / c.name, requested,
                                                lambda c=c: inputs_fingerprint(c, options))
        if row is not None:
            row["reason"] = "complete from an earlier batch: skipped (--force reruns it)"
            rows[c.name] = row
        else:
            todo.append(c)
    in_process = len(todo) == 1 and not scheduler  # see _run_here
    if in_process or not todo:
        options = check_run_options(options)
    start = time.perf_counter()
    n_workers, every_task_ended, prepared = 0, False, False
    held = contextlib.ExitStack()  # OUT_DIR's lock (_prepare), until the summary is written
    try:
        if in_process or not todo:  # nothing to run: the summary is still this batch's
            prepared = _prepare(out, captures, held)
        if in_process:
            n_workers = 1
            rows |= _run_here(todo[0], out, options | {"requested": requested})
        elif todo:
            # Never more local workers than captures to run: a spare worker would cost its
            # start-up and hold cores the busy ones' render threads can use.
            local = None if scheduler else min(workers or os.cpu_count() or 1, len(todo))
            with dask_engine.dask_client(local, scheduler) as client:
                # run's option checks import every stage (seconds); a worker imports them for
                # its first capture anyway, so they run there, before any output is written.
                options = _check_options_on(client, options)
                prepared = _prepare(out, captures, held)
                n_workers = len(client.scheduler_info().get("workers", {}))
                rows |= _run_tasks(client, todo, out, options | {"requested": requested})
        every_task_ended = True
    finally:
        # a killed worker leaves its staging folders: removed here when the cluster was ours
        # (closed now) or every task has ended; after an interrupt a remote scheduler's workers
        # may still be writing theirs, so those are left to the next batch (_prepare). The
        # markers' file lists guard against what a race would still leave.
        # (only while this batch holds OUT_DIR: else they are another batch's, still running)
        for c in todo if prepared and (every_task_ended or not scheduler) else ():
            for leftover in _leftovers(out, c.name):
                shutil.rmtree(leftover, ignore_errors=True)
        if not every_task_ended:
            held.close()  # an interrupt: no summary follows
    ordered = [rows[c.name] for c in captures]
    failed = [r for r in ordered if r["status"] != "ok"]
    engine = scheduler or (
        "the batch's own process (one capture to run: no cluster)" if in_process
        else f"a local cluster of {n_workers} worker process(es)")
    with held:  # OUT_DIR's lock, released once the summary is written (or fails to be)
        write_summary(out, ordered, [
            f"- {len(ordered)} capture(s) in `{captures_dir}`: {len(ordered) - len(failed)} ok "
            f"({len(captures) - len(todo)} skipped as complete), {len(failed)} failed.",
            f"- Ran on {engine if todo else 'nothing (all complete)'}; "
            f"wall time {time.perf_counter() - start:.1f} s.",
            f"- Run options: methods {methods}, spp {spp}, model "
            f"{options['model'] or '(none)'}{', no anchor' if not anchor else ''}"
            f"{', export' if options['export'] else ''}.",
            f"- Per-capture logs: `{LOG_DIR}/<capture>.log`. ΔE-log is `delta_e_log_mean` of "
            "each method's renders against the reference photos (mean over photos, then per "
            "photo)."],
            methods=dict.fromkeys(m.strip() for m in methods.split(",") if m.strip()))
    for r in failed:
        print(f"flashbrdf batch: {r['capture']} failed: {r['reason']}", file=sys.stderr)
    print(f"summary: {(out / 'summary.md').resolve()}")
    return 1 if failed else 0
