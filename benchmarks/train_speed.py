"""Wall and CPU time of `flashbrdf train` on a folder of MERL tables, and its determinism.

Runs the command as a user would, `runs` times with the default worker count and once with
FLASHBRDF_THREADS=1 (one process for the validation fits, one thread reading tables), and records
for each: wall seconds, CPU seconds of the command and its children (user + system), the load
average before and after (the machine is shared: wall time means little without it), the model
file's sha256 and the stage times the model records (params: train_seconds, fit_seconds).
Same seed -> same content, whatever the worker count, is checked and recorded.

    nice -n 10 python -m benchmarks.train_speed --merl-dir /work/data/merl \
        [--runs 1] [--out benchmarks/results/train_speed.json]
"""

import argparse
import hashlib
import io
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


from flashbrdf.files.atomic import write_text


def _children_cpu():
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


TIMES = ("train_seconds", "fit_seconds", "fit_time")   # what a model records of its own run


def model_digest(path, digest=None):
    """sha256 over every array of MODEL.npz (and of the DS-GPLVM .npz inside it), with the times
    it records left out (TIMES): the content, not the zip's timestamps."""
    digest = digest or hashlib.sha256()
    with np.load(path, allow_pickle=False) as z:
        for key in sorted(z.files):
            value = z[key]
            if key in ("params", "meta"):
                fields = json.loads(str(value))
                value = np.array(json.dumps({k: v for k, v in fields.items() if k not in TIMES},
                                            sort_keys=True))
            if key == "dsgplvm":
                model_digest(io.BytesIO(value.tobytes()), digest)
                continue
            digest.update(key.encode() + value.tobytes())
    return digest.hexdigest()


def time_train(merl_dirs, out, threads=None):
    """One `flashbrdf train` run -> dict of its measurements."""
    env = dict(os.environ)
    if threads:
        env["FLASHBRDF_THREADS"] = str(threads)
    cmd = ["flashbrdf", "train", *sum((["--merl-dir", d] for d in merl_dirs), []),
           "--out", str(out)]
    load_before = os.getloadavg()
    cpu0, t0 = _children_cpu(), time.perf_counter()
    subprocess.run(cmd, env=env, check=True, stdout=subprocess.DEVNULL)
    wall, cpu = time.perf_counter() - t0, _children_cpu() - cpu0
    with np.load(out, allow_pickle=False) as z:
        params = json.loads(str(z["params"])) if "params" in z else {}
    return {"command": " ".join(cmd), "FLASHBRDF_THREADS": threads or "default",
            "wall_s": round(wall, 1), "cpu_s": round(cpu, 1),
            "loadavg_before": [round(v, 2) for v in load_before],
            "loadavg_after": [round(v, 2) for v in os.getloadavg()],
            "content_sha256": model_digest(out),
            "train_seconds": params.get("train_seconds"), "fit_seconds": params.get("fit_seconds")}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--merl-dir", action="append", required=True)
    ap.add_argument("--runs", type=int, default=1)
    ap.add_argument("--out", default="benchmarks/results/train_speed.json")
    args = ap.parse_args()
    runs = []
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(args.runs):
            runs.append(time_train(args.merl_dir, Path(tmp) / f"default{k}.npz"))
            print(runs[-1], flush=True)
        runs.append(time_train(args.merl_dir, Path(tmp) / "one.npz", threads=1))
        print(runs[-1], flush=True)
    result = {"command": "nice -n 10 python " + " ".join(sys.argv), "cores": os.cpu_count(),
              "runs": runs, "same_content": len({r["content_sha256"] for r in runs}) == 1}
    write_text(args.out, json.dumps(result, indent=1))
    lines = ["# `flashbrdf train` time", "", f"`{result['command']}` ({os.cpu_count()} cores, shared)",
             "", "| FLASHBRDF_THREADS | wall s | CPU s | load avg before (1/5/15 min) | model content sha256 |",
             "|---|---|---|---|---|"]
    lines += [f"| {r['FLASHBRDF_THREADS']} | {r['wall_s']} | {r['cpu_s']} | "
              f"{' / '.join(map(str, r['loadavg_before']))} | {r['content_sha256'][:12]} |" for r in runs]
    lines += ["", f"Same model content in every run: {result['same_content']}."]
    write_text(str(Path(args.out).with_suffix(".md")), "\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
