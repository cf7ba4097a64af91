"""`flashbrdf batch` and `evaluate --workers` against their sequential forms (a benchmark).

Parts (each merges its numbers into benchmarks/results/batch_speed.json, then batch_speed.md is
rewritten from the JSON):
- batch:    N captures of the sample's size (copies of sample_data/capture, 256², both reference
            photos) as N sequential `flashbrdf run` processes (a shell loop), then as
            `flashbrdf batch --workers 2`; speed-up and the largest ΔE difference. Then a batch of
            1 capture against one `run`: the overhead of the cluster.
- cluster:  a simulated cluster on this host, `dask scheduler` plus W `dask worker --nthreads 1`
            processes (W = 1, 2, 4), `flashbrdf batch --scheduler`; speed-up against 1 worker.
- table1:   a reduced Table 1 protocol (--experiments K, 2D only) in a loop and on
            `--workers 2`; the ratio of wall times and the largest difference in any number.
The machine's load average is recorded before and after each measurement: it is shared.

    nice -n 10 python benchmarks/batch_speed.py --part batch --captures 8
    nice -n 10 python benchmarks/batch_speed.py --part cluster --captures 8
    nice -n 10 python benchmarks/batch_speed.py --part table1 --merl-dir /work/data/merl \
        --experiments 4 --materials 40
"""

import argparse
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
RESULTS = REPO / "benchmarks" / "results"
SAMPLE = REPO / "sample_data" / "capture"
SHARED = Path(os.environ.get("FLASHBRDF_SHARED", REPO.parent / "shared"))
FLASHBRDF = [sys.executable, "-m", "pipeline"]


def _load():
    return [round(x, 2) for x in os.getloadavg()]


def _timed(cmd, **kwargs):
    """Run `cmd` (list) to completion: -> wall seconds; raises on a non-zero exit."""
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, cwd=REPO, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL, **kwargs)
    return time.perf_counter() - t0


def _captures(folder, n):
    """`n` capture folders under `folder`, each a copy of the sample capture (its envmaps are
    named relative to the scene folder, so the copies sit at the sample's depth)."""
    folder.mkdir(parents=True, exist_ok=True)
    for i in range(n):
        target = folder / f"capture{i:02d}"
        if not target.exists():
            shutil.copytree(SAMPLE, target)
            scene = json.loads((SAMPLE / "scene.json").read_text())
            _absolute_files(scene)
            (target / "scene.json").write_text(json.dumps(scene, indent=2))
    return sorted(folder.iterdir())


def _absolute_files(node):
    """Make the scene's paths that leave the sample folder ("../...") absolute, in place."""
    if isinstance(node, dict):
        for key, value in node.items():
            if key == "file" and isinstance(value, str) and value.startswith(".."):
                node[key] = str((SAMPLE / value).resolve())
            else:
                _absolute_files(value)
    elif isinstance(node, list):
        for item in node:
            _absolute_files(item)


def _delta_e(out):
    report = json.loads((Path(out) / "report.json").read_text())
    return {(r["method"], r["photo"]): r["delta_e_log_mean"] for r in report["references"]}


def part_batch(work, n):
    captures = _captures(work / "captures", n)
    seq_out = work / "sequential"
    load = {"before": _load()}
    seq_s = []
    for c in captures:
        seq_s.append(_timed(FLASHBRDF + ["run", str(c), "--out", str(seq_out / c.name)]))
    load["after_sequential"] = _load()
    batch_out = work / "batch"
    batch_s = _timed(FLASHBRDF + ["batch", str(work / "captures"), "--out", str(batch_out),
                                  "--workers", "2"])
    load["after_batch"] = _load()
    diff = max(abs(_delta_e(batch_out / c.name)[k] - v)
               for c in captures for k, v in _delta_e(seq_out / c.name).items())
    one = work / "one"
    _captures(one, 1)
    run_s = _timed(FLASHBRDF + ["run", str(one / "capture00"), "--out", str(work / "one_run")])
    one_batch_s = _timed(FLASHBRDF + ["batch", str(one), "--out", str(work / "one_batch"),
                                      "--workers", "1"])
    load["after_overhead"] = _load()
    return {"captures": n, "capture": "sample_data/capture copies (256², 2 reference photos), "
                                      "default run options (dsgplvm, 64 spp)",
            "sequential_runs_s": round(sum(seq_s), 1), "per_run_s": [round(s, 1) for s in seq_s],
            "batch_workers2_s": round(batch_s, 1), "speedup": round(sum(seq_s) / batch_s, 2),
            "max_abs_delta_e_difference": diff,
            "overhead": {"run_s": round(run_s, 1), "batch_of_1_s": round(one_batch_s, 1),
                         "extra_s": round(one_batch_s - run_s, 1)},
            "load_average": load}


def part_cluster(work, n, worker_counts=(1, 2, 4)):
    _captures(work / "captures", n)
    out = {}
    for w in worker_counts:
        port = 8786 + 10 + w
        procs = [subprocess.Popen(["dask", "scheduler", "--port", str(port), "--no-dashboard"],
                                  stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                  start_new_session=True)]
        try:
            time.sleep(3)
            procs += [subprocess.Popen(["dask", "worker", f"tcp://127.0.0.1:{port}", "--nthreads",
                                        "1", "--no-dashboard"], stdout=subprocess.DEVNULL,
                                       stderr=subprocess.DEVNULL, start_new_session=True)
                      for _ in range(w)]
            time.sleep(5)
            load = _load()
            seconds = _timed(FLASHBRDF + ["batch", str(work / "captures"), "--out",
                                          str(work / f"cluster{w}"), "--scheduler",
                                          f"tcp://127.0.0.1:{port}"])
            out[str(w)] = {"seconds": round(seconds, 1), "load_before": load,
                           "load_after": _load()}
        finally:
            for p in reversed(procs):
                os.killpg(p.pid, signal.SIGTERM)
            for p in procs:
                p.wait(timeout=60)
    base = out[str(worker_counts[0])]["seconds"]
    for w in out:
        out[w]["speedup_vs_1"] = round(base / out[w]["seconds"], 2)
    return {"captures": n, "cores": os.cpu_count(), "workers": out}


def _numbers(value, path=""):
    if isinstance(value, dict):
        return {k: v for key, item in value.items() for k, v in _numbers(item, f"{path}/{key}").items()}
    if isinstance(value, list):
        return {k: v for i, item in enumerate(value) for k, v in _numbers(item, f"{path}/{i}").items()}
    return {path: value}


def part_table1(work, merl_dir, k, materials):
    """run_evaluation in this process (2D only), in a loop and on a 2-worker local cluster."""
    sys.path.insert(0, str(REPO))
    from experiments.evaluate import run_evaluation
    from pipeline.dask_engine import dask_client
    subset = work / "merl"
    subset.mkdir()
    for path in sorted(Path(merl_dir).glob("*.binary"))[:materials]:
        (subset / path.name).symlink_to(path.resolve())
    load = {"before": _load()}
    t0 = time.perf_counter()
    run_evaluation(subset, work / "t1_loop", experiments=k, experiments_3d=0)
    seq_s = time.perf_counter() - t0
    load["after_loop"] = _load()
    t0 = time.perf_counter()
    with dask_client(workers=2) as client:
        run_evaluation(subset, work / "t1_dask", experiments=k, experiments_3d=0, client=client)
    par_s = time.perf_counter() - t0
    load["after_dask"] = _load()
    a, b = (json.loads((work / d / "table1.json").read_text()) for d in ("t1_loop", "t1_dask"))
    worst, choices_equal = 0.0, True
    for key in ("summary", "per_experiment", "ablations", "hyperparameters"):
        na, nb = _numbers(a[key]), _numbers(b[key])
        for path, v in na.items():
            if isinstance(v, float):
                worst = max(worst, abs(v - nb[path]))
            elif v != nb.get(path):
                choices_equal = False
    return {"experiments": k, "materials": materials,
            "note": f"the first {materials} MERL (NBRDF proxy) tables by name, 2D metrics only "
                    "(3D metrics take ~15 min an experiment here); run_evaluation in-process, "
                    "the loop vs a 2-worker local cluster",
            "loop_s": round(seq_s, 1), "workers2_s": round(par_s, 1),
            "ratio": round(par_s / seq_s, 3), "max_abs_difference": worst,
            "same_choices_and_names": choices_equal, "load_average": load}


def write_markdown(result):
    lines = ["# `flashbrdf batch` and `evaluate --workers` (benchmark)", "",
             "Made by `benchmarks/batch_speed.py` (commands in its docstring) on "
             f"{os.cpu_count()} cores shared with other jobs: load averages are given "
             "(1, 5, 15 min).", ""]
    for b in (result.get(k) for k in ("batch", "batch_earlier")):
        if not b:
            continue
        o = b["overhead"]
        lines += [f"## {b['captures']} captures, `--workers 2` against {b['captures']} "
                  "sequential `run`s", "",
                  f"- Captures: {b['capture']}.",
                  f"- Sequential: {b['sequential_runs_s']} s; batch: {b['batch_workers2_s']} s: "
                  f"**{b['speedup']}×** (target ≥ 1.6×).",
                  f"- Largest |ΔE-log difference| batch vs sequential: "
                  f"{b['max_abs_delta_e_difference']:.3g} (target ≤ 1e-9).",
                  f"- Overhead: a batch of 1 took {o['batch_of_1_s']} s, one `run` "
                  f"{o['run_s']} s: {o['extra_s']} s more (target ≤ 5 s).",
                  f"- Load average: {b['load_average']}.", ""]
    c = result.get("cluster")
    if c:
        lines += [f"## Simulated cluster: `dask scheduler` + W `dask worker --nthreads 1` on this "
                  f"{c['cores']}-core host, {c['captures']} captures", "",
                  "| workers | seconds | speed-up vs 1 | load before |", "|---|---|---|---|"]
        lines += [f"| {w} | {v['seconds']} | {v['speedup_vs_1']} | {v['load_before']} |"
                  for w, v in c["workers"].items()]
        lines += ["", "Past the core count the curve flattens here; on a cluster each worker "
                  "brings its own core.", ""]
    t = result.get("table1")
    if t:
        lines += [f"## Table 1, reduced: {t['experiments']} experiments", "",
                  f"- {t['note']}.",
                  f"- Loop: {t['loop_s']} s; `--workers 2`: {t['workers2_s']} s: ratio "
                  f"**{t['ratio']}** (target ≤ 0.6 on the full protocol).",
                  f"- Largest difference in any number: {t['max_abs_difference']:.3g}; same "
                  f"choices and names: {t['same_choices_and_names']}.",
                  f"- Load average: {t['load_average']}.", ""]
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--part", required=True, choices=["batch", "cluster", "table1"])
    ap.add_argument("--captures", type=int, default=8)
    ap.add_argument("--merl-dir", default="/work/data/merl")
    ap.add_argument("--experiments", type=int, default=4)
    ap.add_argument("--materials", type=int, default=100, help="table1: the first M tables")
    ap.add_argument("--work", help="scratch folder (default: a temp folder, removed)")
    args = ap.parse_args(argv)
    RESULTS.mkdir(parents=True, exist_ok=True)
    json_path = RESULTS / "batch_speed.json"
    result = json.loads(json_path.read_text()) if json_path.exists() else {}
    with tempfile.TemporaryDirectory(dir=args.work) as tmp:
        work = Path(tmp)
        if args.part == "batch":
            if "batch" in result:  # the earlier measurement stays in the record
                result["batch_earlier"] = result["batch"]
            result["batch"] = part_batch(work, args.captures)
        elif args.part == "cluster":
            result["cluster"] = part_cluster(work, args.captures)
        else:
            result["table1"] = part_table1(work, args.merl_dir, args.experiments, args.materials)
    result.setdefault("commands", {})[args.part] = (
        "nice -n 10 python benchmarks/batch_speed.py " + " ".join(argv or sys.argv[1:]))
    json_path.write_text(json.dumps(result, indent=1) + "\n")
    (RESULTS / "batch_speed.md").write_text(write_markdown(result) + "\n")
    print(json.dumps(result[args.part], indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
