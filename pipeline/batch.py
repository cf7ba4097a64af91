"""`flashbrdf batch CAPTURES_DIR --out OUT_DIR [--workers N] [--scheduler ADDRESS] [run options]`.

Every subfolder of CAPTURES_DIR that holds a scene.json is one capture. Each capture is one Dask
task that calls `run` in the worker process (pipeline/cmd_run.py, the same function as
`flashbrdf run`), so OUT_DIR/<subfolder>/ is exactly what `run` writes, plus the completion marker.

All or nothing per capture: the task builds the capture in a hidden staging folder inside OUT_DIR
(`.<subfolder>.partial-<id>`), writes the marker `.batch_complete.json` (its summary row) last, and
renames the folder into place. A capture is complete when OUT_DIR/<subfolder>/ holds a readable marker; a
second call skips complete captures unless --force. Staging folders left by a killed worker are
removed by the client when the batch ends (and at the start of the next batch).

A task that raises is retried once by Dask (retries=1), and a task whose worker dies is retried
once on another worker (dask_engine.ALLOWED_FAILURES); then the capture is recorded as failed. Bad
input in one capture (InputError) is recorded as failed at once, since a retry would fail the same.

Each worker process reads the model once (cached on path, size and mtime) and keeps it for its
next captures. A local cluster has at most one worker per capture to run, and shares the cores
out between its workers (dask_engine); the largest captures are submitted with the highest
priority, so that the last one to finish is a small one. What `run` prints goes to OUT_DIR/logs/<subfolder>.log, not to the terminal; the
terminal shows one progress bar over captures. OUT_DIR/summary.csv and summary.md give one row per
capture. Exit 0 when all succeeded, 1 when any failed, 2 when CAPTURES_DIR holds no capture.
"""

import argparse
import contextlib
import csv
import io
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

from brdf.atomic import write_text
from brdf.errors import InputError
from pipeline import dask_engine

MARKER = ".batch_complete.json"
LOG_DIR = "logs"
SUMMARY_FIELDS = ("capture", "status", "reason", "seconds", "cpu_seconds", "worker")
RUN_OPTIONS = ("model", "methods", "spp", "no_anchor", "materials", "albedo_map")


def find_captures(captures_dir):
    """Sorted subfolders of `captures_dir` that hold a scene.json ([Path]); InputError if none."""
    folder = Path(captures_dir)
    if not folder.is_dir():
        raise InputError(captures_dir, "not a folder")
    captures = sorted(p for p in folder.iterdir() if p.is_dir() and (p / "scene.json").is_file())
    if not captures:
        raise InputError(captures_dir, "no capture: no subfolder holds a scene.json")
    return captures


def completed_row(folder):
    """The summary row in `folder`'s marker when a batch finished it, else None (no marker, or
    one that cannot be read: the capture is run again)."""
    try:
        row = json.loads((Path(folder) / MARKER).read_text())
    except (OSError, ValueError):
        return None
    return row if isinstance(row, dict) and row.get("status") == "ok" else None


def _leftovers(out_dir, name):
    """Hidden folders a batch leaves for capture `name` if its worker is killed: the staging
    folder (`.<name>.partial-<id>`), `run`'s own temporary folder beside it (`run` builds the
    staging folder as `..<name>.partial-<id>.<random>.part`, see safety.staged_output_dir, so a
    worker killed mid-run leaves that one) and a replaced output (`.<name>.old-<id>`)."""
    out_dir = Path(out_dir)
    patterns = (f".{name}.partial-*", f"..{name}.partial-*", f".{name}.old-*")
    return [p for pattern in patterns for p in out_dir.glob(pattern)]


def _repoint(staging, target):
    """slice.json names its slice.csv by absolute path: make it the final one, as `run` into
    `target` would have written it."""
    report_path = Path(staging) / "slice.json"
    if report_path.is_file():
        report = json.loads(report_path.read_text())
        if str(report.get("slice_csv", "")).startswith(str(Path(staging).resolve())):
            report["slice_csv"] = str(Path(target).resolve() / "slice.csv")
            write_text(report_path, json.dumps(report, indent=1) + "\n")


def _publish(staging, target):
    """Rename the finished `staging` folder to `target`, replacing an earlier output there."""
    target = Path(target)
    _repoint(staging, target)
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
    """cmd_run's _load_methods, read once per worker process: cached on the model file's path,
    size and modification time (a retrained model is read again), the method names and anchor."""
    from pipeline.cmd_run import _load_methods
    stat = None if model_path is None else Path(model_path).stat()
    key = (None if model_path is None else str(Path(model_path).resolve()),
           None if stat is None else (stat.st_size, stat.st_mtime_ns), tuple(names), bool(anchor))
    with _MODELS_LOCK:
        if key not in _MODELS:
            print(f"model: reading {model_path} in worker process {os.getpid()}", file=sys.stderr)
            _MODELS.clear()  # one model at a time: a worker serves one batch
            _MODELS[key] = _load_methods(names, model_path, anchor)
        else:
            print(f"model: already read by worker process {os.getpid()}", file=sys.stderr)
        return _MODELS[key]


class _ThreadOutput(io.TextIOBase):
    """A stand-in for sys.stdout / sys.stderr that sends each thread's text to that thread's log
    file, if it has one (a worker may run several tasks on threads at once)."""

    def __init__(self, fallback):
        self.fallback, self.local = fallback, threading.local()

    def write(self, text):
        target = getattr(self.local, "file", None) or self.fallback
        return target.write(text)

    def flush(self):
        (getattr(self.local, "file", None) or self.fallback).flush()

    def isatty(self):
        return False


_ROUTING_LOCK = threading.Lock()


@contextlib.contextmanager
def _output_to(log_file):
    """Send this thread's stdout and stderr to `log_file` (appended) inside the block."""
    with _ROUTING_LOCK:
        for stream in ("stdout", "stderr"):
            if not isinstance(getattr(sys, stream), _ThreadOutput):
                setattr(sys, stream, _ThreadOutput(getattr(sys, stream)))
    Path(log_file).parent.mkdir(parents=True, exist_ok=True)
    with open(log_file, "a", encoding="utf-8", buffering=1) as f:
        sys.stdout.local.file = sys.stderr.local.file = f
        try:
            yield f
        finally:
            sys.stdout.local.file = sys.stderr.local.file = None


def _row_from_report(name, report, seconds, cpu_seconds, worker):
    """The summary row of one finished capture from its report.json (dict). seconds: wall;
    cpu_seconds: the worker process's CPU time (user + system) over the capture, which a loaded
    machine does not inflate as it does the wall time."""
    row = {"capture": name, "status": "ok", "reason": "", "seconds": round(seconds, 3),
           "cpu_seconds": round(cpu_seconds, 3), "worker": worker, "delta_e_log": {}}
    for method, s in report.get("summary", {}).items():
        row["delta_e_log"][method] = s.get("delta_e_log_mean", {}).get("mean")
    for r in report.get("references", []):
        row["delta_e_log"][f"{r['method']}/{r['photo']}"] = r.get("delta_e_log_mean")
    return row


def failed_row(name, reason, seconds=None, worker=""):
    """The summary row of a failed capture; `reason` is cut to its first line."""
    lines = str(reason).strip().splitlines()
    return {"capture": name, "status": "failed", "reason": lines[0] if lines else "failed",
            "seconds": None if seconds is None else round(seconds, 3), "cpu_seconds": None,
            "worker": worker,
            "delta_e_log": {}}


def run_capture(scene_dir, out_dir, options):
    """The Dask task: `run` one capture into OUT_DIR/<name>/, all or nothing. -> summary row dict.

    options: the run options (RUN_OPTIONS: model, methods, spp, no_anchor, materials,
    albedo_map). Raises on unexpected errors (Dask
    retries once); bad input in the capture is returned as a failed row.
    """
    from pipeline.cmd_run import run
    name = Path(scene_dir).name
    out_dir = Path(out_dir)
    worker = f"{socket.gethostname()}:{os.getpid()}"
    staging = out_dir / f".{name}.partial-{uuid.uuid4().hex[:8]}"
    start, cpu_start = time.perf_counter(), time.process_time()
    with _output_to(out_dir / LOG_DIR / f"{name}.log") as log, \
            dask_engine.worker_threads() as threads:
        print(f"--- {time.strftime('%Y-%m-%d %H:%M:%S')} {name}: started on {worker}, "
              f"{threads} thread(s)", file=log)
        try:
            run(argparse.Namespace(scene_dir=str(scene_dir), out=str(staging), **options),
                load_methods=cached_load_methods)
            seconds = time.perf_counter() - start
            report = json.loads((staging / "report.json").read_text())
            row = _row_from_report(name, report, seconds, time.process_time() - cpu_start,
                                   worker)
            write_text(staging / MARKER, json.dumps(row, indent=1) + "\n")
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
    """InputError if an output folder OUT_DIR/<name> would be, or hold, an input."""
    out_dir, captures_dir = Path(out_dir).resolve(), Path(captures_dir).resolve()
    inputs = [captures_dir] + [c.resolve() for c in captures]
    for c in captures:
        target = out_dir / c.name
        if any(p.is_relative_to(target) for p in inputs) or any(
                target.is_relative_to(p) for p in inputs[1:]):
            raise InputError(out_dir, f"output {target} would overwrite the input capture(s); "
                                      "choose an --out outside CAPTURES_DIR's captures")


def _reason(err):
    from distributed import KilledWorker
    if isinstance(err, KilledWorker):
        return (f"the worker died while running it, {dask_engine.ALLOWED_FAILURES + 1} times "
                "(KilledWorker)")
    text = str(err).strip().splitlines()
    return f"{type(err).__name__}: {text[0] if text else ''}".rstrip(": ")


def _columns(rows):
    """ΔE-log columns in first-seen order: each method's mean, then method/photo."""
    keys = list(dict.fromkeys(k for r in rows for k in r["delta_e_log"]))
    return [k for k in keys if "/" not in k] + [k for k in keys if "/" in k]


def _cell(value):
    if value is None:
        return ""
    return f"{value:.6g}" if isinstance(value, float) else str(value)


def write_summary(out_dir, rows, header_lines=()):
    """OUT_DIR/summary.csv and summary.md, one row per capture (atomic writes)."""
    columns = _columns(rows)
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(list(SUMMARY_FIELDS) + [f"delta_e_log {c}" for c in columns])
    for r in rows:
        writer.writerow([r.get(f) if r.get(f) is not None else "" for f in SUMMARY_FIELDS]
                        + [repr(r["delta_e_log"][c]) if r["delta_e_log"].get(c) is not None
                           else "" for c in columns])
    write_text(Path(out_dir) / "summary.csv", buffer.getvalue())
    head = list(SUMMARY_FIELDS) + [f"ΔE-log {c}" for c in columns]
    lines = ["# flashbrdf batch summary", "", *header_lines, "",
             "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        cells = [_cell(r.get(f)).replace("|", "\\|") for f in SUMMARY_FIELDS]
        cells += [_cell(r["delta_e_log"].get(c)) for c in columns]
        lines.append("| " + " | ".join(cells) + " |")
    write_text(Path(out_dir) / "summary.md", "\n".join(lines) + "\n")


def capture_bytes(capture_dir):
    """Bytes of the files in a capture folder (int): its photos dominate, and a capture's run
    time grows with its pixels and photos, so this orders the captures largest first."""
    return sum(p.stat().st_size for p in Path(capture_dir).rglob("*") if p.is_file())


def _run_tasks(client, todo, out_dir, options):
    """Submit one task per capture, the largest first (a large one started last would leave
    the other workers idle at the end); -> {name: row} as they finish, with a progress bar."""
    from distributed import as_completed
    from tqdm import tqdm
    token = uuid.uuid4().hex[:8]
    # Absolute paths (not resolved: a symlinked capture keeps its name): workers elsewhere see
    # the same shared filesystem, not our working directory.
    futures = {client.submit(run_capture, str(c.absolute()), str(Path(out_dir).absolute()),
                             options, retries=1, pure=False, priority=capture_bytes(c),
                             key=f"batch-{c.name}-{token}"): c.name for c in todo}
    rows = {}
    total = len(futures)
    with tqdm(total=total, unit="capture", file=sys.stderr,
              disable=not sys.stderr.isatty()) as bar:
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
            bar.set_postfix_str(f"{name}: {rows[name]['status']}")
            bar.update(1)
            if bar.disable:
                print(f"[{len(rows)}/{total}] {name}: {rows[name]['status']}",
                      file=sys.stderr, flush=True)
    return rows


def batch(args):
    from pipeline.cmd_render import samples_per_pixel
    from pipeline.cmd_run import _methods, _model_path
    captures = find_captures(args.captures_dir)
    dask_engine.check_engine_options(args)
    methods = _methods(args.methods)
    model = _model_path(args, methods)
    samples_per_pixel(args)
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise InputError(out, "exists and is not a folder")
    _check_outputs(out, args.captures_dir, captures)
    options = {"model": None if model is None else str(model.resolve()), "methods": args.methods,
               "spp": args.spp, "no_anchor": args.no_anchor,
               "materials": getattr(args, "materials", "auto"),
               "albedo_map": bool(getattr(args, "albedo_map", False))}

    start = time.perf_counter()
    out.mkdir(parents=True, exist_ok=True)
    for c in captures:
        for leftover in _leftovers(out, c.name):
            shutil.rmtree(leftover, ignore_errors=True)
    rows, todo = {}, []
    for c in captures:
        row = None if args.force else completed_row(out / c.name)
        if row is not None:
            row["reason"] = "complete from an earlier batch: skipped (--force reruns it)"
            rows[c.name] = row
        else:
            todo.append(c)
    if todo:
        try:
            # Never more local workers than captures to run: a spare worker would cost its
            # start-up and hold cores the busy ones' render threads can use.
            workers = None if args.scheduler else min(args.workers or os.cpu_count() or 1,
                                                      len(todo))
            with dask_engine.dask_client(workers, args.scheduler) as client:
                n_workers = len(client.scheduler_info().get("workers", {}))
                rows |= _run_tasks(client, todo, out, options)
        finally:
            for c in todo:  # a killed worker leaves its staging folder
                for leftover in _leftovers(out, c.name):
                    shutil.rmtree(leftover, ignore_errors=True)
    else:
        n_workers = 0
    ordered = [rows[c.name] for c in captures]
    failed = [r for r in ordered if r["status"] != "ok"]
    engine = args.scheduler or f"a local cluster of {n_workers} worker process(es)"
    write_summary(out, ordered, [
        f"- {len(ordered)} capture(s) in `{args.captures_dir}`: {len(ordered) - len(failed)} ok "
        f"({len(captures) - len(todo)} skipped as complete), {len(failed)} failed.",
        f"- Ran on {engine if todo else 'nothing (all complete)'}; "
        f"wall time {time.perf_counter() - start:.1f} s.",
        f"- Run options: methods {args.methods}, spp {args.spp}, model "
        f"{options['model'] or '(none)'}{', no anchor' if args.no_anchor else ''}.",
        f"- Per-capture logs: `{LOG_DIR}/<capture>.log`. ΔE-log is `delta_e_log_mean` of each "
        "method's renders against the reference photos (mean over photos, then per photo)."])
    for r in failed:
        print(f"flashbrdf batch: {r['capture']} failed: {r['reason']}", file=sys.stderr)
    print(f"summary: {(out / 'summary.md').resolve()}")
    return 1 if failed else 0
