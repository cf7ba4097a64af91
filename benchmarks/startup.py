"""Start-up of the command line: `flashbrdf --help` and `flashbrdf infer` for one material, each a
fresh process (what a user or a script pays per call), and the imports that remain.

    python -m benchmarks.startup --merl-dir /work/data/merl [--runs 7]

Writes benchmarks/results/startup.{json,md}: wall seconds (median, min, max over the runs, after
one warm-up run that fills the OS file cache) and peak RSS, and the ten largest imports of each
command by their own time (`python -X importtime`, self time, one run). Targets (issue "One
package"): --help < 0.3 s, infer < 1 s on a quiet machine; the load average is recorded beside
the figures because a loaded machine inflates every one of them.
"""

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from flashbrdf.pipeline.options import DEFAULT_MODEL

RESULTS = Path(__file__).resolve().parent / "results"
MATERIAL = "red-specular-plastic"  # the sample capture's material, held out of the default model


def timed(command, runs):
    """Median, min and max wall seconds and the largest peak RSS (MiB) of `runs` fresh processes,
    after one warm-up."""
    subprocess.run(command, check=True, capture_output=True)
    walls, peaks = [], []
    for _ in range(runs):
        before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
        start = time.perf_counter()
        subprocess.run(command, check=True, capture_output=True)
        walls.append(time.perf_counter() - start)
        peaks.append(max(before, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss))
    return {"median_s": statistics.median(walls), "min_s": min(walls), "max_s": max(walls),
            "peak_rss_mib": max(peaks) / 1024, "runs": runs}


def largest_imports(command, top=10):
    """[(module, self seconds)] of one run under -X importtime, largest first."""
    done = subprocess.run([sys.executable, "-X", "importtime", *command[1:]], check=True,
                          capture_output=True, text=True)
    rows = []
    for line in done.stderr.splitlines():
        if line.startswith("import time:") and "self [us]" not in line:
            self_us, _, name = line.removeprefix("import time:").split("|")
            rows.append((name.strip(), int(self_us) / 1e6))
    return sorted(rows, key=lambda r: -r[1])[:top]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--merl-dir", required=True, help="MERL (NBRDF proxy) tables")
    parser.add_argument("--runs", type=int, default=7)
    args = parser.parse_args(argv)
    table = Path(args.merl_dir) / f"{MATERIAL}.binary"
    flashbrdf = [sys.executable, "-m", "flashbrdf"]
    with tempfile.TemporaryDirectory() as work:
        slice_csv = os.path.join(work, "slice.csv")
        subprocess.run([*flashbrdf, "merl-slice", str(table), "--out", slice_csv], check=True)
        commands = {
            "--help": [*flashbrdf, "--help"],
            "infer": [*flashbrdf, "infer", "--model", str(DEFAULT_MODEL), "--slice", slice_csv,
                      "--out", os.path.join(work, "brdf.binary")],
        }
        load = os.getloadavg()[0]
        result = {"command": "python -m benchmarks.startup " + " ".join(argv or sys.argv[1:]),
                  "load_average_1min": load, "cores": os.cpu_count()}
        for name, command in commands.items():
            result[name] = timed(command, args.runs)
            result[name]["largest_imports"] = largest_imports(command)
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "startup.json").write_text(json.dumps(result, indent=1) + "\n")
    lines = ["# Start-up of the command line", "", f"Command: `{result['command']}`; load average "
             f"{load:.1f} on {os.cpu_count()} cores.", "",
             "| command | median s | min s | max s | peak RSS MiB |", "|---|---|---|---|---|"]
    for name in commands:
        r = result[name]
        lines.append(f"| `flashbrdf {name}` | {r['median_s']:.3f} | {r['min_s']:.3f} | "
                     f"{r['max_s']:.3f} | {r['peak_rss_mib']:.0f} |")
    for name in commands:
        lines += ["", f"Largest imports of `flashbrdf {name}` (self seconds):", ""]
        lines += [f"- {module}: {seconds:.3f}" for module, seconds in result[name]["largest_imports"]]
    (RESULTS / "startup.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
