"""How our Table 1 LAB figures compare with the paper's: the chandraker baseline, which learns
nothing, scored on every MERL table in RGB (the contract's metric) and in CIELAB with the
ε-mapped values divided by a factor s before the Lab map (s = 1 is the contract's: white at Y = 1).

chandraker's prediction depends only on the table itself, so its errors differ from the paper's
[6] column only by the data (NBRDF proxy against the real MERL) and the metric. Where the RGB
figures agree and the LAB ones do not, the paper's CIELAB conversion was scaled unlike ours; the
s whose six LAB figures (lin, root, log; mean, median) sit closest to the paper's (least summed
|ln ratio|) says by how much. Writes lab_scale.md and lab_scale.json.

    nice -n 10 python -m benchmarks.lab_scale --merl-dir /work/data/merl
"""

import argparse
import json
import os
import sys

import numpy as np

from flashbrdf.brdf import merl, metrics, views
from flashbrdf.brdf.colour import linear_rgb_to_lab
from flashbrdf.experiments.table1_report import PAPER_TABLE1
from flashbrdf.files.atomic import write_text
from flashbrdf.infer import Chandraker

SCALES = (1, 2, 4, 6, 8, 9, 10, 11, 12, 16)
EPSILON = {"lin": lambda x: x, "root": np.sqrt, "log": np.log1p}


def scaled_lab_errors(pred, true, scale):
    """{"lin", "root", "log"}: mean ΔE*ab of Lab(ε(ρ) / scale), over the bins valid in `true`
    (the contract's LAB error at scale 1; brdf.metrics.brdf_error checks that)."""
    valid = np.isfinite(true).all(axis=-1)
    p = np.where(np.isfinite(pred[valid]), np.maximum(pred[valid], 0.0), 0.0)
    t = np.maximum(true[valid], 0.0)
    return {k: float(np.mean(np.linalg.norm(linear_rgb_to_lab(f(p) / scale)
                                            - linear_rgb_to_lab(f(t) / scale), axis=-1)))
            for k, f in EPSILON.items()}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--merl-dir", default="/work/data/merl")
    ap.add_argument("--out", default=os.path.join(os.path.dirname(os.path.abspath(__file__)),
                                                  "results"))
    args = ap.parse_args(argv)
    method = Chandraker().fit(None)
    rgb, lab = [], {s: [] for s in SCALES}
    for _, path in merl.list_merl(args.merl_dir):
        table = merl.read_merl(path)
        truth = views.table_2d(table)
        pred = method.predict(views.flash_slice(table)[0], "2d")[0]
        errs = metrics.brdf_errors(pred, truth)
        rgb.append({k: errs[f"rgb_{k}"] for k in EPSILON})
        for s in SCALES:
            lab[s].append(scaled_lab_errors(pred, truth, s))
        assert abs(lab[1][-1]["log"] - errs["lab_log"]) < 1e-9 * max(1.0, errs["lab_log"])

    paper = PAPER_TABLE1["2d"]["chandraker"]

    def stats(rows, k):
        v = [r[k] for r in rows]
        return {"mean": float(np.mean(v)), "median": float(np.median(v))}

    result = {"n": len(rgb), "rgb": {k: stats(rgb, k) for k in EPSILON},
              "lab": {str(s): {k: stats(lab[s], k) for k in EPSILON} for s in SCALES},
              "paper_chandraker": paper}
    misfit = {s: sum(abs(np.log(result["lab"][str(s)][k][st] / paper[f"lab_{k}"][st]))
                     for k in EPSILON for st in ("mean", "median")) for s in SCALES}
    best = min(misfit, key=misfit.get)
    result["best_scale"], result["misfit"] = best, {str(s): float(m) for s, m in misfit.items()}

    def row(label, cells):
        return f"| {label} | " + " | ".join(cells) + " |"

    def cell(ours, k, space):
        p = paper[f"{space}_{k}"]
        return (f"{ours[k]['mean']:.3g} / {ours[k]['median']:.3g} "
                f"({p['mean']:.3g} / {p['median']:.3g})")

    lines = ["# Table 1's LAB scale: chandraker against the paper's [6]", "",
             "Command: `nice -n 10 python -m benchmarks.lab_scale --merl-dir MERL`", "",
             f"chandraker (ρ(θh, θd) = the slice; nothing learnt) on {len(rgb)} MERL (NBRDF proxy) "
             "tables, 2D, mean / median; the paper's [6] figure in brackets. LAB at scale s is "
             "the contract's LAB error with ε(ρ) / s in place of ε(ρ) (s = 1: the contract).", "",
             "| | lin | root | log |", "|---|---|---|---|",
             row("RGB (contract)", [cell(result["rgb"], k, "rgb") for k in EPSILON])]
    for s in SCALES:
        label = "LAB (contract)" if s == 1 else f"LAB, s = {s}"
        lines.append(row(label + f", misfit {misfit[s]:.2f}",
                         [cell(result["lab"][str(s)], k, "lab") for k in EPSILON]))
    lines += ["", f"Closest to the paper's six LAB figures: s = {best} (misfit: the sum of "
              "|ln(ours / paper)| over them). The RGB figures agree within the data's "
              "difference; the contract's LAB ones are about twice the paper's, so Table 1's "
              "LAB columns compare with the paper's as ratios between methods, not as values."]
    write_text(os.path.join(args.out, "lab_scale.json"), json.dumps(result, indent=1) + "\n")
    write_text(os.path.join(args.out, "lab_scale.md"), "\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
