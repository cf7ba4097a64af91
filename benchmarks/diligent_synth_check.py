"""Run the contract on synthetic DiLiGenT objects (benchmarks/diligent_synth.py) and tabulate.

    python -m benchmarks.diligent_synth_check --synth DIR --work WORK
        [--cases a,b] [--flash 52] [--extra segment,extract,render]

Per case: `flashbrdf import-diligent CASE --flash 52 --out WORK/CASE/scene`, then
`flashbrdf run WORK/CASE/scene --out WORK/CASE/out`, each under /usr/bin/time -v (exit, wall
seconds, max RSS). It records the number of materials, the mean delta_e_log_mean over the
references, warnings, any traceback, files written in the object folder or the scene folder by
`run` (input touched), and the extracted slice against truth.json's true slice (median
relative error over the bins with data, where the truth is known). Writes WORK/summary.json
and prints a table.
"""

import argparse
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
PY = sys.executable


def _listing(folder):
    out = {}
    for p in Path(folder).rglob("*"):
        if p.is_file():
            st = p.stat()
            out[os.fspath(p)] = (st.st_size, st.st_mtime_ns)
    return out


def _timed(args, log):
    cmd = ["/usr/bin/time", "-v", "nice", "-n", "10", PY, "-m", "flashbrdf", *map(str, args)]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    Path(log).write_text(proc.stdout + "\n----- stderr -----\n" + proc.stderr)
    wall = re.search(r"Elapsed \(wall clock\) time.*: (?:(\d+):)?(\d+):([\d.]+)", proc.stderr)
    seconds = (int(wall.group(1) or 0) * 3600 + int(wall.group(2)) * 60 + float(wall.group(3))) \
        if wall else None
    rss = re.search(r"Maximum resident set size \(kbytes\): (\d+)", proc.stderr)
    err = proc.stderr.split("\tCommand being timed")[0]
    return {"exit": proc.returncode, "seconds": seconds,
            "rss_mb": int(rss.group(1)) / 1024 if rss else None,
            "traceback": "Traceback" in proc.stderr,
            "stderr_lines": [ln for ln in err.splitlines() if ln.strip()][-8:],
            "stdout_warnings": [ln for ln in proc.stdout.splitlines()
                                if re.search(r"warn|note|error", ln, re.I)][:10]}


def _slice_error(slice_csv, truth):
    from flashbrdf.brdf.views import read_slice_csv
    rho, n = read_slice_csv(slice_csv)
    truth = np.asarray(truth)
    ok = np.isfinite(rho).all(1) & (truth > 1e-9).all(1)
    if not ok.any():
        return None, 0
    rel = np.abs(rho[ok] / truth[ok] - 1)
    return float(np.median(rel)), int(ok.sum())


def check_case(case_dir, work, flash, extra):
    case_dir, work = Path(case_dir), Path(work)
    work.mkdir(parents=True, exist_ok=True)
    truth = json.loads((case_dir / "truth.json").read_text())
    before_obj = _listing(case_dir)
    scene, out = work / "scene", work / "out"
    result = {"case": case_dir.name}
    result["import"] = _timed(["import-diligent", case_dir, "--flash", flash, "--out", scene],
                              work / "import.log")
    if result["import"]["exit"] != 0:
        result["partial_scene"] = scene.exists()
        return result
    before_scene = _listing(scene)
    result["run"] = _timed(["run", scene, "--out", out], work / "run.log")
    result["input_touched"] = sorted(set(_listing(case_dir).items()) ^ set(before_obj.items()))
    result["scene_touched"] = sorted(k for k, v in _listing(scene).items()
                                     if before_scene.get(k) != v)
    if result["run"]["exit"] != 0:
        result["partial_out"] = sorted(os.fspath(p.relative_to(out)) for p in out.rglob("*")) \
            if out.exists() else []
        return result
    report = json.loads((out / "report.json").read_text())
    refs = report["references"]
    # report.json writes NaN as null
    de = np.array([np.nan if r["delta_e_log_mean"] is None else r["delta_e_log_mean"]
                   for r in refs], float)
    rel = np.array([np.nan if r["rel_rmse"] is None else r["rel_rmse"] for r in refs], float)
    result["K"] = len(report.get("materials") or [None])
    result["materials"] = [(m["label"], m["pixels"]) for m in report.get("materials") or []]
    result["delta_e_log_mean"] = float(np.nanmean(de)) if np.isfinite(de).any() else None
    result["delta_e_nan"] = int(np.sum(~np.isfinite(de)))
    result["rel_rmse_mean"] = float(np.nanmean(rel)) if np.isfinite(rel).any() else None
    result["n_references"] = len(refs)
    result["report_warnings"] = report.get("warnings")
    if truth.get("true_slice_photo_units") and (out / "slice.csv").is_file():
        result["slice_median_rel_err"], result["slice_bins"] = _slice_error(
            out / "slice.csv", truth["true_slice_photo_units"])
    for cmd in extra:
        if cmd == "segment":
            result["segment"] = _timed(["segment", scene, "--out", work / "labels.png"],
                                       work / "segment.log")
        elif cmd == "extract":
            result["extract"] = _timed(["extract", scene, "--out", work / "slice.csv"],
                                       work / "extract.log")
            if truth.get("true_slice_photo_units") and result["extract"]["exit"] == 0:
                result["extract_rel_err"], _ = _slice_error(work / "slice.csv",
                                                            truth["true_slice_photo_units"])
        elif cmd == "render":
            brdf = out / "dsgplvm" / "brdf.binary"
            if not brdf.is_file():
                brdf = next(out.rglob("*.binary"), None)
            if brdf is None:
                result["render"] = {"skipped": "run wrote no BRDF table"}
                continue
            result["render"] = _timed(["render", scene, "--brdf", brdf, "--out", work / "render"],
                                      work / "render.log")
    return result


def main(argv=None):
    parser = argparse.ArgumentParser()
    parser.add_argument("--synth", type=Path, required=True)
    parser.add_argument("--work", type=Path, required=True)
    parser.add_argument("--cases", default="all")
    parser.add_argument("--flash", default="52")
    parser.add_argument("--extra", default="")
    parser.add_argument("--results", action="store_true",
                        help="also write benchmarks/results/diligent_synth.{json,md}")
    args = parser.parse_args(argv)
    cases = sorted(p.name for p in args.synth.iterdir() if (p / "truth.json").is_file()) \
        if args.cases == "all" else args.cases.split(",")
    extra = [e for e in args.extra.split(",") if e]
    summary_path = args.work / "summary.json"
    summary = json.loads(summary_path.read_text()) if summary_path.is_file() else {}
    for name in cases:
        res = check_case(args.synth / name, args.work / name, args.flash, extra)
        summary[name] = res
        args.work.mkdir(parents=True, exist_ok=True)
        summary_path.write_text(json.dumps(summary, indent=1))
        run = res.get("run", {})
        print(f"{name:24s} import {res['import']['exit']} run {run.get('exit')} "
              f"{run.get('seconds')}s {run.get('rss_mb') and round(run['rss_mb'])}MB "
              f"K={res.get('K')} dE={res.get('delta_e_log_mean')} "
              f"slice={res.get('slice_median_rel_err')} tb={run.get('traceback')} "
              f"touched={len(res.get('input_touched', [])) + len(res.get('scene_touched', []))}",
              flush=True)
    if args.results:
        write_results(summary, " ".join(sys.argv[1:] if argv is None else argv))
    return 0


def write_results(summary, command):
    """benchmarks/results/diligent_synth.{json,md}: one row per case of the summary."""
    results = ROOT / "benchmarks" / "results"
    (results / "diligent_synth.json").write_text(json.dumps(
        {"command": "python -m benchmarks.diligent_synth_check " + command,
         "cases": summary}, indent=1) + "\n")
    lines = ["# The contract on synthetic DiLiGenT-format objects", "",
             f"Command: `python -m benchmarks.diligent_synth_check {command}` "
             "(objects from `benchmarks/diligent_synth.py`: 612×512, the ball's 96 lights, a known "
             "BRDF, cast shadows). Per case: `import-diligent --flash 52`, then `run` with the "
             "default method. slice error: median relative error of the extracted slice against "
             "the true one (– where the truth is path traced).", "",
             "| case | import / run exit | run s | max RSS MB | materials | ΔE-log mean | "
             "slice error | traceback | inputs touched |", "|---|---|---|---|---|---|---|---|---|"]
    for name, res in sorted(summary.items()):
        run = res.get("run", {})
        slice_err = res.get("slice_median_rel_err")
        touched = len(res.get("input_touched", [])) + len(res.get("scene_touched", []))
        de = res.get("delta_e_log_mean")
        lines.append(f"| {name} | {res['import']['exit']} / {run.get('exit')} | "
                     f"{run.get('seconds')} | {run.get('rss_mb') and round(run['rss_mb'])} | "
                     f"{res.get('K')} | {'–' if de is None else f'{de:.3f}'} | "
                     f"{'–' if slice_err is None else f'{slice_err:.1e}'} | "
                     f"{run.get('traceback')} | {touched} |")
    (results / "diligent_synth.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    sys.exit(main())
