"""`flashbrdf batch` and `evaluate --workers` against their sequential forms (a benchmark).

Parts (each merges its numbers into benchmarks/results/batch_speed.json, then batch_speed.md is
rewritten from the JSON):
- batch:    N captures of the sample's size (copies of sample_data/capture, 256², both reference
            photos) as N sequential `flashbrdf run` processes (a shell loop), then as
            `flashbrdf batch --workers 2`; speed-up and the largest ΔE difference. Then a batch of
            1 capture against one `run`: the overhead of the cluster.
- overhead: only that last comparison, repeated (--repeats, default 3; the order of `run` and
            `batch` alternates), with each pair's load averages and CPU seconds; the medians.
- cluster:  a simulated cluster on this host, `dask scheduler` plus W `dask worker --nthreads 1`
            processes (W = 1, 2, 4), `flashbrdf batch --scheduler`; speed-up against 1 worker.
- table1:   a reduced Table 1 protocol (--experiments K, 2D only) in a loop and on
            `--workers 2`; the ratio of wall times and the largest difference in any number.
The machine's load average is recorded before and after each measurement: it is shared.

    nice -n 10 python -m benchmarks.batch_speed --part batch --captures 8
    nice -n 10 python -m benchmarks.batch_speed --part overhead --repeats 3
    nice -n 10 python -m benchmarks.batch_speed --part cluster --captures 8
    nice -n 10 python -m benchmarks.batch_speed --part table1 --merl-dir /work/data/merl \
        --experiments 4 --materials 40
"""

import argparse
import json
import math
import os
import statistics
import resource
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
FLASHBRDF = [sys.executable, "-m", "flashbrdf"]


def _load():
    return [round(x, 2) for x in os.getloadavg()]


def _children_cpu():
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _timed(cmd, cpu=None, **kwargs):
    """Run `cmd` (list) to completion: -> wall seconds; raises on a non-zero exit. `cpu`, a
    list, gets the CPU seconds (user + system) of the command and the processes it waited for
    (a local cluster's workers): unlike the wall time, they do not grow with the machine's load."""
    t0, c0 = time.perf_counter(), _children_cpu()
    subprocess.run(cmd, check=True, cwd=REPO, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL, **kwargs)
    if cpu is not None:
        cpu.append(_children_cpu() - c0)
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
    seq_s, seq_cpu, batch_cpu = [], [], []
    for c in captures:
        seq_s.append(_timed(FLASHBRDF + ["run", str(c), "--out", str(seq_out / c.name)],
                            cpu=seq_cpu))
    load["after_sequential"] = _load()
    batch_out = work / "batch"
    batch_s = _timed(FLASHBRDF + ["batch", str(work / "captures"), "--out", str(batch_out),
                                  "--workers", "2"], cpu=batch_cpu)
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
            "cpu_s": {"sequential_runs": round(sum(seq_cpu), 1), "batch": round(batch_cpu[0], 1),
                      "per_run": round(sum(seq_cpu) / len(seq_cpu), 1),
                      "batch_per_capture": round(batch_cpu[0] / n, 1)},
            "overhead": {"run_s": round(run_s, 1), "batch_of_1_s": round(one_batch_s, 1),
                         "extra_s": round(one_batch_s - run_s, 1)},
            "load_average": load}


def part_overhead(work, repeats):
    """A batch of 1 capture (`--workers 1`) against one `run` of it, `repeats` times, the order
    alternating (a load that drifts then favours neither); wall and CPU seconds of each."""
    one = work / "one"
    _captures(one, 1)
    pairs = []
    for i in range(repeats):
        pair = {"load_before": _load()}
        cpu = {"run": [], "batch": []}
        commands = {"run": FLASHBRDF + ["run", str(one / "capture00"), "--out",
                                        str(work / f"run{i}")],
                    "batch": FLASHBRDF + ["batch", str(one), "--out", str(work / f"batch{i}"),
                                          "--workers", "1"]}
        for name in (("run", "batch") if i % 2 == 0 else ("batch", "run")):
            pair[f"{name}_s"] = round(_timed(commands[name], cpu=cpu[name]), 2)
            pair[f"{name}_cpu_s"] = round(cpu[name][0], 2)
        pair["extra_s"] = round(pair["batch_s"] - pair["run_s"], 2)
        pair["extra_cpu_s"] = round(pair["batch_cpu_s"] - pair["run_cpu_s"], 2)
        pair["load_after"] = _load()
        pairs.append(pair)
    median = {k: round(statistics.median(p[k] for p in pairs), 2)
              for k in ("run_s", "batch_s", "extra_s", "run_cpu_s", "batch_cpu_s", "extra_cpu_s")}
    return {"capture": "a copy of sample_data/capture (256², 2 reference photos), default run "
                       "options (dsgplvm, 64 spp)", "pairs": pairs, "median": median}


# The README's worker set-up: Dask's nanny would set MALLOC_TRIM_THRESHOLD_ in its worker, which
# fixes glibc's mmap threshold and makes the renderer ~2x slower (see pipeline/dask_engine.py);
# a Dask config file unsets it (null), turns off the workers' statistical profiler (~1 s of CPU a
# capture), and the scheduler allows one worker death per task.
DASK_YAML = """distributed:
  nanny:
    pre-spawn-environ:
      MALLOC_TRIM_THRESHOLD_: null
  worker:
    profile:
      enabled: false
  scheduler:
    allowed-failures: 1
"""


def part_cluster(work, n, worker_counts=(1, 2, 4)):
    _captures(work / "captures", n)
    (work / "dask").mkdir(exist_ok=True)
    (work / "dask" / "flashbrdf.yaml").write_text(DASK_YAML)
    env = dict(os.environ, DASK_CONFIG=str(work / "dask"), OMP_NUM_THREADS="1",
               FLASHBRDF_THREADS="1")
    out = {}
    for w in worker_counts:
        port = 8786 + 10 + w
        procs = [subprocess.Popen(["dask", "scheduler", "--port", str(port), "--no-dashboard"],
                                  stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                  start_new_session=True, env=env)]
        try:
            time.sleep(3)
            procs += [subprocess.Popen(["dask", "worker", f"tcp://127.0.0.1:{port}", "--nthreads",
                                        "1", "--no-dashboard"], stdout=subprocess.DEVNULL,
                                       stderr=subprocess.DEVNULL, start_new_session=True, env=env)
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


def cluster_model(n, profile):
    """What a cluster would give a batch of n captures on W workers, each with its own core:
    start + ceil(n / W) x per-capture seconds, from the CPU seconds of run_profile.json (one
    worker process, 1 thread: the first capture, and each further one), which the load of this
    shared host does not inflate as it does wall times. start = the first capture's extra
    (imports, model read); Dask's own start-up (a few seconds) is left out.
    -> {"start_s", "per_capture_s", "predicted_speedup": {W: x}} for W up to 2n, or None."""
    if not profile or "one_worker_process" not in profile:
        return None
    first = profile["one_worker_process"]["first_capture"]["cpu_s"]
    per_capture = profile["one_worker_process"]["second_capture"]["cpu_s"]
    start = max(first - per_capture, 0.0)
    t1 = start + n * per_capture
    predicted = {w: round(t1 / (start + math.ceil(n / w) * per_capture), 2)
                 for w in (1, 2, 4, 8, 16) if w <= 2 * n}
    return {"start_s": round(start, 1), "per_capture_s": round(per_capture, 1),
            "predicted_speedup": predicted,
            "source": "benchmarks/results/run_profile.json"}


def write_cluster_plot(c, path):
    """Speed-up against workers: measured on this host, the cores' ceiling, the model's curve."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    measured = sorted((int(w), v["speedup_vs_1"]) for w, v in c["workers"].items())
    model = sorted((int(w), s) for w, s in c["model"]["predicted_speedup"].items())
    fig, ax = plt.subplots(figsize=(5.5, 4))
    top = max(s for _, s in model)
    ax.plot([w for w, _ in model], [w for w, _ in model], ":", color="grey", label="ideal (W×)")
    ax.plot([w for w, _ in model], [s for _, s in model], "--", color="tab:blue",
            label=f"cluster model: {c['model']['start_s']} s + ⌈{c['captures']}/W⌉ × "
                  f"{c['model']['per_capture_s']} s (CPU)")
    ax.plot([w for w, _ in measured], [s for _, s in measured], "o-", color="tab:red",
            label=f"measured, this {c['cores']}-core host (shared)")
    for w, speedup in measured:
        ax.annotate(f"load {c['workers'][str(w)]['load_before'][0]:.0f}", (w, speedup),
                    textcoords="offset points", xytext=(4, -12), fontsize=7, color="tab:red")
    ax.axhline(c["cores"], color="tab:red", lw=0.8, alpha=0.5)
    ax.text(1.05, c["cores"] * 1.03, f"{c['cores']} cores: the ceiling here", color="tab:red",
            fontsize=8)
    ax.set_xscale("log", base=2)
    ax.set_xticks([w for w, _ in model], [str(w) for w, _ in model])
    ax.set_ylim(0, top * 1.15)
    ax.set_xlabel("Dask workers (1 thread each)")
    ax.set_ylabel("speed-up against 1 worker")
    ax.set_title(f"flashbrdf batch, {c['captures']} captures of the sample's size", fontsize=10)
    ax.legend(fontsize=8, loc="upper left")
    fig.text(0.01, 0.01, "nice -n 10 python -m benchmarks.batch_speed --part cluster", fontsize=6,
             color="grey")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)




def part_table1(work, merl_dir, k, materials, k_3d=0):
    """run_evaluation in this process (k experiments, 3D metrics on k_3d of them), in a loop and
    on a 2-worker local cluster."""
    from flashbrdf.experiments.evaluate import run_evaluation
    from flashbrdf.experiments.table1_files import json_leaves
    from flashbrdf.pipeline.dask_engine import dask_client
    subset = work / "merl"
    subset.mkdir()
    for path in sorted(Path(merl_dir).glob("*.binary"))[:materials]:
        (subset / path.name).symlink_to(path.resolve())
    load = {"before": _load()}
    t0 = time.perf_counter()
    run_evaluation(subset, work / "t1_loop", experiments=k, experiments_3d=k_3d)
    seq_s = time.perf_counter() - t0
    load["after_loop"] = _load()
    t0 = time.perf_counter()
    with dask_client(workers=2) as client:
        run_evaluation(subset, work / "t1_dask", experiments=k, experiments_3d=k_3d,
                       client=client)
    par_s = time.perf_counter() - t0
    load["after_dask"] = _load()
    a, b = (json.loads((work / d / "table1.json").read_text()) for d in ("t1_loop", "t1_dask"))
    worst, choices_equal = 0.0, True
    for key in ("summary", "per_experiment", "ablations", "hyperparameters"):
        na, nb = json_leaves(a[key]), json_leaves(b[key])
        for path, v in na.items():
            if isinstance(v, float):
                worst = max(worst, abs(v - nb[path]))
            elif v != nb.get(path):
                choices_equal = False
    return {"experiments": k, "materials": materials, "experiments_3d": k_3d,
            "note": f"the first {materials} MERL (NBRDF proxy) tables by name, 3D metrics on "
                    f"{k_3d} experiment(s); run_evaluation in-process, the loop vs a 2-worker "
                    "local cluster",
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
                  *([f"- CPU seconds (user + system, all processes): {b['cpu_s']['sequential_runs']}"
                     f" for the {b['captures']} `run`s ({b['cpu_s']['per_run']} each), "
                     f"{b['cpu_s']['batch']} for the batch ({b['cpu_s']['batch_per_capture']} a "
                     "capture, cluster start-up included)."] if "cpu_s" in b else []),
                  f"- Overhead: a batch of 1 took {o['batch_of_1_s']} s, one `run` "
                  f"{o['run_s']} s: {o['extra_s']} s more (target ≤ 5 s).",
                  f"- Load average: {b['load_average']}.", ""]
    for o in (result.get(k) for k in ("overhead", "overhead_earlier")):
        if not o:
            continue
        m = o["median"]
        lines += ["## Overhead: a batch of 1 capture (`--workers 1`) against one `run`", "",
                  *([f"- {o['note']}."] if "note" in o else []),
                  f"- {o['capture']}; {len(o['pairs'])} pairs, the order alternating.",
                  f"- Median: `run` {m['run_s']} s, batch {m['batch_s']} s: **{m['extra_s']} s "
                  f"more** (target ≤ 5 s); CPU seconds (all processes) {m['run_cpu_s']} against "
                  f"{m['batch_cpu_s']}: {m['extra_cpu_s']} s more.", "",
                  "| pair | run s | batch s | extra s | extra CPU s | load before | load after |",
                  "|---|---|---|---|---|---|---|"]
        lines += [f"| {i + 1} | {p['run_s']} | {p['batch_s']} | {p['extra_s']} | "
                  f"{p['extra_cpu_s']} | {p['load_before']} | {p['load_after']} |"
                  for i, p in enumerate(o["pairs"])]
        lines += [""]
    c = result.get("cluster")
    if c:
        lines += [f"## Simulated cluster: `dask scheduler` + W `dask worker --nthreads 1` on this "
                  f"{c['cores']}-core host, {c['captures']} captures", "",
                  "| workers | seconds | speed-up vs 1 | load before |", "|---|---|---|---|"]
        lines += [f"| {w} | {v['seconds']} | {v['speedup_vs_1']} | {v['load_before']} |"
                  for w, v in c["workers"].items()]
        m = c.get("model")
        if m:
            lines += ["", "![speed-up against workers](batch_scaling.png)", "",
                      f"- On this host 4 workers share {c['cores']} cores: the speed-up cannot "
                      f"exceed ~{c['cores']}×. Beyond that, on a host shared with other jobs, more "
                      "worker processes win a larger share of the cores from the other jobs: a "
                      "4-worker point above 2 workers' measures that, not scaling.",
                      f"- Cluster model, from the CPU seconds of two captures in one process "
                      f"with 1 thread (`{m['source']}`): {m['start_s']} s of start (imports, "
                      "model read) + "
                      f"⌈captures / W⌉ × {m['per_capture_s']} s a capture. On a cluster where each "
                      "worker has its own core and the shared filesystem keeps up, that predicts "
                      + ", ".join(f"{s}× at {w}" for w, s in m["predicted_speedup"].items())
                      + f" workers for {c['captures']} captures: the steps come from ⌈n / W⌉ "
                      "(a worker with one capture more sets the wall time), and past n workers "
                      "nothing is gained.", ""]
        else:
            lines += ["", "Past the core count the curve flattens here; on a cluster each worker "
                      "brings its own core.", ""]
    for t in (result.get(k) for k in ("table1", "table1_earlier")):
        if not t:
            continue
        lines += [f"## Table 1, reduced: {t['experiments']} experiments, {t['materials']} "
                  f"tables, 3D metrics on {t.get('experiments_3d', 0)}", "",
                  f"- {t['note']}.",
                  f"- Loop: {t['loop_s']} s; `--workers 2`: {t['workers2_s']} s: ratio "
                  f"**{t['ratio']}** (target ≤ 0.6 on the full protocol).",
                  f"- Largest difference in any number: {t['max_abs_difference']:.3g}; same "
                  f"choices and names: {t['same_choices_and_names']}.",
                  f"- Load average: {t['load_average']}.", ""]
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--part", required=True, choices=["batch", "overhead", "cluster", "table1", "report"],
                    help="report: only rewrite batch_speed.md and batch_scaling.png from the JSON")
    ap.add_argument("--captures", type=int, default=8)
    ap.add_argument("--repeats", type=int, default=3, help="overhead: pairs of run and batch")
    ap.add_argument("--merl-dir", default="/work/data/merl")
    ap.add_argument("--experiments", type=int, default=4)
    ap.add_argument("--materials", type=int, default=100, help="table1: the first M tables")
    ap.add_argument("--experiments-3d", type=int, default=0,
                    help="table1: 3D metrics on this many experiments")
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
        elif args.part == "overhead":
            if "overhead" in result:  # the earlier measurement stays in the record
                result["overhead_earlier"] = result["overhead"]
            result["overhead"] = part_overhead(work, args.repeats)
        elif args.part == "cluster":
            result["cluster"] = part_cluster(work, args.captures)
        elif args.part == "table1":
            if "table1" in result:  # the earlier measurement stays in the record
                result["table1_earlier"] = result["table1"]
            result["table1"] = part_table1(work, args.merl_dir, args.experiments, args.materials,
                                           args.experiments_3d)
    if args.part != "report":
        result.setdefault("commands", {})[args.part] = (
            "nice -n 10 python -m benchmarks.batch_speed " + " ".join(argv or sys.argv[1:]))
    if "cluster" in result:
        profile_path = RESULTS / "run_profile.json"
        profile = json.loads(profile_path.read_text()) if profile_path.exists() else None
        result["cluster"]["model"] = cluster_model(result["cluster"]["captures"], profile)
        if result["cluster"]["model"]:
            write_cluster_plot(result["cluster"], RESULTS / "batch_scaling.png")
    json_path.write_text(json.dumps(result, indent=1) + "\n")
    (RESULTS / "batch_speed.md").write_text(write_markdown(result) + "\n")
    print(json.dumps(result.get(args.part, {}), indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
