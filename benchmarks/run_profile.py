"""Where one `flashbrdf run` of the sample capture spends its time (a profile, for `batch`).

Three measurements, each in its own process:
1. `python -X importtime -m pipeline run sample_data/capture`: wall seconds per stage (run's own
   table), CPU seconds (user + system) of the process, and the import time of every package
   the run imports (top-level packages, cumulative).
2. The same run under cProfile: cumulative seconds of the calls that matter (imports, model
   read, segmentation, rendering, report figures).
3. Two captures in one process with 1 thread (as in a batch worker): the CPU seconds of the
   first (cold: imports, model read) and the second (warm: what each further capture costs a
   worker).
CPU / wall above 1 means both cores were busy; on a loaded machine wall time also holds the time
the process waited for a core, so the CPU seconds are the figures to compare. Writes
benchmarks/results/run_profile.json and run_profile.md.

    nice -n 10 python benchmarks/run_profile.py
"""

import argparse
import json
import os
import pstats
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from batch_speed import _children_cpu, _load  # the load average and CPU seconds, as there

REPO = Path(__file__).resolve().parents[1]
RESULTS = REPO / "benchmarks" / "results"
SAMPLE = REPO / "sample_data" / "capture"
RUN = [sys.executable, "-m", "pipeline", "run", str(SAMPLE)]

# cProfile entries worth naming: (label, file suffix, function name)
CALLS = [("imports (every module, nested)", "<frozen importlib._bootstrap>", "_find_and_load"),
         ("load model", "pipeline/cmd_run.py", "_load_methods"),
         ("segment (Gaussian mixtures)", "slice_extract/segment.py", "cluster_samples"),
         ("render (envmap integrator)", "render/scene_render.py", "render_scene"),
         ("compare (ΔE maps + PNGs)", "render/compare.py", "write_comparison"),
         ("report (figures + markdown)", "pipeline/report.py", "write_report"),
         ("matplotlib savefig (report + ΔE PNGs)", "matplotlib/figure.py", "savefig")]

WARM = """
import json, os, sys, time, argparse
os.environ["FLASHBRDF_THREADS"] = "1"
from threadpoolctl import threadpool_limits
from flashbrdf.pipeline.cmd_run import run
from flashbrdf.pipeline.batch import cached_load_methods
out = sys.argv[1]
seconds = []
with threadpool_limits(1):
    for i in range(2):
        c0, w0 = time.process_time(), time.perf_counter()
        run(argparse.Namespace(scene_dir=sys.argv[2], out=f"{out}/warm{i}", model=None,
                               methods="dsgplvm", spp=64, no_anchor=False),
            load_methods=cached_load_methods)
        seconds.append([time.process_time() - c0, time.perf_counter() - w0])
print(json.dumps(seconds), file=sys.__stdout__)
"""


def stage_table(text):
    """{stage: wall seconds} from run's printed stage table."""
    return {m.group(1).strip(): float(m.group(2))
            for m in re.finditer(r"^(\S.*?)\s+(\d+\.\d\d)$", text, re.M)
            if m.group(1).strip() not in ("total",)}


def import_times(text, top=12):
    """[(package, cumulative s)] of the top-level imports in -X importtime output."""
    rows = []
    for line in text.splitlines():
        m = re.match(r"import time:\s+(\d+) \|\s+(\d+) \| (\s*)(\S+)", line)
        if m and not m.group(3):  # not indented: imported by the program itself
            rows.append((m.group(4), int(m.group(2)) / 1e6))
    total = sum(s for _, s in rows)
    rows.sort(key=lambda r: -r[1])
    return total, [(name, round(s, 2)) for name, s in rows[:top]]


def profile_calls(prof_path):
    stats = pstats.Stats(str(prof_path)).stats
    out = {}
    for label, suffix, name in CALLS:
        best = 0.0
        for (file, _, func), (_, _, _, cumulative, _) in stats.items():
            if func == name and file.endswith(suffix):
                best = max(best, cumulative)  # the outermost call holds the nested ones
        out[label] = round(best, 2)
    return out


def main(argv=None):
    argparse.ArgumentParser(description=__doc__.split("\n\n")[0]).parse_args(argv)
    result = {"load_average": {"before": _load()}}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        c0, w0 = _children_cpu(), time.perf_counter()
        done = subprocess.run([sys.executable, "-X", "importtime", *RUN[1:], "--out",
                               str(tmp / "run")], cwd=REPO, capture_output=True, text=True,
                              check=True)
        wall, cpu = time.perf_counter() - w0, _children_cpu() - c0
        total_imports, imports = import_times(done.stderr)
        result["run"] = {"wall_s": round(wall, 1), "cpu_s": round(cpu, 1),
                         "cpu_per_wall": round(cpu / wall, 2),
                         "stages_wall_s": stage_table(done.stderr),
                         "imports_s": round(total_imports, 2), "largest_imports_s": imports}
        result["load_average"]["after_run"] = _load()
        shutil.rmtree(tmp / "run")
        subprocess.run([sys.executable, "-m", "cProfile", "-o", str(tmp / "run.prof"),
                        *RUN[1:], "--out", str(tmp / "run")], cwd=REPO, capture_output=True,
                       check=True)
        result["cprofile_cumulative_s"] = profile_calls(tmp / "run.prof")
        result["load_average"]["after_cprofile"] = _load()
        warm = subprocess.run([sys.executable, "-c", WARM, str(tmp), str(SAMPLE)], cwd=REPO,
                              capture_output=True, text=True, check=True)
        (cold_cpu, cold_wall), (warm_cpu, warm_wall) = json.loads(warm.stdout.splitlines()[-1])
        result["one_worker_process"] = {
            "first_capture": {"cpu_s": round(cold_cpu, 1), "wall_s": round(cold_wall, 1)},
            "second_capture": {"cpu_s": round(warm_cpu, 1), "wall_s": round(warm_wall, 1)}}
        result["load_average"]["after_warm"] = _load()
    result["command"] = "nice -n 10 python benchmarks/run_profile.py"
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "run_profile.json").write_text(json.dumps(result, indent=1) + "\n")
    (RESULTS / "run_profile.md").write_text(markdown(result))
    print(json.dumps(result, indent=1))
    return 0


def markdown(r):
    run, w = r["run"], r["one_worker_process"]
    lines = ["# Profile of one `flashbrdf run` (sample capture, 256², 2 reference photos, "
             "dsgplvm, 64 spp)", "", f"Made by `{r['command']}` on {os.cpu_count()} shared "
             f"cores; load averages {r['load_average']}.", "",
             f"- Wall {run['wall_s']} s, CPU {run['cpu_s']} s (user + system): CPU / wall "
             f"{run['cpu_per_wall']} (2.0 would be both cores busy throughout).",
             f"- Imports: {run['imports_s']} s of wall time; largest: "
             + ", ".join(f"{n} {s} s" for n, s in run["largest_imports_s"]) + ".",
             f"- In one worker process with 1 thread: the first capture {w['first_capture']['cpu_s']}"
             f" s CPU (imports, model read), each further one {w['second_capture']['cpu_s']} s CPU"
             f" (wall {w['first_capture']['wall_s']} and {w['second_capture']['wall_s']} s).", "",
             "| stage (run's table) | wall s |", "|---|---|"]
    lines += [f"| {k} | {v} |" for k, v in run["stages_wall_s"].items()]
    lines += ["", "| call (cProfile, cumulative, wall) | s |", "|---|---|"]
    lines += [f"| {k} | {v} |" for k, v in r["cprofile_cumulative_s"].items()]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    sys.exit(main())
