"""The slice-fit share λ of the default DS-GPLVM's weights, and the row blend's extension (flat or by
the microfacet geometry term), measured where they were chosen and where they were checked.

    PYTHONPATH=$PWD nice -n 10 python benchmarks/slice_fit.py --merl-dir MERL --test-dir RGL
        [--ball-model sample_data/models/merl100_1d2d.npz --ball-merl-dir MERL_AND_RGL]
        [--out benchmarks/results]

MERL and RGL are the MERL (NBRDF proxy) and RGL (NBRDF proxy) tables (../shared/tools/merl_proxy.py).
- MERL: 3 seeded 80/20 splits (rng seeds 100, 101, 102) of the --merl-dir tables; the anchored
  log-RGB DS-GPLVM fitted on the 80%, 2D LAB-log (and Table 1's other LAB metrics) of the 20%.
  λ was chosen here.
- RGL folds: the 5 folds of benchmarks/generalisation.py (seed 0): each fold predicted by the
  DS-GPLVM fitted on MERL plus the other folds. Looked at after the choice.
- DiLiGenT ball (optional): the model's 3D prediction for the ball's extracted slice (from
  benchmarks/diligent_ball.py's import and extract), rendered for the 95 other lights with the
  benchmark's direct renderer, ΔE-log mean.
Each λ is a prediction-time switch of one fitted model, so the settings share their fits. The
"flat" extension is the blend as it was before (the observed row copied along θd and φd).
Writes OUT/slice_fit.{json,md}.
"""

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))
from flashbrdf.brdf import metrics  # noqa: E402
from flashbrdf.brdf.bins import scatter_valid, valid_bins_3d  # noqa: E402
from generalisation import fold_training  # noqa: E402
from flashbrdf.infer import TrainingSet, load_method, make_method  # noqa: E402
from flashbrdf.infer.estimator import stream_combination  # noqa: E402
from flashbrdf.infer.row_blend import blend_log, blend_toward_row, blend_weights  # noqa: E402

LAMBDAS = (0.0, 0.25, 0.5, 0.75, 1.0)
EXTENSIONS = ("flat", "microfacet")
METRICS = ("lab_lin", "lab_root", "lab_log")


def blended(table, flash_slice, extension):
    """The anchored, un-blended 2D `table` blended toward the observed row, extended either way."""
    if extension == "microfacet":
        return blend_toward_row(table, flash_slice)
    row, w = blend_weights(flash_slice)
    return blend_log(table, row[:, None, :], w)


def score_predictions(method, cases):
    """{(λ, extension): [brdf_errors]} for a fitted DS-GPLVM over cases [(slice, true 2D table)]."""
    out = {}
    for lam in LAMBDAS:
        method.set_params(slice_fit=lam, row_blend_deg=0.0)     # anchored, blended below
        for rho, truth in cases:
            pred = method.predict(rho, "2d")[0]
            for ext in EXTENSIONS:
                out.setdefault((lam, ext), []).append(metrics.brdf_errors(blended(pred, rho, ext),
                                                                          truth))
    method.set_params(slice_fit=0.5, row_blend_deg=20.0)
    return out


def summarise(scores):
    return {f"{lam}|{ext}": {"lab_log_mean": float(np.mean([e["lab_log"] for e in errs])),
                             "lab_log_median": float(np.median([e["lab_log"] for e in errs])),
                             **{m: float(np.mean([e[m] for e in errs])) for m in METRICS},
                             "n": len(errs)}
            for (lam, ext), errs in scores.items()}


def merge(into, scores):
    for key, errs in scores.items():
        into.setdefault(key, []).extend(errs)


def merl_splits(merl):
    scores = {}
    for seed in (100, 101, 102):
        order = np.random.default_rng(seed).permutation(len(merl))
        cut = len(merl) // 5
        test, train = np.sort(order[:cut]), np.sort(order[cut:])
        method = make_method("dsgplvm", feature_space="rgb", anchor=True).fit(merl.subset(train))
        merge(scores, score_predictions(method, [(merl.slices[i], merl.tables_2d[i]) for i in test]))
        print("merl split", seed, flush=True)
    return summarise(scores)


def rgl_folds(merl, test, folds=5, seed=0):
    scores = {}
    for k in range(folds):
        both, fold = fold_training(merl, test, k, folds, seed)
        method = make_method("dsgplvm", feature_space="rgb", anchor=True).fit(both)
        merge(scores, score_predictions(method, [(test.slices[i], test.tables_2d[i])
                                                 for i in fold]))
        print("rgl fold", k, flush=True)
    return summarise(scores)


def ball(model, merl_dir):
    """{"λ|extension": ΔE-log mean over the ball's 95 other lights} from 3D predictions."""
    from benchmarks._real_common import SHARED, direct_render, run_cli
    from benchmarks.diligent_ball import _load_scene
    from flashbrdf.brdf.views import read_slice_csv
    from flashbrdf.pipeline.report import image_errors, read_image
    out = {}
    with tempfile.TemporaryDirectory() as work:
        work = Path(work)
        scene_dir = work / "scene"
        data = SHARED / "data" / "real" / "diligent-ball"
        for argv in (["import-diligent", data, "--flash", 52, "--out", scene_dir],
                     ["extract", scene_dir, "--out", work / "slice.csv"]):
            rc, err, _ = run_cli(argv)
            if rc:
                print(f"ball: {argv[0]} failed: {err}", flush=True)
                return {}
        scene, mask, normals, view = _load_scene(scene_dir)
        rho, _ = read_slice_csv(work / "slice.csv")
        refs = [p for p in scene["photos"] if p["role"] == "reference"]
        photos = {p["file"]: read_image(scene_dir / p["file"]) for p in refs}
        method = load_method(model, "dsgplvm", merl_dir, anchor=True)
        ih, jd, _ = valid_bins_3d()
        for lam in (0.0, 0.5):
            method.set_params(slice_fit=lam, row_blend_deg=0.0)
            weights, space = method.combination(rho)    # anchored; the blend (w = 0) is off
            base = stream_combination(method.training_, weights, space)
            for ext in EXTENSIONS:
                row, w = blend_weights(rho)
                if ext == "microfacet":
                    table = blend_toward_row(scatter_valid(base), rho)
                else:
                    table = scatter_valid(blend_log(base, row[ih], w[ih, jd]))
                errs = []
                for p in refs:
                    image = np.zeros(mask.shape + (3,))
                    image[mask] = direct_render(
                        table, np.broadcast_to(p["light"]["direction"], normals.shape),
                        np.broadcast_to(view, normals.shape), normals,
                        np.asarray(p["light"]["irradiance_rgb"], float))
                    errs.append(image_errors(image, photos[p["file"]], mask)[1])
                out[f"{lam}|{ext}"] = float(np.nanmean(errs))
                print("ball", lam, ext, out[f"{lam}|{ext}"], flush=True)
    return out


def markdown(result):
    lines = ["# Slice-fit weights and the row blend's extension", "",
             f"Command: `{result['command']}` ({result['seconds']:.0f} s).", "",
             "2D LAB-log mean / median (and Table 1's lab_lin, lab_root means); λ is the share of "
             "the weights from the slice fit, the extension is how the blend carries the observed "
             "row along θd.", ""]
    for name, block in (("MERL (NBRDF proxy), 3 × 20 held out", result["merl"]),
                        ("RGL (NBRDF proxy), 5 folds, 22 held out", result["rgl"])):
        lines += [f"## {name}", "", "| λ | extension | LAB-log mean / median | lab_lin | lab_root |",
                  "|---|---|---|---|---|"]
        for key, r in block.items():
            lam, ext = key.split("|")
            lines.append(f"| {lam} | {ext} | {r['lab_log_mean']:.3f} / {r['lab_log_median']:.3f} "
                         f"| {r['lab_lin']:.3f} | {r['lab_root']:.3f} |")
        lines.append("")
    if result.get("ball"):
        lines += ["## DiLiGenT ball (3D, 95 lights, ΔE-log mean)", "",
                  "| λ | extension | ΔE-log |", "|---|---|---|"]
        for key, v in result["ball"].items():
            lam, ext = key.split("|")
            lines.append(f"| {lam} | {ext} | {v:.4f} |")
        lines.append("")
    return "\n".join(lines)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--merl-dir", required=True)
    p.add_argument("--test-dir", required=True)
    p.add_argument("--ball-model")
    p.add_argument("--ball-merl-dir")
    p.add_argument("--out", default=str(Path(__file__).resolve().parent / "results"))
    args = p.parse_args(argv)
    start = time.perf_counter()
    merl = TrainingSet.from_merl_dir(args.merl_dir)
    test = TrainingSet.from_merl_dir(args.test_dir)
    result = {"command": "PYTHONPATH=$PWD nice -n 10 python benchmarks/slice_fit.py "
                         + " ".join(sys.argv[1:] if argv is None else argv),
              "merl": merl_splits(merl), "rgl": rgl_folds(merl, test)}
    if args.ball_model:
        result["ball"] = ball(args.ball_model, args.ball_merl_dir)
    result["seconds"] = time.perf_counter() - start
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "slice_fit.json").write_text(json.dumps(result, indent=1) + "\n")
    (out / "slice_fit.md").write_text(markdown(result))
    print(markdown(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
