"""The files of Table 1's protocol: table1.json, table1.md and the error/run-time plot, from the
experiments' records (experiments.evaluate), and json_leaves to compare two runs' numbers."""

import json
import os

import numpy as np

from flashbrdf.experiments.table1_report import PAPER_TABLE1, summarise_errors, write_markdown
from flashbrdf.files.atomic import write_text
from flashbrdf.infer.model_selection import lab_log


def mean_performing(records):
    """The index of the experiment whose dsgplvm 2D LAB-log mean is closest to the mean over
    experiments (the paper's choice for Table 2)."""
    means = np.array([lab_log(r["errors_2d"]["dsgplvm"]) for r in records])
    return int(np.argmin(np.abs(means - means.mean())))


def summarise_key(records, key):
    """{method: summarise_errors of every experiment's errors under `key`} (errors_2d, errors_3d)."""
    out = {}
    for r in records:
        for name, errs in r.get(key, {}).items():
            out.setdefault(name, []).extend(errs)
    return {name: summarise_errors(errs) for name, errs in out.items()}


def write_table1(out_dir, result, records, costs, points, ablations, planned):
    """table1.json, table1.md and error_vs_runtime.png of the experiments run so far (the result
    dict is completed in place)."""
    result["protocol"] = (f"{len(records)} of {planned} planned experiments (5-fold splits of seeded "
                          "permutations: 60/20/20 % train/validation/test); validation picks "
                          "dsgplvm q, beta and pca/oracle hyperparameters by 2D LAB-log error.")
    result["summary"] = {"2d": summarise_key(records, "errors_2d")}
    s3 = summarise_key(records, "errors_3d")
    if s3:
        result["summary"]["3d"] = s3
    mp = mean_performing(records)
    result["mean_performing"] = {"experiment": records[mp]["experiment"],
                                 "summary": {"2d": {m: summarise_errors(e) for m, e in
                                                    records[mp]["errors_2d"].items()}}}
    result["costs"] = {m: {"train_s": float(np.mean(c["train_s"])),
                           "infer_2d_s": float(np.mean(c["infer_2d_s"])),
                           "infer_3d_s": c["infer_3d_s"], "peak_mb": c["peak_mb"]}
                       for m, c in costs.items()}
    result["ablations"] = {k: summarise_errors(v["errors"]) for k, v in ablations.items()
                           if v.get("errors")}
    result["ablations_skipped"] = {k: v["skipped"] for k, v in ablations.items() if "skipped" in v}
    result["hyperparameters"] = [{"experiment": r["experiment"], "chosen": r["chosen"]}
                                 for r in records]
    result["runtime_points"] = points
    result["per_experiment"] = [{"experiment": r["experiment"], "test": r["test"],
                                 "errors_2d": r["errors_2d"], "errors_3d": r.get("errors_3d")}
                                for r in records]
    result["paper_table1"] = PAPER_TABLE1
    write_text(os.path.join(out_dir, "table1.json"), json.dumps(result, indent=1, default=str) + "\n")
    write_markdown(os.path.join(out_dir, "table1.md"), result)
    if points:
        from flashbrdf.experiments.runtime_plot import write_runtime_plot  # matplotlib: here only
        write_runtime_plot(os.path.join(out_dir, "error_vs_runtime.png"), points)


def json_leaves(value, path=""):
    """{"/key/0/...": leaf} of a nested JSON value: compares two runs' numbers path by path
    (the loop against Dask in tests/test_evaluate_dask.py and benchmarks/batch_speed.py)."""
    if isinstance(value, dict):
        return {k: v for key, item in value.items()
                for k, v in json_leaves(item, f"{path}/{key}").items()}
    if isinstance(value, list):
        return {k: v for i, item in enumerate(value)
                for k, v in json_leaves(item, f"{path}/{i}").items()}
    return {path: value}
