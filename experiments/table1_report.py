"""Table 1 outputs of `flashbrdf evaluate`: the paper's numbers, table1.md and the error/run-time plot."""

import json

import numpy as np

from flashbrdf.files.atomic import write_text

METHODS = ("dsgplvm", "dsgplvm-paper", "pca", "noll", "chandraker", "ashikhmin", "oracle")
TRANSFORMS = ("lin", "root", "log")
SPACES = ("rgb", "lab")
STATS = ("mean", "median")
DATASET = "MERL (NBRDF proxy)"
CITATION = ("MERL BRDF database (Matusik, Pfister, Brand & McMillan, \"A Data-Driven Reflectance "
            "Model\", SIGGRAPH 2003; CC-BY-SA-4.0), here rebuilt from the NBRDF neural fits of "
            "Sztrajman, Rainer, Ritschel & Weyrich, \"Neural BRDF Representation and Importance "
            "Sampling\", CGF 40(6) 2021, evaluated at MERL bin centres")


def _paper():
    """Georgoulis et al. 2015, Table 1: {view: {method: {space_transform: {stat: value}}}}."""
    cols2 = ("dsgplvm", "noll", "chandraker", "ashikhmin")        # Ours, [28], [6], [1]
    rows2 = {("rgb", "mean"): [[6.36, 29.47, 6.78, 6.83], [0.23, 8.91, 0.44, 0.43], [0.07, 0.18, 0.19, 0.19]],
             ("rgb", "median"): [[1.43, 5.28, 3.53, 3.52], [0.14, 0.26, 0.46, 0.44], [0.05, 0.10, 0.22, 0.25]],
             ("lab", "mean"): [[6.48, 29.38, 11.20, 10.78], [3.25, 11.59, 5.63, 5.03], [2.57, 5.19, 5.36, 4.81]],
             ("lab", "median"): [[4.66, 14.60, 11.54, 11.78], [2.70, 5.54, 5.79, 5.19], [2.17, 4.72, 5.03, 4.95]]}
    rows3 = {("rgb", "mean"): [[7.28, 31.19], [0.26, 9.98], [0.09, 0.20]],
             ("rgb", "median"): [[1.90, 5.93], [0.16, 0.34], [0.07, 0.11]],
             ("lab", "mean"): [[7.17, 31.05], [3.22, 12.42], [2.50, 4.84]],
             ("lab", "median"): [[5.41, 16.20], [2.71, 5.47], [2.20, 4.46]]}
    out = {}
    for view, cols, rows in (("2d", cols2, rows2), ("3d", cols2[:2], rows3)):
        out[view] = {}
        for (space, stat), per_t in rows.items():
            for transform, values in zip(TRANSFORMS, per_t):
                for method, value in zip(cols, values):
                    out[view].setdefault(method, {}).setdefault(f"{space}_{transform}", {})[stat] = value
        out[view]["dsgplvm-paper"] = out[view]["dsgplvm"]   # both beside the paper's "Ours"
    return out


PAPER_TABLE1 = _paper()


def summarise_errors(per_material):
    """[{metric: value}] -> {metric: {"mean", "median", "n"}}."""
    if not per_material:
        return {}
    out = {}
    for key in per_material[0]:
        v = np.array([m[key] for m in per_material], float)
        out[key] = {"mean": float(np.mean(v)), "median": float(np.median(v)), "n": int(len(v))}
    return out


def _cell(ours, paper):
    a = "—" if ours is None else (f"{ours:.3f}" if ours < 1 else f"{ours:.2f}")
    return a if paper is None else f"{a} ({paper:.2f})"


def table_markdown(summary, view, methods=METHODS):
    """One view's Table 1 block: rows space×stat, columns transform×method; 'ours (paper)'."""
    present = [m for m in methods if m in summary.get(view, {})]
    head = "| | | " + " | ".join(f"{t} {m}" for t in TRANSFORMS for m in present) + " |"
    lines = [head, "|" + "---|" * (2 + len(TRANSFORMS) * len(present))]
    for space in SPACES:
        for stat in STATS:
            cells = []
            for t in TRANSFORMS:
                for m in present:
                    ours = summary[view][m].get(f"{space}_{t}", {}).get(stat)
                    paper = PAPER_TABLE1.get(view, {}).get(m, {}).get(f"{space}_{t}", {}).get(stat)
                    cells.append(_cell(ours, paper))
            lines.append(f"| {space.upper()} | {stat} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def wins(summary, view, method="dsgplvm", rivals=("chandraker", "ashikhmin", "noll")):
    """{rival: bool} — does `method` beat the rival on every LAB metric (mean and median)?"""
    out = {}
    s = summary.get(view, {})
    for r in rivals:
        if method in s and r in s:
            out[r] = all(s[method][f"lab_{t}"][st] < s[r][f"lab_{t}"][st]
                         for t in TRANSFORMS for st in STATS)
    return out


def write_markdown(path, result):
    s, lines = result["summary"], []
    lines += [f"# Table 1 on {DATASET}", "",
              f"Data: {CITATION}.", "",
              f"Command: `{result['command']}`", "",
              f"Protocol: {result['protocol']}", "",
              "Cells: ours (the paper's number for the same column on the real MERL, where it has "
              "one; its LAB figures are on a scale about half the contract's, "
              "docs/results.md, so compare LAB columns as ratios between "
              "methods). dsgplvm-paper = the paper's DS-GPLVM (log-LAB features, no anchoring; "
              "docs/methods.md lists where it departs from the paper); dsgplvm = what `flashbrdf infer` does: the same model with slice "
              "anchoring (its theta_d = 0 row corrected to the observed slice, carried over "
              "theta_d) and the feature space (log-LAB or log-RGB) picked on validation. Both "
              "stand beside the paper's Ours. noll = [28], chandraker = [6], ashikhmin = [1]; pca "
              "(Nielsen et al. 2015) and oracle (ridge projection of the true table onto the "
              "training PCA basis) are ours only. Errors as the contract defines them.", ""]
    for view, title in (("2d", "2D BRDFs"), ("3d", "3D BRDFs")):
        if view not in s:
            continue
        n = next(iter(next(iter(s[view].values())).values()))["n"]
        lines += [f"## {title} (all test predictions pooled, n = {n} per method)", "",
                  table_markdown(s, view), ""]
        for m in ("dsgplvm", "dsgplvm-paper"):
            if m in s[view]:
                lines += [f"{m} beats on every LAB metric (mean and median): "
                          f"{json.dumps(wins(s, view, m))}; vs pca/oracle: "
                          f"{json.dumps(wins(s, view, m, rivals=('pca', 'oracle')))}", ""]
    mp = result.get("mean_performing")
    if mp:
        lines += [f"## Mean-performing experiment (#{mp['experiment']}, the paper's choice: "
                  "dsgplvm 2D LAB-log mean closest to the mean over experiments)", "",
                  table_markdown(mp["summary"], "2d"), ""]
    lines += ["## Cost per method", "", "| method | train s | 2D infer s/material | "
              "3D infer s/material | peak MB |", "|---|---|---|---|---|"]
    for m, c in result["costs"].items():
        f = lambda x: "—" if x is None else f"{x:.3g}"   # noqa: E731
        lines.append(f"| {m} | {f(c.get('train_s'))} | {f(c.get('infer_2d_s'))} | "
                     f"{f(c.get('infer_3d_s'))} | {f(c.get('peak_mb'))} |")
    if result.get("ablations"):
        lines += ["", "## Ablations (2D, pooled over the experiments where they ran)", "",
                  "| variant | LAB-log mean | LAB-log median | RGB-log mean | n |", "|---|---|---|---|---|"]
        for name, a in result["ablations"].items():
            lines.append(f"| {name} | {a['lab_log']['mean']:.3f} | {a['lab_log']['median']:.3f} | "
                         f"{a['rgb_log']['mean']:.4f} | {a['lab_log']['n']} |")
    lines += ["", "## Hyperparameters chosen on validation", ""]
    for h in result["hyperparameters"]:
        lines.append(f"- experiment {h['experiment']}: " + json.dumps(h["chosen"], default=str))
    lines += ["", "## Notes", ""] + [f"- {n}" for n in result.get("notes", [])]
    write_text(path, "\n".join(lines) + "\n")
