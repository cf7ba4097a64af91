"""Error against run time, one point per method and setting, labels that never overlap:
benchmarks/results/error_vs_runtime.png (reads JSON only, runs in a second).

    python -m benchmarks.error_vs_runtime [--table1 benchmarks/results/table1.json]
        [--ood benchmarks/results/generalisation.json] [--out benchmarks/results/error_vs_runtime.png]

- Panel 1, MERL (NBRDF proxy): Table 1's run-time points (table1.json "runtime_points": every method
  and every hyperparameter setting tried, scored on experiment 0's test materials), 2D LAB-log mean
  against 2D inference time per slice.
- Panel 2, out of distribution: {"methods": {name: {"lab_log_mean", "lab_log_median", "predict_ms",
  "fit_s"}}} (the generalisation benchmark's JSON, or `flashbrdf evaluate --test-dir`'s
  test_set.json, which has the same fields). Filled marker: mean; open marker: median. Skipped with
  a note when the file is absent.

The layout (labels in a non-overlapping column with leader lines) is experiments/runtime_plot.py, which
`flashbrdf evaluate` also uses for its own error_vs_runtime.png.
"""

import argparse
import json
import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

from flashbrdf.experiments.runtime_plot import grid_points, make_figure, write_figure

RESULTS = ROOT / "benchmarks" / "results"


def table1_points(path):
    """Panel 1's points from table1.json and its dataset name."""
    result = json.loads(Path(path).read_text())
    return grid_points(result["runtime_points"]), result.get("dataset", "MERL (NBRDF proxy)")


def ood_points(path):
    """Panel 2's points and medians from a generalisation/test_set JSON."""
    result = json.loads(Path(path).read_text())
    methods = result["methods"]
    points = [{"label": m, "method": m, "x": r["predict_ms"], "y": r["lab_log_mean"]}
              for m, r in methods.items()]
    medians = {m: r["lab_log_median"] for m, r in methods.items() if "lab_log_median" in r}
    label = result.get("label") or result.get("dataset") or Path(path).stem
    return points, medians, label


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--table1", default=str(RESULTS / "table1.json"))
    ap.add_argument("--ood", default=str(RESULTS / "generalisation.json"))
    ap.add_argument("--ood-label", help="how to name the OOD data (default: from the JSON)")
    ap.add_argument("--out", default=str(RESULTS / "error_vs_runtime.png"))
    args = ap.parse_args(argv)
    merl_points, dataset = table1_points(args.table1)
    if os.path.exists(args.ood):
        ood = ood_points(args.ood)
        note = f"Panel 2: {os.path.relpath(args.ood, ROOT)}."
    else:
        ood = None
        note = (f"OOD panel skipped: {os.path.relpath(args.ood, ROOT)} is absent (the "
                "generalisation benchmark writes it).")
    fig = make_figure(merl_points, dataset, ood, args.ood_label,
                      "python -m benchmarks.error_vs_runtime. " + note)
    panels = len(fig.axes)
    write_figure(args.out, fig)
    print(f"{args.out} ({panels} panel(s)); {note}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
