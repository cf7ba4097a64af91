"""Narrow-θh slices: what inference predicts outside the θh window a slice observes.

    nice -n 10 python benchmarks/sparse_slices.py [--folds 5] [--windows 0-19,10-25,20-40]

A planar card under a phone flash is seen over θh 0–19° only, so each of its materials' slices
holds ~40 of the 90 θh bins and nothing past 19°. This cuts the θd = 0 slice of held-out tables
(MERL (NBRDF proxy) and RGL (NBRDF proxy), the default model's 121 training tables in 5 folds:
the DS-GPLVM is refitted on the other 4 with the default model's hyperparameters) to a θh window
and scores the anchored DS-GPLVM's 2D prediction against the held-out table:
- inside the window and outside it (θh bins past the window's end), on the θd = 0 row and on the
  whole 2D table: mean |ln((ρ_pred + e)/(ρ_true + e))|, e = brdf.colour.FEATURE_OFFSET, per bin
  and channel (a log error: 0.69 is a factor 2);
- "wild": the share of held-out tables whose θd = 0 row, outside the window, is off by more than a
  factor 3 (|ln| > ln 3) on more than a quarter of those bins;
against the full slice's prediction of the same tables (what the window costs) and against the
variants of how the anchoring correction ln c (infer.anchoring) continues past the last observed
bin. Writes benchmarks/results/sparse_slices.{json,md}.
"""

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from benchmarks._real_common import RESULTS  # noqa: E402
from flashbrdf.brdf.colour import FEATURE_OFFSET  # noqa: E402
from flashbrdf.brdf.merl import theta_h_centres  # noqa: E402

WILD = np.log(3.0)


def log_error(pred, true):
    """(..., ) mean over channels of |ln((pred + e)/(true + e))|, NaN where either is NaN."""
    e = FEATURE_OFFSET
    with np.errstate(invalid="ignore"):
        d = np.abs(np.log(np.maximum(pred, 0) + e) - np.log(np.maximum(true, 0) + e))
    return d.mean(axis=-1)


def window_slice(rho, lo_deg, hi_deg):
    """The slice (90, 3) with every bin outside [lo, hi] degrees of θh set to NaN (missing)."""
    theta = np.degrees(theta_h_centres())
    out = np.array(rho, dtype=float, copy=True)
    out[(theta < lo_deg) | (theta > hi_deg)] = np.nan
    return out


def score(pred, true, lo_deg, hi_deg):
    """Errors of a 2D prediction (90, 90, 3) against the truth, inside and past the window."""
    theta = np.degrees(theta_h_centres())
    inside, past = (theta >= lo_deg) & (theta <= hi_deg), theta > hi_deg
    row, table = log_error(pred[:, 0], true[:, 0]), log_error(pred, true)
    return {"row_in": float(np.nanmean(row[inside])), "row_past": float(np.nanmean(row[past])),
            "table_in": float(np.nanmean(table[inside])),
            "table_past": float(np.nanmean(table[past])),
            "wild": bool(np.nanmean(row[past] > WILD) > 0.25)}


def main(argv=None):
    from flashbrdf.infer import anchoring, make_method
    from flashbrdf.infer.model_file import read_model
    from flashbrdf.pipeline.options import DEFAULT_MODEL
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--folds", type=int, default=5)
    ap.add_argument("--windows", default="0-19,10-25,20-40")
    ap.add_argument("--fade", default="inf,8,3,0",
                    help="infer.anchoring.ANCHOR_FADE_BINS values to compare (inf: hold ln c)")
    args = ap.parse_args(argv)
    windows = [tuple(float(x) for x in w.split("-")) for w in args.windows.split(",")]
    fades = [float(x) for x in args.fade.split(",")]
    default = anchoring.ANCHOR_FADE_BINS
    training, params, _ = read_model(DEFAULT_MODEL)
    params = {**params["dsgplvm"], "anchor": True}
    folds = np.array_split(np.random.default_rng(0).permutation(len(training)), args.folds)
    rows = []
    start = time.perf_counter()
    for f, test in enumerate(folds):
        train = np.setdiff1d(np.arange(len(training)), test)
        method = make_method("dsgplvm", **params).fit(training.subset(train))
        for i in test:
            true = training.tables_2d[i]
            full = method.predict(training.slices[i], view="2d")[0]
            for lo, hi in windows:
                cut = window_slice(training.slices[i], lo, hi)
                if np.isfinite(cut).all(axis=1).sum() < 3:
                    continue
                row = {"material": training.names[i], "fold": f, "window": [lo, hi],
                       "full_slice": score(full, true, lo, hi)}
                for fade in fades:
                    anchoring.ANCHOR_FADE_BINS = fade
                    row[f"fade {fade:g}"] = score(method.predict(cut, view="2d")[0], true, lo, hi)
                anchoring.ANCHOR_FADE_BINS = default
                rows.append(row)
        print(f"fold {f}: {len(rows)} rows, {time.perf_counter() - start:.0f} s", flush=True)
    command = "nice -n 10 python benchmarks/sparse_slices.py " + " ".join(argv or sys.argv[1:])
    summary = summarise(rows, windows, ["full_slice"] + [f"fade {x:g}" for x in fades])
    (RESULTS / "sparse_slices.json").write_text(json.dumps(
        {"command": command, "summary": summary, "rows": rows}, indent=1) + "\n")
    (RESULTS / "sparse_slices.md").write_text(markdown(command, summary))
    print(markdown(command, summary))
    return 0


def summarise(rows, windows, variants):
    out = []
    for lo, hi in windows:
        mine = [r for r in rows if r["window"] == [lo, hi]]
        for which in variants:
            entry = {"window": [lo, hi], "slice": which, "tables": len(mine)}
            for key in ("row_in", "row_past", "table_in", "table_past"):
                values = np.array([r[which][key] for r in mine])
                entry[key] = {"mean": float(np.nanmean(values)),
                              "p90": float(np.nanpercentile(values, 90))}
            entry["wild"] = float(np.mean([r[which]["wild"] for r in mine]))
            out.append(entry)
    return out


def markdown(command, summary):
    lines = ["# Narrow-θh slices: the prediction outside the observed window", "",
             f"Command: `{command}`. Held-out tables of the default model's training set "
             "(MERL (NBRDF proxy) + RGL (NBRDF proxy)), DS-GPLVM refitted per fold. Errors: mean "
             "|ln((ρ_pred + e)/(ρ_true + e))| over bins and channels (0.69 = a factor 2); mean and "
             "90th percentile over tables. 'wild': share of tables whose θd = 0 row is off by > 3× "
             "on > 25% of the bins past the window.", "",
             "| θh window | slice given | tables | θd=0 row, in | θd=0 row, past | 2D table, in "
             "| 2D table, past | wild |", "|---|---|---|---|---|---|---|---|"]
    for e in summary:
        cells = " | ".join(f"{e[k]['mean']:.3f} (p90 {e[k]['p90']:.3f})"
                           for k in ("row_in", "row_past", "table_in", "table_past"))
        lines.append(f"| {e['window'][0]:.0f}–{e['window'][1]:.0f}° | {e['slice']} | "
                     f"{e['tables']} | {cells} | {100 * e['wild']:.0f}% |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    sys.exit(main())
