"""Generalisation beyond MERL: every method scored on measured materials it was not trained on.

    nice -n 10 python -m benchmarks.generalisation --merl-dir MERL --test-dir RGL
        [--folds 5 | --fold-groups benchmarks/rgl_kinds.json] [--seed 0] [--out benchmarks/results]

MERL and RGL here are the MERL (NBRDF proxy) and RGL (NBRDF proxy) tables written by
../shared/tools/merl_proxy.py (the RGL ones with --weights ../shared/data/rgl-nbrdf-dev/...).

Two settings, each 2D Table-1 metrics per material and per θd band:
- "merl-only": trained on every --merl-dir table, tested on every --test-dir table (what the shipped
  model, trained on MERL only, meets on a felt or a paper);
- "merl+test-folds": the --test-dir tables cut into seeded folds; each fold is predicted by methods
  trained on MERL plus the other folds, so no claim rests on a material that was trained on (what
  `flashbrdf train --merl-dir MERL --merl-dir MY_TABLES` gives for materials of the same kinds).
Hyperparameters are chosen exactly as `flashbrdf train` chooses them (infer.model_selection.tune_baselines:
a seeded 80/20 split of the training tables, never the test tables), including the DS-GPLVM's
variance calibration κ. Also reported: the share of held-out (θh, θd > 0, channel) bins inside the
central 90% interval of the default method, the novelty warnings, and prediction / fit times.
"dsgplvm-relative" is the relative representation (infer.relative), scored beside the default.
--methods picks a subset (the default "dsgplvm" and the baselines are always needed for the ratios).

So that the three accuracy checks of issue 11 come from one run, the same run can also do
- --merl-quick: the MERL protocol of `flashbrdf evaluate --quick` (experiment 0, 2D only) on
  --merl-dir (experiments.evaluate.run_evaluation), every method's six 2D Table 1 errors;
- --ball MODEL [--ball-merl-dir DIR]: benchmarks/diligent_ball.py with that model (the shipped
  default; needs ../shared/data/real; DIR holds its training tables), every method's ΔE-log over
  the 95 other lights.
Writes OUT/generalisation.{json,md}.
"""

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from flashbrdf.brdf import merl, metrics
from flashbrdf.infer import TrainingSet, make_method, novelty_warning
from flashbrdf.infer.uncertainty import standardised_residuals
from flashbrdf.experiments.evaluate import PAPER_FIXED, run_evaluation
from flashbrdf.infer.model_selection import tune_baselines

BANDS_DEG = ((0, 30), (30, 60), (60, 75), (75, 90))
METHODS = ("dsgplvm", "dsgplvm-paper", "dsgplvm-relative", "pca", "noll", "chandraker",
           "ashikhmin")
BASELINES = ("pca", "noll", "chandraker", "ashikhmin")


def band_errors(pred, true):
    """2D LAB-log over all bins and over each θd band of BANDS_DEG: [all, band...]."""
    theta_d = np.degrees(merl.theta_d_centres())
    out = [metrics.brdf_error(pred, true)]
    for low, high in BANDS_DEG:
        cols = (theta_d >= low) & (theta_d < high)
        out.append(metrics.brdf_error(pred[:, cols], true[:, cols]))
    return out


def kind_folds(names, groups):
    """One fold per kind: groups {kind: [fnmatch patterns of material names]} -> [index arrays],
    in the groups' order. Every name must match exactly one kind."""
    from fnmatch import fnmatchcase
    kinds = [[k for k, patterns in groups.items() if any(fnmatchcase(n, p) for p in patterns)]
             for n in names]
    odd = [(n, k) for n, k in zip(names, kinds) if len(k) != 1]
    if odd:
        raise SystemExit(f"--fold-groups: {odd[0][0]} matches {len(odd[0][1])} kinds, not one")
    return [np.array([i for i, k in enumerate(kinds) if k[0] == kind], dtype=np.int64)
            for kind in groups]


def fold_training(merl_set, test, k, n_folds=5, seed=0, folds=None):
    """(training set, sorted held-out test indices) of fold k of the "merl+test-folds" setting
    (seeded folds, or the given index arrays, e.g. kind_folds); k = "merl-only": MERL alone,
    every test table held out."""
    if k == "merl-only":
        return merl_set, np.arange(len(test))
    if folds is None:
        folds = np.array_split(np.random.default_rng(seed).permutation(len(test)), n_folds)
    rest = np.sort(np.concatenate([f for j, f in enumerate(folds) if j != int(k)]))
    both = TrainingSet(list(merl_set.names) + [test.names[i] for i in rest],
                       np.concatenate([merl_set.slices, test.slices[rest]]),
                       np.concatenate([merl_set.tables_2d, test.tables_2d[rest]]))
    return both, np.sort(folds[int(k)])


def interval_hits(method, rho, true, coverage=0.9):
    """(bins inside the central `coverage` interval, bins scored), θd > 0, in the method's
    feature space (infer.uncertainty.standardised_residuals)."""
    from scipy.stats import norm
    z = standardised_residuals(method, rho, true)
    return int((z <= norm.ppf(0.5 + coverage / 2)).sum()), int(z.size)


def fit_all(training, seed, methods=METHODS):
    """{method: fitted estimator}, {method: fit seconds}, hyperparameters as `flashbrdf train`."""
    t0 = time.perf_counter()
    params = tune_baselines(training, seed=seed)
    tune_s = time.perf_counter() - t0
    fitted, seconds = {}, {}
    for name in methods:
        if name == "dsgplvm":
            kw = params["dsgplvm"] | {"anchor": True, "seed": seed}
        elif name == "dsgplvm-paper":
            kw = {"seed": seed} | PAPER_FIXED
        elif name == "dsgplvm-relative":
            kw = {"representation": "relative", "seed": seed}
        else:
            kw = params.get(name, {})
        start = time.perf_counter()
        fitted[name] = make_method("dsgplvm" if name.startswith("dsgplvm") else name, **kw) \
            .fit(training)
        seconds[name] = time.perf_counter() - start
    seconds["tune"] = tune_s
    return fitted, seconds, params


def score(fitted, test, index, records, kind=None):
    """Append one record per (method, test material) to `records` (with its kind, if given)."""
    for name, method in fitted.items():
        for i in index:
            start = time.perf_counter()
            pred, variance = method.predict(test.slices[i], "2d")
            ms = 1e3 * (time.perf_counter() - start)
            errs = band_errors(pred, test.tables_2d[i])
            rec = {"method": name, "material": test.names[i], "lab_log": errs[0],
                   "bands": errs[1:], "predict_ms": ms} | ({"kind": kind} if kind else {})
            if name == "dsgplvm":
                rec["hits"], rec["bins"] = interval_hits(method, test.slices[i], test.tables_2d[i])
                rec["novelty"], warning = novelty_warning(method, test.slices[i])
                rec["warned"] = warning is not None
            records.append(rec)


def summarise(records):
    out = {}
    for name in METHODS:
        rs = [r for r in records if r["method"] == name]
        if not rs:
            continue
        lab = np.array([r["lab_log"] for r in rs])
        bands = np.array([r["bands"] for r in rs])
        out[name] = {"lab_log_mean": float(lab.mean()), "lab_log_median": float(np.median(lab)),
                     "bands_mean": bands.mean(0).tolist(),
                     "predict_ms": float(np.median([r["predict_ms"] for r in rs])),
                     "materials": len(rs)}
        if name == "dsgplvm":
            out[name]["coverage90"] = float(sum(r["hits"] for r in rs) / sum(r["bins"] for r in rs))
            out[name]["warned"] = int(sum(r["warned"] for r in rs))
    return out


def markdown(result):
    lines = ["# Generalisation: methods trained on MERL (NBRDF proxy), tested on RGL (NBRDF proxy)",
             "", f"`{result['command']}`", ""]
    for setting, block in result["settings"].items():
        s = block["summary"]
        best = min(BASELINES, key=lambda m: s[m]["lab_log_mean"])
        lines += [f"## {setting}", "", block["what"], "",
                  "| method | 2D LAB-log mean / median | " + " | ".join(
                      f"θd {a}–{b}°" for a, b in BANDS_DEG) + " | predict ms |",
                  "|---|---|" + "---|" * len(BANDS_DEG) + "---|"]
        present = [m for m in METHODS if m in s]
        for name in present:
            r = s[name]
            lines.append(f"| {name} | {r['lab_log_mean']:.2f} / {r['lab_log_median']:.2f} | "
                         + " | ".join(f"{v:.2f}" for v in r["bands_mean"])
                         + f" | {r['predict_ms']:.0f} |")
        d = s["dsgplvm"]
        lines += ["", f"- Best baseline by mean: **{best}**. dsgplvm / {best}: mean "
                  f"{d['lab_log_mean'] / s[best]['lab_log_mean']:.2f}×, median "
                  f"{d['lab_log_median'] / s[best]['lab_log_median']:.2f}× (target ≤ 0.9×).",
                  f"- Central 90% intervals of dsgplvm hold {100 * d['coverage90']:.1f}% of the "
                  f"held-out bins (θd > 0; target 80–95%).",
                  f"- Novelty warnings: {d['warned']} of {d['materials']} materials.",
                  "- Fit seconds: " + ", ".join(f"{k} {v:.0f}" for k, v in
                                                  block["fit_seconds"].items()), ""]
        lines += ["| material | " + " | ".join(present) + " |",
                  "|---|" + "---|" * len(present)]
        for mat in block["materials"]:
            row = {r["method"]: r["lab_log"] for r in block["records"] if r["material"] == mat}
            if row:   # a --fold-runs part scores only its folds' materials
                lines.append(f"| {mat} | " + " | ".join(f"{row[m]:.2f}" for m in present) + " |")
        lines += kinds_markdown(block, present) or warning_lines(block["records"])
        lines.append("")
    lines += checks_markdown(result)
    return "\n".join(lines)


def kinds_markdown(block, present):
    """Per held-out kind, each method's 2D LAB-log mean, and dsgplvm over the best baseline of
    that kind (only for a merl+test-kinds block)."""
    kinds = list(dict.fromkeys(r["kind"] for r in block["records"] if "kind" in r))
    if not kinds:
        return []
    lines = ["", "Per held-out kind, 2D LAB-log mean, and the share of θd > 0 bins inside dsgplvm's "
             "central 90% intervals:", "",
             "| kind | n | " + " | ".join(present) + " | dsgplvm / best baseline | 90% coverage |",
             "|---|---|" + "---|" * len(present) + "---|---|"]
    for kind in kinds:
        mean = {m: float(np.mean([r["lab_log"] for r in block["records"]
                                  if r.get("kind") == kind and r["method"] == m]))
                for m in present}
        best = min((m for m in BASELINES if m in mean), key=mean.get)
        ds = [r for r in block["records"] if r.get("kind") == kind and r["method"] == "dsgplvm"]
        cover = sum(r["hits"] for r in ds) / max(1, sum(r["bins"] for r in ds))
        lines.append(f"| {kind} | {len(ds)} | " + " | ".join(f"{mean[m]:.2f}" for m in present)
                     + f" | {mean['dsgplvm'] / mean[best]:.2f}× {best} | {100 * cover:.1f}% |")
    return lines + warning_lines(block["records"])


def warning_lines(records, lost_ratio=1.2):
    """Issue 36's warning check: among materials where dsgplvm's LAB-log exceeds lost_ratio × the
    best baseline's on that material, the share warned (recall); among the others, the share warned
    (false-warning rate)."""
    ds = {r["material"]: r for r in records if r["method"] == "dsgplvm"}
    best = {m: min(r["lab_log"] for r in records if r["material"] == m and r["method"] in BASELINES)
            for m in ds}
    lost = [m for m in ds if ds[m]["lab_log"] > lost_ratio * best[m]]
    kept = [m for m in ds if m not in lost]
    warned = [m for m in ds if ds[m]["warned"]]
    recall = f"{sum(m in warned for m in lost)}/{len(lost)}" if lost else "— (none lost)"
    return ["", f"Warning: dsgplvm lost (> {lost_ratio}× the material's best baseline) on "
            f"{len(lost)}: {', '.join(lost) or 'none'}; warned {len(warned)}: "
            f"{', '.join(warned) or 'none'}. Recall {recall}; false warnings "
            f"{sum(m in warned for m in kept)}/{len(kept)} "
            f"({100 * sum(m in warned for m in kept) / max(1, len(kept)):.0f}%)."]


def band_check(summary):
    """Issue 11's RGL checks for one setting: {ratio_mean, ratio_median (to the best baseline by
    mean), band_ratios (dsgplvm over the best baseline of each θd band)}."""
    d = summary["dsgplvm"]
    best = min(BASELINES, key=lambda m: summary[m]["lab_log_mean"])
    best_band = np.min([summary[m]["bands_mean"] for m in BASELINES], axis=0)
    return {"best": best, "ratio_mean": d["lab_log_mean"] / summary[best]["lab_log_mean"],
            "ratio_median": d["lab_log_median"] / summary[best]["lab_log_median"],
            "band_ratios": (np.array(d["bands_mean"]) / best_band).tolist()}


def merl_quick(merl_dir, seed):
    """The MERL protocol of `flashbrdf evaluate --quick` (experiment 0), 2D only: {method:
    {metric: {mean, median}}} with metric each of Table 1's six."""
    with tempfile.TemporaryDirectory() as folder:
        result = run_evaluation(merl_dir, folder, quick=True, experiments_3d=0, seed=seed,
                                command="flashbrdf evaluate --quick (experiment 0, 2D)")
    return {m: {k: {"mean": v["mean"], "median": v["median"]} for k, v in errs.items()}
            for m, errs in result["summary"]["2d"].items()}


def ball(model, merl_dir):
    """benchmarks/diligent_ball.py with `model`: {method: ΔE-log mean over the 95 lights}."""
    from benchmarks import diligent_ball
    from benchmarks._real_common import RESULTS
    with tempfile.TemporaryDirectory() as work:
        try:
            rc = diligent_ball.main(["--model", str(model), "--merl-dir", str(merl_dir),
                                     "--work", work])
        except SystemExit as stop:          # a stage failed (e.g. no ../shared/data/real)
            print(f"ball: {stop}", flush=True)
            return {}
    if rc:
        return {}
    result = json.loads((RESULTS / "diligent_ball.json").read_text())
    return {m: info["delta_e_log_mean"]["mean"] for m, info in result["methods"].items()}


def checks_markdown(result):
    """The side-by-side block of issue 11's numbers, from this one run."""
    lines = ["## Issue 11's checks, side by side (this run)", ""]
    for setting, block in result["settings"].items():
        c = block["check"]
        lines.append(f"- RGL {setting}: dsgplvm / {c['best']} mean {c['ratio_mean']:.2f}×, median "
                     f"{c['ratio_median']:.2f}× (target ≤ 0.90×); θd bands over the best baseline "
                     "of each band " + " / ".join(f"{v:.2f}×" for v in c["band_ratios"])
                     + " (target ≤ 1.10×).")
    q = result.get("merl_quick")
    if q:
        metrics_ = ("lab_lin", "lab_root", "lab_log")
        lines += ["", "MERL (NBRDF proxy) protocol, `evaluate --quick` (experiment 0, 20 test "
                  "tables), 2D mean / median:", "",
                  "| method | " + " | ".join(metrics_) + " |", "|---|" + "---|" * len(metrics_)]
        for m, errs in q.items():
            lines.append(f"| {m} | " + " | ".join(
                f"{errs[k]['mean']:.2f} / {errs[k]['median']:.2f}" for k in metrics_) + " |")
    b = result.get("ball")
    if b:
        lines += ["", "DiLiGenT ball (benchmarks/diligent_ball.py, model " + result["ball_model"]
                  + "), ΔE-log mean over 95 lights: "
                  + ", ".join(f"{m} {v:.2f}" for m, v in b.items()) + "."]
    lines.append("")
    return lines


def add_methods_panel(result):
    """result["methods"]: what benchmarks/error_vs_runtime.py plots as the OOD panel, from the
    MERL-only setting (the shipped model's situation): {name: {lab_log_mean, lab_log_median,
    predict_ms, fit_s}}."""
    block = result["settings"].get("merl-only") or next(iter(result["settings"].values()))
    result["methods"] = {name: {"lab_log_mean": r["lab_log_mean"],
                                "lab_log_median": r["lab_log_median"],
                                "predict_ms": r["predict_ms"],
                                "fit_s": block["fit_seconds"].get(name)}
                         for name, r in block["summary"].items()}


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--merl-dir", help="training tables (required unless --merge)")
    p.add_argument("--test-dir", help="test tables (required unless --merge)")
    p.add_argument("--folds", type=int, default=5)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--settings", default="merl-only,merl+test-folds")
    p.add_argument("--methods", default=",".join(METHODS))
    p.add_argument("--merl-quick", action="store_true")
    p.add_argument("--ball", metavar="MODEL")
    p.add_argument("--ball-merl-dir", metavar="DIR",
                   help="the ball model's training tables, for its 3D predictions (default: "
                        "--merl-dir; the shipped model also needs the RGL tables beside them)")
    p.add_argument("--fold-groups", metavar="JSON",
                   help="hold out one kind at a time instead of seeded folds: a JSON file "
                        "{kind: [fnmatch patterns of test material names]} (e.g. "
                        "benchmarks/rgl_kinds.json); the setting is then merl+test-kinds")
    p.add_argument("--fold-runs", default=None, metavar="K,K",
                   help="compute only these folds (default all): split one run over processes")
    p.add_argument("--merge", nargs="+", metavar="JSON",
                   help="combine the JSON of such parts (same seed and folds) into one result")
    p.add_argument("--out", default=str(Path(__file__).resolve().parent / "results"))
    args = p.parse_args(argv)
    if args.merge:
        return merge_parts(args.merge, Path(args.out))
    if not (args.merl_dir and args.test_dir):
        p.error("--merl-dir and --test-dir are required (or --merge)")
    merl_set = TrainingSet.from_merl_dir(args.merl_dir)
    test = TrainingSet.from_merl_dir(args.test_dir)
    result = {"command": "nice -n 10 python -m benchmarks.generalisation "
                         + " ".join(sys.argv[1:] if argv is None else argv),
              "train": "MERL (NBRDF proxy)", "test": "RGL (NBRDF proxy)", "settings": {}}
    wanted = args.settings.split(",")
    methods = [m for m in METHODS if m in args.methods.split(",") + ["dsgplvm", *BASELINES]]
    if "merl-only" in wanted:
        fitted, seconds, params = fit_all(merl_set, args.seed, methods)
        records = []
        score(fitted, test, range(len(test)), records)
        result["settings"]["merl-only"] = {
            "what": f"Trained on the {len(merl_set)} MERL (NBRDF proxy) tables only.",
            "fit_seconds": seconds, "params": params, "records": records,
            "materials": list(test.names), "summary": summarise(records)}
        print("merl-only", json.dumps(summarise(records)["dsgplvm"]), flush=True)
    if "merl+test-folds" in wanted:
        groups = json.loads(Path(args.fold_groups).read_text()) if args.fold_groups else None
        folds = kind_folds(test.names, groups) if groups else None
        n_folds = len(folds) if groups else args.folds
        records, fit_s = [], {}
        runs = range(n_folds) if args.fold_runs is None else \
            [int(k) for k in args.fold_runs.split(",")]
        for k in runs:
            both, fold = fold_training(merl_set, test, k, args.folds, args.seed, folds)
            fitted, seconds, _ = fit_all(both, args.seed, methods)
            score(fitted, test, fold, records, kind=list(groups)[k] if groups else None)
            for name, s in seconds.items():
                fit_s[name] = fit_s.get(name, 0.0) + s / len(runs)
            print(f"fold {k}", json.dumps(summarise(records)["dsgplvm"]), flush=True)
        what = (f"{n_folds} seeded folds of the test tables: each fold predicted by methods "
                f"trained on MERL plus the other folds (never on the fold itself)." if not groups
                else f"One kind held out at a time ({args.fold_groups}: "
                     + ", ".join(f"{k} {len(f)}" for k, f in zip(groups, folds))
                     + "): each kind predicted by methods trained on MERL plus the other kinds, "
                       "so no material of its kind was trained on.")
        result["settings"]["merl+test-kinds" if groups else "merl+test-folds"] = {
            "what": what, "fit_seconds": fit_s, "records": records,
            "materials": list(test.names), "summary": summarise(records)}
    for block in result["settings"].values():
        block["check"] = band_check(block["summary"])
    add_methods_panel(result)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    write_results(out, result)                 # the RGL tables survive a failure below
    if args.merl_quick:
        result["merl_quick"] = merl_quick(args.merl_dir, args.seed)
        print("merl quick", json.dumps(result["merl_quick"].get("dsgplvm")), flush=True)
        write_results(out, result)
    if args.ball:
        result["ball_model"] = args.ball
        result["ball"] = ball(args.ball, args.ball_merl_dir or args.merl_dir)
        print("ball", json.dumps(result["ball"]), flush=True)
        write_results(out, result)
    print(markdown(result))
    return 0


def merge_parts(paths, out):
    """One result from the JSON of runs that each did part of the work (--fold-runs, --settings):
    records of a setting are pooled, fit seconds averaged over the parts, extras kept."""
    parts = [json.loads(Path(p).read_text()) for p in paths]
    result = {"command": " ; ".join(p["command"] for p in parts), "train": parts[0]["train"],
              "test": parts[0]["test"], "settings": {}}
    for part in parts:
        for key in ("merl_quick", "ball", "ball_model"):
            if key in part:
                result[key] = part[key]
        for setting, block in part["settings"].items():
            into = result["settings"].setdefault(setting, {
                "what": block["what"], "records": [], "materials": block["materials"],
                "fit_seconds": {}, "parts": 0})
            into["records"] += block["records"]
            into["parts"] += 1
            for name, sec in block["fit_seconds"].items():
                into["fit_seconds"][name] = into["fit_seconds"].get(name, 0.0) + sec
            if "params" in block:
                into["params"] = block["params"]
    for block in result["settings"].values():
        n_parts = block.pop("parts")
        block["fit_seconds"] = {k: v / n_parts for k, v in block["fit_seconds"].items()}
        block["summary"] = summarise(block["records"])
        block["check"] = band_check(block["summary"])
    add_methods_panel(result)
    out.mkdir(parents=True, exist_ok=True)
    write_results(out, result)
    print(markdown(result))
    return 0


def write_results(out, result):
    (out / "generalisation.json").write_text(json.dumps(result, indent=1, default=float) + "\n")
    (out / "generalisation.md").write_text(markdown(result) + "\n")


if __name__ == "__main__":
    sys.exit(main())
