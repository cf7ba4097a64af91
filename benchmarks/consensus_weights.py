"""The consensus' knot weights and the warning's threshold, chosen and measured on the RGL (NBRDF proxy)
kind hold-out, nested so that no kind's figure comes from a choice it took part in.

    nice -n 10 python -m benchmarks.consensus_weights --merl-dir MERL --test-dir RGL
        [--fold-groups benchmarks/rgl_kinds.json | --random-folds 5] [--seed 0] [--work DIR]
        [--out benchmarks/results]

--random-folds N scores seeded random folds instead of kinds (the partition of
benchmarks.generalisation's "merl+test-folds" setting at the same --seed): every held-out material
then has others of its kind in training, as a new material of a kind the model knows would.

1. For each kind k, every method is trained as `flashbrdf train` trains it on MERL plus the other
   kinds (benchmarks/generalisation.py: fit_all, fold_training) and predicts kind k's materials:
   the consensus' members (the anchored DS-GPLVM's own table, Nöll's, PCA's: DSGPLVMMethod.
   member_tables), the DS-GPLVM's own variance, chandraker and ashikhmin. Also once trained on MERL
   alone, predicting all of them (the paper's setting). Predictions are cached in --work.
2. Knot weights (infer.consensus: per θd knot, over the members, on the simplex) minimise the mean
   over materials of the LAB-log error of the consensus. "shipped": fitted on every kind's held-out
   predictions (what infer.consensus.CONSENSUS_WEIGHTS holds); "nested": kind k is scored with
   weights fitted on the other kinds' held-out predictions only. The reported figures are nested.
3. Warning: a material is "lost" when the consensus' error exceeds 1.2× the best baseline's on it.
   The threshold on the DS-GPLVM/Nöll disagreement (infer.warning) is the 85th percentile of the
   disagreement over the materials not lost; nested as above. Recall over lost materials and the
   false-warning rate over the others are reported, also for infer.warning's full rule (with the
   novelty and sparse-slice reasons) at the shipped constants.
4. Central 90% intervals of the consensus (the DS-GPLVM's variance plus κ · the members' spread,
   as DSGPLVMMethod.predict gives them), per held-out kind, θd > 0 bins.
"""

import argparse
import json
import sys
from pathlib import Path

import numpy as np
from scipy.optimize import minimize
from scipy.stats import norm

from benchmarks.generalisation import BANDS_DEG, band_errors, fit_all, fold_training, kind_folds
from flashbrdf.brdf import colour, merl
from flashbrdf.brdf.metrics import lab_log_features
from flashbrdf.infer import TrainingSet
from flashbrdf.infer.consensus import (
    CONSENSUS_MEMBERS,
    CONSENSUS_WEIGHTS,
    THETA_D_KNOTS_DEG,
    THETA_H_KNOTS_DEG,
    consensus_table,
    member_spread,
    weights_per_bin,
)
from flashbrdf.infer.estimator import InferenceMethod
from flashbrdf.infer.warning import DISAGREEMENT_WARN_DE, disagreement, prediction_warning

BASELINES = ("pca", "noll", "chandraker", "ashikhmin")
LOST_RATIO = 1.2
FALSE_WARNING_QUANTILE = 0.85


def predict_fold(method_set, test, index):
    """{material index: {"members": (M, 90, 90, 3), "var_ds", "baselines": {name: table},
    "calibration", "feature_space", "warning": record}} for one fitted method set."""
    ds = method_set["dsgplvm"]
    out = {}
    for i in index:
        rho = test.slices[i]
        members = ds.member_tables(rho)
        _, var_ds = InferenceMethod.predict(ds, rho, "2d")
        record, _ = prediction_warning(ds, rho)
        out[int(i)] = {"members": np.stack([members[m] for m in CONSENSUS_MEMBERS]),
                       "var_ds": var_ds, "calibration": float(ds.calibration),
                       "feature_space": ds.feature_space, "warning": record,
                       "baselines": {b: method_set[b].predict(rho, "2d")[0] for b in BASELINES}}
    return out


def cached(work, tag, compute):
    path = Path(work) / f"{tag}.npz"
    if path.exists():
        return json_load(path)
    result = compute()
    arrays, meta = {}, {}
    for i, r in result.items():
        arrays[f"{i}_members"] = r["members"]
        arrays[f"{i}_var_ds"] = r["var_ds"]
        for b, t in r["baselines"].items():
            arrays[f"{i}_{b}"] = t
        meta[i] = {k: r[k] for k in ("calibration", "feature_space", "warning")}
    np.savez(path, meta=np.array(json.dumps(meta, default=float)), **arrays)
    return json_load(path)


def json_load(path):
    z = np.load(path)
    meta = json.loads(str(z["meta"]))
    return {int(i): m | {"members": z[f"{i}_members"], "var_ds": z[f"{i}_var_ds"],
                         "baselines": {b: z[f"{i}_{b}"] for b in BASELINES}}
            for i, m in meta.items()}


N_KNOTS = (len(THETA_H_KNOTS_DEG), len(THETA_D_KNOTS_DEG))


def knots_from(z, n_members):
    """Knot weights (H, D, M) on the simplex from free parameters (H·D·(M − 1)) by softmax."""
    z = np.asarray(z).reshape(*N_KNOTS, n_members - 1)
    z = np.concatenate([np.zeros(N_KNOTS + (1,)), z], axis=2)
    e = np.exp(z - z.max(axis=2, keepdims=True))
    return e / e.sum(axis=2, keepdims=True)


def fit_knots(samples):
    """Knot weights (H, D, M) minimising the mean LAB-log error of the consensus over samples,
    each (member metric features on the truth's valid bins (M, n, 3), truth's (n, 3), the bins'
    θh and θd indices (n,), (n,)). Powell from equal weights."""
    n_members = samples[0][0].shape[0]

    def objective(z):
        w = weights_per_bin(knots_from(z, n_members))
        return np.mean([np.linalg.norm(np.einsum("nm,mnc->nc", w[ih, jd], f) - t, axis=-1).mean()
                        for f, t, ih, jd in samples])
    best = minimize(objective, np.zeros(N_KNOTS[0] * N_KNOTS[1] * (n_members - 1)),
                    method="Powell", options={"maxfev": 8000, "xtol": 1e-2, "ftol": 1e-5})
    return knots_from(best.x, n_members)


def sample_of(members, true):
    ok = np.isfinite(true).all(-1) & np.isfinite(members).all(-1).all(0)
    ih, jd = np.nonzero(ok)
    return lab_log_features(members[:, ok]), lab_log_features(true[ok]), ih, jd


def coverage_hits(table, variance, true, space, coverage=0.9):
    """(bins inside the central interval, bins), θd > 0, in the method's feature space."""
    resid = colour.rho_to_features(np.nan_to_num(true), space=space) - \
        colour.rho_to_features(np.nan_to_num(table), space=space)
    ok = np.isfinite(true).all(-1)[..., None] & np.isfinite(variance) & (variance > 0)
    ok[:, 0] = False
    z = np.abs(resid[ok]) / np.sqrt(variance[ok])
    return int((z <= norm.ppf(0.5 + coverage / 2)).sum()), int(z.size)


def raw_z(p, true, knots):
    """(|z| (90, 90, 3) NaN where not scored, θd > 0) of a consensus under the variance
    DSGPLVMMethod.predict gives it."""
    space = p["feature_space"]
    spread = member_spread(colour.rho_to_features(np.nan_to_num(p["members"]), space=space), knots)
    var = p["var_ds"] + p["calibration"] * np.where(np.isnan(p["var_ds"]), np.nan, spread)
    cons = consensus_table(p["members"], knots)
    resid = colour.rho_to_features(np.nan_to_num(true), space=space) - \
        colour.rho_to_features(np.nan_to_num(cons), space=space)
    ok = np.isfinite(true).all(-1)[..., None] & np.isfinite(var) & (var > 0)
    ok[:, 0] = False
    return np.where(ok, np.abs(resid) / np.sqrt(np.where(ok, var, 1.0)), np.nan)


def fit_variance_factors(zs, coverage=0.9):
    """Per θd knot band (0–30, 30–60, 60–75, 75–90°): the factor on the variance that makes
    the central `coverage` interval hold that share of the band's pooled bins."""
    theta_d = np.degrees(merl.theta_d_centres())
    out = []
    for lo, hi in BANDS_DEG:
        z = np.concatenate([v[:, (theta_d >= lo) & (theta_d < hi)].ravel() for v in zs])
        z = z[np.isfinite(z)]
        out.append(float((np.quantile(z, coverage) / norm.ppf(0.5 + coverage / 2)) ** 2))
    return np.array(out)


def score_setting(preds, test, kind_of, kinds, knots_for_kind):
    """Per material: errors of the consensus (knots_for_kind(kind)), of every baseline and of the
    DS-GPLVM member; coverage; disagreement. -> list of records."""
    records = []
    for i, p in sorted(preds.items()):
        knots = knots_for_kind(kind_of[i])
        true = test.tables_2d[i]
        cons = consensus_table(p["members"], knots)
        space = p["feature_space"]
        spread = member_spread(colour.rho_to_features(np.nan_to_num(p["members"]), space=space),
                               knots)
        var = p["var_ds"] + p["calibration"] * np.where(np.isnan(p["var_ds"]), np.nan, spread)
        hits, bins = coverage_hits(cons, var, true, space)
        errs = {"consensus": band_errors(cons, true), "dsgplvm": band_errors(p["members"][0], true)}
        errs |= {b: band_errors(t, true) for b, t in p["baselines"].items()}
        best = min(BASELINES, key=lambda b: errs[b][0])
        records.append({"material": test.names[i], "kind": kinds[kind_of[i]],
                        "errors": errs, "best_baseline": best,
                        "ratio": errs["consensus"][0] / errs[best][0],
                        "disagreement": disagreement(p["members"][0], p["members"][1]),
                        # the shipped rule on a full slice: infer.warning's disagreement alone
                        "warning_shipped": bool(disagreement(p["members"][0], p["members"][1])
                                                > DISAGREEMENT_WARN_DE),
                        "novelty_beyond_training": bool((p["warning"]["score"] or 0.0) > 1.0),
                        "hits": hits, "bins": bins})
    return records


def summary(records, kinds):
    def mean(rs, m, band=0):
        return float(np.mean([r["errors"][m][band] for r in rs]))
    out = {"all": {}, "kinds": {}}
    for scope, rs in [("all", records)] + [(k, [r for r in records if r["kind"] == k])
                                           for k in kinds]:
        if not rs:
            continue
        means = {m: mean(rs, m) for m in ("consensus", "dsgplvm") + BASELINES}
        best = min(BASELINES, key=means.get)
        entry = {"n": len(rs), "means": means, "best_baseline": best,
                 "ratio": means["consensus"] / means[best],
                 "ratio_dsgplvm": means["dsgplvm"] / means[best],
                 "coverage90": sum(r["hits"] for r in rs) / sum(r["bins"] for r in rs),
                 "bands": {m: [mean(rs, m, b + 1) for b in range(len(BANDS_DEG))]
                           for m in ("consensus",) + BASELINES}}
        if scope == "all":
            out["all"] = entry
        else:
            out["kinds"][scope] = entry
    return out


def warning_rates(records, kind_of_name, kinds, nested=True, threshold=None):
    """Recall over lost materials, false-warning rate over the others, and the thresholds."""
    lost = {r["material"]: r["ratio"] > LOST_RATIO for r in records}
    warned, thresholds = {}, {}
    for kind in kinds:
        others = [r for r in records if r["kind"] != kind and not lost[r["material"]]]
        t = threshold if threshold is not None else \
            float(np.quantile([r["disagreement"] for r in others], FALSE_WARNING_QUANTILE))
        thresholds[kind] = t
        for r in records:
            if r["kind"] == kind:
                warned[r["material"]] = r["disagreement"] > t
    n_lost = sum(lost.values())
    return {"lost": [m for m, v in lost.items() if v],
            "warned": [m for m, v in warned.items() if v],
            "recall": (sum(warned[m] for m in lost if lost[m]) / n_lost) if n_lost else None,
            "false_warning_rate": sum(warned[m] for m in lost if not lost[m])
            / max(1, len(lost) - n_lost), "thresholds": thresholds}


def markdown(result):
    kinds = result["kinds"]
    lines = ["# Consensus weights and warning threshold: RGL (NBRDF proxy) "
             + result.get("partition", "kind hold-out") + ", nested", "",
             f"`{result['command']}`", "",
             "Knot weights (per θh knot " + ", ".join(f"{k:g}°" for k in THETA_H_KNOTS_DEG)
             + ": rows θd knots " + ", ".join(f"{k:g}°" for k in THETA_D_KNOTS_DEG)
             + "; columns: " + ", ".join(CONSENSUS_MEMBERS) + "), fitted on every kind's held-out "
             "predictions (the shipped infer.consensus.CONSENSUS_WEIGHTS):", ""]
    for h, block in zip(THETA_H_KNOTS_DEG, result["knots_all"]):
        lines += [f"    θh {h:g}°: " + " | ".join(" ".join(f"{v:.2f}" for v in row)
                                                 for row in block)]
    lines += ["", "Variance factors per θd band that would make each band's pooled bins 90% covered "
              "(not shipped: per kind they over-cover felt and coatings and leave car paints "
              "under 80%), fitted on every kind: "
              + ", ".join(f"{v:.2f}" for v in result["variance_factors_all"])
              + "; nested: " + "; ".join(f"{k} " + ", ".join(f"{x:.2f}" for x in v)
                                         for k, v in result["variance_factors_nested"].items())]
    for setting in ("kinds_nested", "kinds_shipped_constants", "merl_only_nested"):
        if setting not in result:       # --no-merl-only
            continue
        s = result[setting]["summary"]
        a = s["all"]
        lines += ["", f"## {setting}", "", result[setting]["what"], "",
                  "| scope | n | consensus | dsgplvm alone | pca | noll | chandraker | ashikhmin "
                  "| consensus / best | dsgplvm alone / best | 90% coverage |",
                  "|---|---|---|---|---|---|---|---|---|---|---|"]
        for scope, e in [("all", a)] + list(s["kinds"].items()):
            m = e["means"]
            lines.append(f"| {scope} | {e['n']} | " + " | ".join(
                f"{m[k]:.2f}" for k in ("consensus", "dsgplvm") + BASELINES)
                + f" | {e['ratio']:.3f}× {e['best_baseline']} | {e['ratio_dsgplvm']:.3f}× | "
                  f"{100 * e['coverage90']:.1f}% |")
        lines += ["", "θd bands (LAB-log mean, " + " / ".join(f"{lo}–{hi}°" for lo, hi in BANDS_DEG)
                  + "): " + "; ".join(f"{m} " + " / ".join(f"{v:.2f}" for v in vals)
                                      for m, vals in a["bands"].items())]
        w = result[setting].get("warning")
        if w:
            lines += ["", f"Warning (nested threshold): lost (consensus > {LOST_RATIO}× best baseline) "
                      f"{len(w['lost'])}: {', '.join(w['lost']) or 'none'}; warned "
                      f"{len(w['warned'])}: {', '.join(w['warned']) or 'none'}; recall "
                      + ("—" if w["recall"] is None else f"{100 * w['recall']:.0f}%")
                      + f", false-warning rate {100 * w['false_warning_rate']:.1f}%; thresholds "
                      + ", ".join(f"{k} {v:.1f}" for k, v in w["thresholds"].items()) + "."]
        w = result[setting].get("warning_shipped")
        if w:
            lines += ["Warning as shipped (infer.warning.prediction_warning, every reason): recall "
                      + ("—" if w["recall"] is None else f"{100 * w['recall']:.0f}%")
                      + f", false-warning rate {100 * w['false_warning_rate']:.1f}%; warned: "
                      + (", ".join(w["warned"]) or "none") + "."]
        w = result[setting].get("warning_novelty_only")
        if w:
            lines += ["Ablation, the GP's novelty > 1 as the only rule (the warning before issue 36): "
                      "recall " + ("—" if w["recall"] is None else f"{100 * w['recall']:.0f}%")
                      + f", false-warning rate {100 * w['false_warning_rate']:.1f}%; warned: "
                      + (", ".join(w["warned"]) or "none") + "."]
        lines += ["", "| material | kind | consensus | best baseline | ratio | disagreement |",
                  "|---|---|---|---|---|---|"]
        for r in result[setting]["records"]:
            lines.append(f"| {r['material']} | {r['kind']} | {r['errors']['consensus'][0]:.2f} | "
                         f"{r['best_baseline']} {r['errors'][r['best_baseline']][0]:.2f} | "
                         f"{r['ratio']:.2f} | {r['disagreement']:.1f} |")
    lines += ["", f"Kinds: {', '.join(kinds)}.", ""]
    return "\n".join(lines)


def shipped_rates(records, key="warning_shipped"):
    lost = {r["material"]: r["ratio"] > LOST_RATIO for r in records}
    warned = {r["material"]: r[key] for r in records}
    n_lost = sum(lost.values())
    return {"warned": [m for m, v in warned.items() if v],
            "recall": sum(warned[m] for m in lost if lost[m]) / n_lost if n_lost else None,
            "false_warning_rate": sum(warned[m] for m in lost if not lost[m])
            / max(1, len(lost) - n_lost)}


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--merl-dir", required=True)
    p.add_argument("--test-dir", required=True)
    p.add_argument("--fold-groups", default=str(Path(__file__).parent / "rgl_kinds.json"))
    p.add_argument("--random-folds", type=int, default=0,
                   help="score this many seeded random folds (--seed) instead of the kinds")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--work", default="/tmp/consensus_weights")
    p.add_argument("--no-merl-only", action="store_true")
    p.add_argument("--out", default=str(Path(__file__).resolve().parent / "results"))
    args = p.parse_args(argv)
    Path(args.work).mkdir(parents=True, exist_ok=True)
    merl_set, test = TrainingSet.from_merl_dir(args.merl_dir), TrainingSet.from_merl_dir(args.test_dir)
    if args.random_folds:
        folds = np.array_split(np.random.default_rng(args.seed).permutation(len(test)),
                               args.random_folds)
        kinds = [f"fold {k}" for k in range(len(folds))]
    else:
        groups = json.loads(Path(args.fold_groups).read_text())
        kinds, folds = list(groups), kind_folds(test.names, groups)
    kind_of = {int(i): k for k, f in enumerate(folds) for i in f}
    methods = ("dsgplvm",) + BASELINES
    preds = {}
    for k in range(len(folds)):
        def compute(k=k):
            both, fold = fold_training(merl_set, test, k, folds=folds)
            return predict_fold(fit_all(both, args.seed, methods)[0], test, fold)
        preds |= cached(args.work, f"kind{k}", compute)
        print("kind", k, "done", flush=True)
    samples = {i: sample_of(p["members"], test.tables_2d[i]) for i, p in preds.items()}
    knots_all = fit_knots(list(samples.values()))
    nested = {k: fit_knots([s for i, s in samples.items() if kind_of[i] != k])
              for k in range(len(folds))}
    zs = {i: raw_z(p, test.tables_2d[i], nested[kind_of[i]]) for i, p in preds.items()}
    factors_all = fit_variance_factors([raw_z(p, test.tables_2d[i], knots_all)
                                        for i, p in preds.items()])
    factors_nested = {k: fit_variance_factors([z for i, z in zs.items() if kind_of[i] != k])
                      for k in range(len(folds))}
    result = {"command": "nice -n 10 python -m benchmarks.consensus_weights "
              + " ".join(sys.argv[1:] if argv is None else argv), "kinds": kinds,
              "partition": (f"random folds (seed {args.seed})" if args.random_folds
                            else "kind hold-out"),
              "knots_all": knots_all.tolist(),
              "knots_nested": {kinds[k]: v.tolist() for k, v in nested.items()},
              "variance_factors_all": factors_all.tolist(),
              "variance_factors_nested": {kinds[k]: v.tolist() for k, v in factors_nested.items()}}
    for setting, knots_for, what in (
            ("kinds_nested", lambda k: nested[k],
             "Each kind predicted by methods trained on MERL plus the other kinds; its consensus "
             "weights fitted on the other kinds' held-out predictions only."),
            ("kinds_shipped_constants", lambda k: CONSENSUS_WEIGHTS,
             "The same predictions with the shipped CONSENSUS_WEIGHTS (fitted on all kinds: not "
             "nested, for reference only).")):
        records = score_setting(preds, test, kind_of, kinds, knots_for)
        result[setting] = {"what": what, "records": records, "summary": summary(records, kinds),
                           "warning": warning_rates(records, kind_of, kinds),
                           "warning_shipped": shipped_rates(records),
                           "warning_novelty_only": shipped_rates(records,
                                                                 "novelty_beyond_training")}
    if not args.no_merl_only:
        def compute_merl():
            return predict_fold(fit_all(merl_set, args.seed, methods)[0], test,
                                range(len(test)))
        merl_preds = cached(args.work, "merl_only", compute_merl)
        records = score_setting(merl_preds, test, kind_of, kinds, lambda k: nested[k])
        result["merl_only_nested"] = {
            "what": "Trained on the MERL tables alone (the paper's setting), every RGL table "
                    "predicted; each kind's consensus weights are the nested ones above (chosen "
                    "without that kind).", "records": records,
            "summary": summary(records, kinds), "warning_shipped": shipped_rates(records),
            "warning_novelty_only": shipped_rates(records, "novelty_beyond_training")}
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "consensus_weights.json").write_text(json.dumps(result, indent=1, default=float) + "\n")
    (out / "consensus_weights.md").write_text(markdown(result))
    print(markdown(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
