"""The observed-row blend (infer/row_blend.py) on RGL (NBRDF proxy): the default DS-GPLVM's 2D
errors with the blend off and on, from the same fits, in the two settings of
benchmarks/generalisation.py (same seed, same 5 folds).

    PYTHONPATH=$PWD nice -n 10 python benchmarks/row_blend.py --merl-dir MERL --test-dir RGL \\
        --folds-run 0,1,2 --part OUT/part_a.json            # one process per part on a busy machine
    PYTHONPATH=$PWD python benchmarks/row_blend.py --summarise OUT/part_*.json \\
        [--baselines benchmarks/results/generalisation.json] [--out benchmarks/results]

A part refits the default DS-GPLVM (log-RGB features, anchored: what `train` chose for the
MERL-only setting and for the shipped model) on MERL plus the other folds for each fold it is given,
or on MERL alone for fold "merl-only", and scores every held-out table twice: row_blend_deg 0 (the
previous default) and infer.row_blend.ROW_BLEND_DEG. The blend acts at prediction time only, so the
two columns differ by the blend alone. --summarise writes OUT/generalisation_blend.{json,md},
with the baselines' rows taken from the generalisation benchmark's JSON (their code is unchanged).
"""

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))
from generalisation import BANDS_DEG, BASELINES, band_errors, fold_training  # noqa: E402
from flashbrdf.infer import TrainingSet, make_method  # noqa: E402
from flashbrdf.infer.row_blend import ROW_BLEND_DEG  # noqa: E402


def run_part(args):
    merl_set = TrainingSet.from_merl_dir(args.merl_dir)
    test = TrainingSet.from_merl_dir(args.test_dir)
    records = []
    for k in args.folds_run.split(","):
        training, held_out = fold_training(merl_set, test, k)
        start = time.process_time()
        method = make_method("dsgplvm", feature_space="rgb", anchor=True).fit(training)
        fit_cpu = time.process_time() - start
        for i in held_out:
            rec = {"setting": "merl-only" if k == "merl-only" else "merl+test-folds",
                   "fold": k, "material": test.names[i], "fit_cpu_s": fit_cpu}
            for deg in (0.0, ROW_BLEND_DEG):
                method.row_blend_deg = deg
                start = time.process_time()
                pred, _ = method.predict(test.slices[i], "2d")
                rec[f"predict_cpu_ms_{deg:g}"] = 1e3 * (time.process_time() - start)
                rec[f"errors_{deg:g}"] = band_errors(pred, test.tables_2d[i])
            records.append(rec)
            print(json.dumps(rec), flush=True)
    Path(args.part).write_text(json.dumps({"command": " ".join(sys.argv), "records": records}))


def summarise(args):
    records = [r for p in args.summarise for r in json.loads(Path(p).read_text())["records"]]
    base = json.loads(Path(args.baselines).read_text())["settings"]
    out = {"commands": [json.loads(Path(p).read_text())["command"] for p in args.summarise],
           "row_blend_deg": ROW_BLEND_DEG, "settings": {}}
    lines = ["# The observed-row blend on RGL (NBRDF proxy): the default DS-GPLVM with it off and on",
             "", "Commands: " + "; ".join(f"`{c}`" for c in out["commands"]), "",
             "| setting | materials | dsgplvm, no blend (mean / median) | with the blend | its θd bands "
             + "(" + " / ".join(f"{a}–{b}°" for a, b in BANDS_DEG) + ") | best baseline | "
             "best baseline per band | ratio mean / median |",
             "|---|---|---|---|---|---|---|---|"]
    for setting in ("merl-only", "merl+test-folds"):
        rs = [r for r in records if r["setting"] == setting]
        if not rs:
            continue
        off = np.array([r["errors_0"] for r in rs])
        on = np.array([r[f"errors_{ROW_BLEND_DEG:g}"] for r in rs])
        # the baselines on the same materials (all of them, or the folds a part got through)
        mats = {r["material"] for r in rs}
        s = {m: {"lab_log": np.array([b["lab_log"] for b in base[setting]["records"]
                                      if b["method"] == m and b["material"] in mats]),
                 "bands": np.array([b["bands"] for b in base[setting]["records"]
                                    if b["method"] == m and b["material"] in mats])}
             for m in BASELINES}
        for m in BASELINES:
            s[m].update(lab_log_mean=s[m]["lab_log"].mean(),
                        lab_log_median=float(np.median(s[m]["lab_log"])),
                        bands_mean=s[m]["bands"].mean(0))
        best = min(BASELINES, key=lambda m: s[m]["lab_log_mean"])
        best_bands = np.min([s[m]["bands_mean"] for m in BASELINES], axis=0)
        row = {"materials": len(rs), "off": [off[:, 0].mean(), np.median(off[:, 0])],
               "on": [on[:, 0].mean(), np.median(on[:, 0])], "on_bands": on[:, 1:].mean(0).tolist(),
               "off_bands": off[:, 1:].mean(0).tolist(), "best": best,
               "best_mean_median": [s[best]["lab_log_mean"], s[best]["lab_log_median"]],
               "best_bands": best_bands.tolist(),
               "predict_cpu_ms": float(np.median([r[f"predict_cpu_ms_{ROW_BLEND_DEG:g}"]
                                                  for r in rs])),
               "fit_cpu_s": float(np.mean([r["fit_cpu_s"] for r in rs]))}
        row["ratio"] = [row["on"][0] / row["best_mean_median"][0],
                        row["on"][1] / row["best_mean_median"][1]]
        out["settings"][setting] = row
        lines.append(f"| {setting} | {len(rs)} | {row['off'][0]:.2f} / {row['off'][1]:.2f} | "
                     f"{row['on'][0]:.2f} / {row['on'][1]:.2f} | "
                     + " / ".join(f"{v:.2f}" for v in row["on_bands"])
                     + f" | {best} {row['best_mean_median'][0]:.2f} / "
                     f"{row['best_mean_median'][1]:.2f} | "
                     + " / ".join(f"{v:.2f}" for v in best_bands)
                     + f" | {row['ratio'][0]:.2f}× / {row['ratio'][1]:.2f}× |")
    lines += ["", "Target (issue 11): ratio ≤ 0.90× on mean and median, no band > 1.10× the best "
              "baseline's. Baselines from the generalisation benchmark's run (their code is "
              "unchanged by the blend).", ""]
    dest = Path(args.out)
    (dest / "generalisation_blend.json").write_text(json.dumps(out, indent=1, default=float) + "\n")
    (dest / "generalisation_blend.md").write_text("\n".join(lines))
    print("\n".join(lines))


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--merl-dir")
    p.add_argument("--test-dir")
    p.add_argument("--folds-run", default="merl-only,0,1,2,3,4")
    p.add_argument("--part")
    p.add_argument("--summarise", nargs="+")
    p.add_argument("--baselines", default=str(Path(__file__).resolve().parent / "results"
                                              / "generalisation.json"))
    p.add_argument("--out", default=str(Path(__file__).resolve().parent / "results"))
    args = p.parse_args(argv)
    if args.summarise:
        summarise(args)
    else:
        run_part(args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
