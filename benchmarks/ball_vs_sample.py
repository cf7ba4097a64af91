"""The observed-row blend's width: the DiLiGenT ball and the sample capture pull it opposite ways.

    PYTHONPATH=$PWD python benchmarks/diligent_ball.py --model MODEL --merl-dir DIR --work BALL
    PYTHONPATH=$PWD nice -n 10 python benchmarks/ball_vs_sample.py --ball-work BALL --merl-dir DIR
        [--model sample_data/models/merl100_1d2d.npz] [--work WORK]

The default dsgplvm (anchored) predicts the ball's and the sample capture's 3D tables with the row
blend (infer.row_blend) at τ = 10°, 20° (the default) and 30°, and with a precision-weighted blend,
a diagnostic that is not in the package: w = v_model / (v_model + v_row) per (θh, θd) bin, where
v_model is the method's own calibrated per-bin variance (channel mean) and v_row the mean squared
error, over the model's training tables, of extending each one's θd = 0 row along θd by the
microfacet ratio (what the blend's target does). The ball is scored as benchmarks/ball_regions.py
scores it (the benchmark's direct pixel model, 95 lights, ΔE-log mean); the sample capture as `run`
scores it (its material-1 slice from `segment` + `extract --labels`, `render` at 64 spp, ΔE-log
mean over the two references), but from the 3D prediction: `run` without --merl-dir (the README's
first command) renders the 2D prediction copied across φd, so its figure differs. Writes benchmarks/results/ball_vs_sample.{json,md}.
"""

import argparse
import json
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from benchmarks._real_common import REPO, RESULTS, run_cli, write_json  # noqa: E402
from benchmarks.ball_regions import per_light_errors  # noqa: E402

TAUS = (10.0, 20.0, 30.0)
THETA_D_BINS = (5, 10, 15, 20, 30, 45, 60)     # where the weights are reported (1° bins)


def row_extension_variance(training):
    """(90, 90) mean over training tables and channels of (ln(ρ + e) − ln(ρ_row g + e))²: how far
    each training table is from its own θd = 0 row extended by the microfacet ratio g."""
    from flashbrdf.brdf.colour import FEATURE_OFFSET
    from flashbrdf.brdf.shadowing import geometry_ratio_2d
    e = FEATURE_OFFSET
    ratio = np.nan_to_num(geometry_ratio_2d(), nan=1.0)[None, ..., None]
    tables = np.asarray(training.tables_2d, float)
    extended = np.asarray(training.slices, float)[:, :, None, :] * ratio
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)   # bins below the horizon
        return np.nanmean((np.log(np.maximum(tables, 0) + e)
                           - np.log(np.maximum(extended, 0) + e)) ** 2, axis=(0, 3))


def precision_weighted_table(unblended_3d, method, rho, v_row):
    """The anchored, unblended 3D table blended toward the observed row with w = v_m / (v_m + v_row)
    on the observed θh bins (1 at θd = 0), as infer.row_blend does with its Gaussian w(θd)."""
    from flashbrdf.brdf import merl
    from flashbrdf.brdf.bins import valid_bins_3d
    from flashbrdf.brdf.shadowing import geometry_ratio_valid
    from flashbrdf.infer.row_blend import blend_log, blend_weights
    variance = np.nanmean(method.predict(rho, "2d")[1], axis=-1)
    row, gaussian = blend_weights(rho)
    w = np.where(gaussian > 0, np.nan_to_num(variance / (variance + v_row + 1e-300)), 0.0)
    w[:, 0] = gaussian[:, 0] > 0
    ratio = np.ones(merl.MERL_SHAPE)
    ratio[valid_bins_3d()] = geometry_ratio_valid()
    return blend_log(unblended_3d, row[:, None, None, :] * ratio[..., None], w[:, :, None]), w


def sample_error(table, work, name):
    """ΔE-log mean over the sample capture's references, rendered by `render`."""
    from flashbrdf.brdf.merl import write_merl
    path, out = work / f"sample_{name}.binary", work / f"sample_render_{name}"
    write_merl(path, table)
    rc, err, _ = run_cli(["render", REPO / "sample_data" / "capture", "--brdf", path, "--out", out,
                           "--force"])
    if rc != 0:
        raise SystemExit(f"render failed (exit {rc}): {err}")
    values = [json.loads(p.read_text())["delta_e_log_mean"] for p in sorted(out.glob("*_compare.json"))]
    return float(np.mean(values))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ball-work", type=Path, required=True)
    ap.add_argument("--merl-dir", action="append", required=True)
    ap.add_argument("--model", default=str(REPO / "sample_data" / "models" / "merl100_1d2d.npz"))
    ap.add_argument("--work", type=Path, default=None)
    args = ap.parse_args(argv)
    from flashbrdf.brdf.views import read_slice_csv
    from flashbrdf.infer.model_file import load_method
    from flashbrdf.infer.row_blend import row_weights
    work = args.work or Path(tempfile.mkdtemp(prefix="ball_vs_sample_"))
    work.mkdir(parents=True, exist_ok=True)
    capture = REPO / "sample_data" / "capture"
    for argv_ in (["segment", capture, "--out", work / "labels.png"],
                  ["extract", capture, "--labels", work / "labels.png", "--out", work / "slices"]):
        if Path(argv_[-1]).exists():   # a rerun in the same work folder
            continue
        rc, err, _ = run_cli(argv_)
        if rc != 0:
            raise SystemExit(f"{argv_[0]} failed (exit {rc}): {err}")
    slices = {"ball": read_slice_csv(args.ball_work / "slice.csv")[0],
              "sample": read_slice_csv(work / "slices" / "material_1.csv")[0]}
    result = {"command": "python benchmarks/ball_vs_sample.py " + " ".join(argv or sys.argv[1:]),
              "model": args.model, "variants": {}}

    def score(name, tables):
        ball = float(per_light_errors(tables["ball"], args.ball_work / "scene")[0].mean())
        result["variants"][name] = {"ball": ball, "sample": sample_error(tables["sample"], work, name)}
        print(name, result["variants"][name], flush=True)

    for tau in TAUS:
        method = load_method(args.model, "dsgplvm", args.merl_dir, anchor=True, row_blend_deg=tau)
        score(f"tau {tau:.0f}", {k: method.predict(rho, "3d")[0] for k, rho in slices.items()})
    method = load_method(args.model, "dsgplvm", args.merl_dir, anchor=True, row_blend_deg=0.0)
    v_row = row_extension_variance(method.training_)
    tables, weights = {}, {}
    for k, rho in slices.items():
        tables[k], weights[k] = precision_weighted_table(method.predict(rho, "3d")[0], method, rho,
                                                         v_row)
    score("precision-weighted", tables)
    seen = {k: np.isfinite(rho).all(axis=1) for k, rho in slices.items()}
    result["precision_weights_median"] = {
        k: {f"theta_d bin {j}": float(np.median(w[seen[k], j])) for j in THETA_D_BINS}
        for k, w in weights.items()}
    write_json(RESULTS / "ball_vs_sample.json", result)
    lines = ["# The row blend's width: the DiLiGenT ball against the sample capture", "",
             f"Command: `{result['command']}`. Model: `{Path(args.model).name}` (the shipped model; "
             "neither material is in it). ΔE-log mean: the ball over its 95 reference lights "
             "(the benchmark's direct pixel model), the sample over its 2 references (`render` of the 3D "
             "prediction; `run` without --merl-dir renders the 2D one).", "",
             "| blend | ball | sample capture |", "|---|---|---|"]
    lines += [f"| {name} | {v['ball']:.4f} | {v['sample']:.4f} |"
              for name, v in result["variants"].items()]
    gaussian = row_weights()[list(THETA_D_BINS)]
    lines += ["", "Median precision weight over the observed θh bins (the Gaussian of τ = 20° gives "
              + ", ".join(f"{v:.2f}" for v in gaussian) + " at the same θd bins):", "",
              "| | " + " | ".join(result["precision_weights_median"]["ball"]) + " |",
              "|---|" + "---|" * 7]
    lines += [f"| {k} | " + " | ".join(f"{v:.2f}" for v in w.values()) + " |"
              for k, w in result["precision_weights_median"].items()]
    (RESULTS / "ball_vs_sample.md").write_text("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
