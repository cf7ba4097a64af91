"""Every method side by side in one run: the RGL kind hold-out (2D LAB-log mean per kind, nested),
the MERL protocol (`flashbrdf evaluate --quick`), DiLiGenT level-matched, and the warning's recall
and false-warning rate on the kind hold-out.

    nice -n 10 python -m benchmarks.side_by_side --merl-dir MERL --test-dir RGL --work WORK

Runs benchmarks.consensus_weights, `flashbrdf evaluate --quick` and benchmarks.diligent_ball
(ball, pot2; the shipped model, baselines fitted on MERL + RGL) as child processes into WORK,
then writes benchmarks/results/side_by_side.{json,md} from their JSON. "dsgplvm" is the shipped
default (the consensus); "dsgplvm alone" its first member, where the hold-out reports it.
"""

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

from benchmarks._real_common import RESULTS, SHARED, write_json

METHODS = ("dsgplvm", "pca", "noll", "chandraker", "ashikhmin")
DEFAULT_MODEL = Path(__file__).resolve().parents[1] / "sample_data" / "models" / "merl100_1d2d.npz"


def _child(argv, log):
    """Run a child (python -m ...), its output to `log`; stop with its last lines on failure."""
    start = time.perf_counter()
    with open(log, "w") as out:
        done = subprocess.run([sys.executable, "-m", *argv], stdout=out, stderr=subprocess.STDOUT,
                              check=False)
    if done.returncode != 0:
        sys.exit(f"{' '.join(argv[:2])} failed; see {log}:\n" + "".join(
            Path(log).read_text().splitlines(True)[-10:]))
    return time.perf_counter() - start


def _merged(merl_dir, test_dir, folder):
    """A folder of symlinks to every table of both folders (the shipped model's training data)."""
    folder.mkdir(parents=True, exist_ok=True)
    for table in [*Path(merl_dir).glob("*.binary"), *Path(test_dir).glob("*.binary")]:
        link = folder / table.name
        if not link.exists():
            link.symlink_to(table.resolve())
    return folder


def kind_holdout(args, work):
    out = work / "kinds"
    seconds = _child(["benchmarks.consensus_weights", "--merl-dir", args.merl_dir, "--test-dir",
                      args.test_dir, "--work", str(work / "kinds_cache"), "--out", str(out)],
                     work / "kinds.log")
    nested = json.loads((out / "consensus_weights.json").read_text())["kinds_nested"]
    rename = {"consensus": "dsgplvm", "dsgplvm": "dsgplvm alone"}
    scopes = {"all kinds": nested["summary"]["all"], **nested["summary"]["kinds"]}
    table = {scope: {"n": s["n"], **{rename.get(m, m): v for m, v in s["means"].items()}}
             for scope, s in scopes.items()}
    warning = {name: {k: nested[name][k] for k in ("warned", "recall", "false_warning_rate")}
               for name in ("warning", "warning_shipped")}
    warning["lost"] = nested["warning"]["lost"]
    return table, warning, seconds


def merl_protocol(args, work):
    out = work / "merl"
    seconds = _child(["flashbrdf", "evaluate", "--merl-dir", args.merl_dir, "--out", str(out),
                      "--quick", "--workers", "2"], work / "merl.log")
    summary = json.loads((out / "table1.json").read_text())["summary"]["2d"]
    return {m: summary[m]["lab_log"] for m in METHODS if m in summary}, seconds


def diligent(args, work, merged):
    rows, seconds = {}, 0.0
    for name in args.diligent:
        data = SHARED / "data" / "real" / f"diligent-{name}"
        seconds += _child(["benchmarks.diligent_ball", "--data", str(data), "--results-name",
                           f"diligent_{name}", "--model", str(args.model), "--merl-dir",
                           str(merged), "--work", str(work / name)], work / f"{name}.log")
        methods = json.loads((RESULTS / f"diligent_{name}.json").read_text())["methods"]
        rows[name] = {m: {"level_matched": info["delta_e_log_mean_level_matched"]["mean"],
                          "calibrated": info["delta_e_log_mean"]["mean"]}
                      for m, info in methods.items()}
    return rows, seconds


def _best_other(values, method="dsgplvm"):
    others = {m: v for m, v in values.items() if m in METHODS and m != method}
    best = min(others, key=others.get)
    return best, values[method] / others[best]


def markdown(result):
    cols = ["dsgplvm", "dsgplvm alone", *METHODS[1:]]
    lines = ["# Every method side by side", "", f"Command: `{result['command']}`; load average "
             f"{result['load_average']:.1f} at the start, {result['minutes']:.0f} min on "
             f"{os.cpu_count()} cores. dsgplvm is the shipped default (the consensus); "
             "'dsgplvm alone' its first member. Data: MERL (NBRDF proxy), RGL (NBRDF proxy).", "",
             "## RGL (NBRDF proxy), one kind held out at a time (nested): 2D LAB-log mean", "",
             "| kind | n | " + " | ".join(cols) + " | dsgplvm / best baseline |",
             "|---|---|" + "---|" * (len(cols) + 1)]
    for scope, row in result["kind_holdout"].items():
        best, ratio = _best_other(row)
        lines.append(f"| {scope} | {row['n']} | " + " | ".join(
            f"{row[c]:.2f}" if c in row else "–" for c in cols) + f" | {ratio:.3f}× {best} |")
    w = result["warning"]
    lines += ["", "## The warning on the kind hold-out", "",
              f"Lost (default > 1.2× the best baseline on the material): {', '.join(w['lost']) or 'none'}.",
              "", "| rule | recall | false-warning rate | warned |", "|---|---|---|---|"]
    for name, label in (("warning", "disagreement, threshold nested per kind"),
                        ("warning_shipped", "as shipped (infer.warning, every reason)")):
        recall = "–" if w[name]["recall"] is None else f"{w[name]['recall']:.0%}"
        lines.append(f"| {label} | {recall} | {w[name]['false_warning_rate']:.1%} | "
                     f"{', '.join(w[name]['warned'])} |")
    merl = result["merl_protocol"]
    lines += ["", "## MERL (NBRDF proxy), `flashbrdf evaluate --quick`: 2D LAB-log", "",
              "| method | mean | median |", "|---|---|---|"]
    lines += [f"| {m} | {v['mean']:.2f} | {v['median']:.2f} |" for m, v in merl.items()]
    best, ratio = _best_other({m: v["mean"] for m, v in merl.items()})
    lines += ["", f"dsgplvm / best baseline ({best}): {ratio:.3f}×.", "",
              "## DiLiGenT, ΔE-log mean over the 95 other lights: level-matched (as calibrated)", "",
              "| object | " + " | ".join(METHODS) + " | dsgplvm / best baseline |",
              "|---|" + "---|" * (len(METHODS) + 1)]
    for name, row in result["diligent"].items():
        best, ratio = _best_other({m: v["level_matched"] for m, v in row.items()})
        lines.append(f"| {name} | " + " | ".join(
            f"{row[m]['level_matched']:.3f} ({row[m]['calibrated']:.3f})" for m in METHODS)
            + f" | {ratio:.3f}× {best} |")
    return "\n".join(lines) + "\n"


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--merl-dir", required=True, help="MERL (NBRDF proxy) tables")
    p.add_argument("--test-dir", required=True, help="RGL (NBRDF proxy) dev tables")
    p.add_argument("--work", required=True, type=Path)
    p.add_argument("--model", default=DEFAULT_MODEL, type=Path)
    p.add_argument("--diligent", nargs="*", default=["ball", "pot2"])
    args = p.parse_args(argv)
    args.work.mkdir(parents=True, exist_ok=True)
    start, load = time.perf_counter(), os.getloadavg()[0]
    kinds, warning, kinds_s = kind_holdout(args, args.work)
    merl, merl_s = merl_protocol(args, args.work)
    merged = _merged(args.merl_dir, args.test_dir, args.work / "merl_rgl")
    real, real_s = diligent(args, args.work, merged)
    result = {"command": "nice -n 10 python -m benchmarks.side_by_side " + " ".join(
                  argv or sys.argv[1:]),
              "load_average": load, "minutes": (time.perf_counter() - start) / 60,
              "seconds": {"kind_holdout": kinds_s, "merl_protocol": merl_s, "diligent": real_s},
              "kind_holdout": kinds, "warning": warning, "merl_protocol": merl, "diligent": real}
    write_json(RESULTS / "side_by_side.json", result)
    text = markdown(result)
    (RESULTS / "side_by_side.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
