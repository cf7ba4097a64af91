"""The sparse tail of a flash slice: what reading its last few-pixel bins costs the planar cards.

    nice -n 5 python benchmarks/sparse_tail.py --cards-work WORK [--thresholds 0,10,20,50,100]

WORK is a `benchmarks/multi_material.py --objects cards` work folder (its planar_scenes/ and
planar_labels.png: `run`'s own segmentation of view 00). Each material's slice is extracted from
view 00 with `flashbrdf extract --labels`; the bins past the last one holding >= T samples are
emptied (infer.slices.without_sparse_tail with min_samples = T; T = 0 reads every bin, the
behaviour before); each method predicts from the model's Python API (so the command line's own
rule does not apply twice) and the 8 other views are rendered with `flashbrdf render --labels`.
Thresholds that empty the same bins give the same prediction and are rendered once.
Writes benchmarks/results/sparse_tail.{json,md}.
"""

import argparse
import hashlib
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from benchmarks._real_common import RESULTS, run_cli  # noqa: E402
from flashbrdf.brdf import merl, views  # noqa: E402
from flashbrdf.files.atomic import write_text  # noqa: E402
from flashbrdf.infer.model_file import load_methods  # noqa: E402
from flashbrdf.infer.slices import without_sparse_tail  # noqa: E402
from flashbrdf.pipeline.options import DEFAULT_MODEL  # noqa: E402


def _cli(argv):
    rc, err, _ = run_cli(argv)
    if rc != 0:
        raise SystemExit(f"flashbrdf {argv[0]} failed (exit {rc}): {err}")


def _write_table(path, table):
    full = views.table_3d_from_2d(table) if table.ndim == 3 else table
    full = np.where(np.isfinite(full), full, -1.0)
    full[~merl.merl_valid_mask()] = -1.0
    merl.write_merl(path, full)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cards-work", required=True, type=Path)
    ap.add_argument("--model", default=DEFAULT_MODEL)
    ap.add_argument("--methods", default="dsgplvm,pca,chandraker")
    ap.add_argument("--thresholds", default="0,10,20,50,100")
    ap.add_argument("--out", default=RESULTS, type=Path)
    args = ap.parse_args(argv)
    work = args.cards_work
    scenes = sorted(p for p in (work / "planar_scenes").iterdir() if (p / "scene.json").is_file())
    labels = work / "planar_labels.png"
    slices_dir = work / "sparse_tail" / "slices"
    _cli(["extract", scenes[0], "--labels", labels, "--out", slices_dir, "--force"])
    k = len(list(slices_dir.glob("material_*.csv")))
    observed = {j: views.read_slice_csv(slices_dir / f"material_{j}.csv") for j in range(1, k + 1)}
    methods = load_methods(args.model, args.methods.split(","),
                           overrides={"dsgplvm": {"anchor": True}})  # as `run` loads them
    thresholds = [int(t) for t in args.thresholds.split(",")]
    result = {"command": "python benchmarks/sparse_tail.py " + " ".join(argv or sys.argv[1:]),
              "flash_view": scenes[0].name, "materials": k, "thresholds": {}, "rendered": {}}
    for t in thresholds:
        trimmed = {j: without_sparse_tail(rho, n, t) if t > 0 else (rho, [])
                   for j, (rho, n) in observed.items()}
        key = hashlib.sha1(json.dumps({j: tr[1] for j, tr in trimmed.items()}).encode()).hexdigest()
        result["thresholds"][str(t)] = {
            "render": key[:10],
            "emptied": {j: {"theta_h_bins": tr[1], "n": [int(observed[j][1][i]) for i in tr[1]]}
                        for j, tr in trimmed.items()}}
        if key[:10] in result["rendered"]:
            continue
        scores = {}
        for name, method in methods.items():
            tables = []
            for j, (rho, _) in trimmed.items():
                path = work / "sparse_tail" / key[:10] / name / f"material_{j}.binary"
                path.parent.mkdir(parents=True, exist_ok=True)
                _write_table(path, method.predict(rho, view="2d")[0])
                tables.append(str(path))
            per_view = []
            for view in scenes[1:]:
                target = work / "sparse_tail" / key[:10] / name / view.name
                _cli(["render", view, "--brdf", ",".join(tables), "--labels", labels, "--out",
                      target, "--force"])
                compare = next(target.glob("*_compare.json"))
                per_view.append(json.loads(compare.read_text())["delta_e_log_mean"])
            scores[name] = {"delta_e_log_mean": float(np.mean(per_view)), "per_view": per_view}
            print(f"T={t}: {name} {np.mean(per_view):.4f}", flush=True)
        result["rendered"][key[:10]] = scores
    args.out.mkdir(parents=True, exist_ok=True)
    write_text(args.out / "sparse_tail.json", json.dumps(result, indent=1) + "\n")
    write_text(args.out / "sparse_tail.md", _markdown(result))
    return 0


def _markdown(result):
    names = list(next(iter(result["rendered"].values())))
    lines = ["# The sparse tail of a flash slice: the planar cards", "",
             f"Command: `{result['command']}`. Flash view {result['flash_view']}, "
             f"{result['materials']} materials (`run`'s own labels); mean ΔE log over the 8 "
             "other views. T = 0 reads every bin (before); T > 0 empties the bins past the last "
             "one of ≥ T samples (the default is T = 20).", "",
             "| T | bins emptied (material: θh bin (n)) | " + " | ".join(names) + " |",
             "|---|---|" + "---|" * len(names)]
    for t, entry in result["thresholds"].items():
        emptied = "; ".join(f"{j}: " + ", ".join(f"{b} ({n})" for b, n in
                                                 zip(e["theta_h_bins"], e["n"]))
                            for j, e in entry["emptied"].items() if e["theta_h_bins"]) or "none"
        scores = result["rendered"][entry["render"]]
        lines.append(f"| {t} | {emptied} | "
                     + " | ".join(f"{scores[m]['delta_e_log_mean']:.2f}" for m in names) + " |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    sys.exit(main())
