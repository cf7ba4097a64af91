"""Several materials on a real object: DiLiGenT pot2, one BRDF against one per material.

    nice -n 10 python -m benchmarks.multi_material [--methods dsgplvm] [--work DIR]
        [--objects pot2,ball,cards] [--runs single,auto,auto_albedo]

pot2 (../shared/data/real/diligent-pot2, 8-bit linear crops) is imported with shot 052 as the
flash and the other 95 shots as references (`import-diligent --flash 52`). `run` is called
twice through the public command line: `--materials 1` (today's single-material pipeline) and
`--materials auto` (segment, then a slice, a BRDF and a render per material). The numbers are
the mean over the 95 references of each render's ΔE log mean (the contract's compare metric).
`auto_albedo` is `--materials auto --albedo-map` (the per-pixel diffuse albedo map on top).
The DiLiGenT ball is segmented too, as the single-material check (auto must choose 1).
The flash planar cards (three inks) are segmented on view 00 and the 8 other views rendered
with one BRDF per material (`segment`, `extract --labels`, `infer`, `render --labels`), and
again with the albedo map (`segment --albedo`, `render --albedo`) when auto_albedo is measured.
Writes benchmarks/results/multi_material.{json,md} and multi_material_<object>_labels.png.
"""

import json
import shutil
import sys
from pathlib import Path

from benchmarks._real_common import RESULTS, SHARED, argument_parser, run_cli


RUNS = {"single": ("1", []), "auto": ("auto", []), "auto_albedo": ("auto", ["--albedo-map"])}


def _run(scene, out, materials, methods, log, extra=()):
    rc, err, seconds = run_cli(["run", scene, "--out", out, "--methods", methods,
                                "--materials", materials, "--force", *extra])
    if rc != 0:
        raise SystemExit(f"run --materials {materials} failed (exit {rc}): {err}")
    report = json.loads((Path(out) / "report.json").read_text())
    summary = {m: s["delta_e_log_mean"]["mean"] for m, s in report["summary"].items()}
    log(f"--materials {materials} {' '.join(extra)}: {len(report['materials'])} material(s), mean ΔE log "
        f"{summary} ({seconds:.0f} s)")
    return {"materials": len(report["materials"]), "delta_e_log_mean": summary,
            "references": {m: s["references"] for m, s in report["summary"].items()},
            "pixels": [m["pixels"] for m in report["materials"]], "seconds": seconds,
            "segmentation": report.get("segmentation")}


def main(argv=None):
    ap = argument_parser(__doc__.splitlines()[0], "diligent-pot2", "flashbrdf_bench_multi")
    ap.set_defaults(methods="dsgplvm")
    ap.add_argument("--objects", default="pot2,ball,cards",
                    help="which to (re)measure; the others keep their entries in the JSON")
    ap.add_argument("--runs", default="single,auto,auto_albedo",
                    help="which runs to (re)measure: single (--materials 1), auto, auto_albedo "
                         "(--materials auto --albedo-map); the others keep their entries")
    args = ap.parse_args(argv)
    runs = [r for r in args.runs.split(",") if r]
    wanted = set(args.objects.split(","))
    log = lambda msg: print(msg, flush=True)  # noqa: E731
    work = args.work
    work.mkdir(parents=True, exist_ok=True)
    previous = RESULTS / "multi_material.json"
    result = json.loads(previous.read_text()) if previous.is_file() else {"objects": {}}
    command = "nice -n 10 python -m benchmarks.multi_material " + " ".join(argv or sys.argv[1:])
    result["command"] = command
    for name, folder in (("pot2", args.data),
                         ("ball", SHARED / "data" / "real" / "diligent-ball")):
        if name not in wanted:
            continue
        scene = work / f"{name}_scene"
        if not (scene / "scene.json").is_file():
            rc, err, _ = run_cli(["import-diligent", folder, "--flash", 52, "--out", scene])
            if rc != 0:
                raise SystemExit(f"import-diligent {folder} failed (exit {rc}): {err}")
        entry = result["objects"].get(name, {})
        for run in runs:
            if run == "single" and name != "pot2":
                continue
            materials, extra = RUNS[run]
            entry[run] = dict(_run(scene, work / f"{name}_{run}", materials, args.methods, log,
                                   extra), command=command)
            if run == "auto":
                shutil.copyfile(work / f"{name}_auto" / "figures" / "labels.png",
                                RESULTS / f"multi_material_{name}_labels.png")
                entry["labels_png"] = f"multi_material_{name}_labels.png"
        reference = entry.get("single") or entry.get("auto")
        entry["reduction"] = {run: {m: 1 - entry[run]["delta_e_log_mean"][m] / v
                                    for m, v in reference["delta_e_log_mean"].items()
                                    if m in entry[run]["delta_e_log_mean"]}
                              for run in RUNS if run in entry and entry[run] is not reference}
        result["objects"][name] = entry
    if "cards" in wanted:
        result["planar_cards"] = dict(_planar_cards(work, args.methods.split(","), log,
                                                    "auto_albedo" in runs), command=command)
    (RESULTS / "multi_material.json").write_text(json.dumps(result, indent=1) + "\n")
    (RESULTS / "multi_material.md").write_text(_markdown(result))
    log(f"wrote {RESULTS / 'multi_material.md'}")
    return 0


def _planar_cards(work, methods, log, albedo=False):
    """The planar cards: segment view 00 (auto), a slice and a BRDF per material, and every
    other view rendered with them. The views are rectified to the card, so one label image
    serves every view's pixel grid (each view's scene has its own flash photo and camera)."""
    from flashbrdf.pipeline.options import DEFAULT_MODEL
    from benchmarks.planar_scenes import planar_card_scenes
    folder = work / "planar_scenes"
    views = (sorted(p for p in folder.iterdir() if (p / "scene.json").is_file())
             if folder.is_dir() else
             planar_card_scenes(SHARED / "data" / "real" / "flash-planar-cards-blue", folder))
    flash = views[0]
    labels, albedo_exr = work / "planar_labels.png", work / "planar_albedo.exr"
    for argv in (["segment", flash, "--out", labels, "--albedo", albedo_exr],
                 ["extract", flash, "--labels", labels, "--out", work / "planar_slices"]):
        rc, err, _ = run_cli(argv)
        if rc != 0:
            raise SystemExit(f"{argv[0]} on the planar cards failed (exit {rc}): {err}")
    k = json.loads(labels.with_suffix(".json").read_text())["materials"]
    out = {"flash_view": flash.name, "materials": k, "labels_png": "multi_material_cards_labels.png",
           "delta_e_log_mean": {}}
    _save_label_png(labels, RESULTS / out["labels_png"])
    for method in methods:
        tables = []
        for j in range(1, k + 1):
            table = work / "planar_brdf" / method / f"material_{j}.binary"
            rc, err, _ = run_cli(["infer", "--model", DEFAULT_MODEL, "--slice",
                                  work / "planar_slices" / f"material_{j}.csv",
                                  "--method", method, "--out", table])
            if rc != 0:
                raise SystemExit(f"infer material {j} failed (exit {rc}): {err}")
            tables.append(str(table))
        for variant, extra in (("", []), ("_albedo", ["--albedo", albedo_exr]))[:1 + albedo]:
            errors = []
            for view in views[1:]:
                target = work / f"planar_render{variant}" / method / view.name
                rc, err, _ = run_cli(["render", view, "--brdf", ",".join(tables), "--labels",
                                      labels, "--out", target, "--force", *extra])
                if rc != 0:
                    raise SystemExit(f"render {view.name} failed (exit {rc}): {err}")
                compare = next(target.glob("*_compare.json"))
                errors.append(json.loads(compare.read_text())["delta_e_log_mean"])
            out.setdefault(f"delta_e_log_mean{variant}", {})[method] = sum(errors) / len(errors)
            out.setdefault(f"per_view{variant}", {})[method] = errors
            log(f"planar cards, {k} material(s), {method}{variant}: mean ΔE log "
                f"{sum(errors) / len(errors):.2f}")
    return out


def _save_label_png(labels_png, target):
    import cv2
    from flashbrdf.pipeline.report_figures import label_map
    label_map(target, cv2.imread(str(labels_png), cv2.IMREAD_UNCHANGED))


def _markdown(result):
    lines = ["# Several materials: one BRDF against one per material (DiLiGenT, flash = shot 052)",
             "", "Mean over the reference shots of ΔE log mean (95 references per object; photos "
             "are the DiLiGenT shots, 'MERL (NBRDF proxy)' model). Commands (each object keeps "
             "the command that measured it):", ""]
    lines += [f"- {name} {run}: `{entry[run].get('command', result['command'])}`"
              for name, entry in result["objects"].items() for run in RUNS if run in entry]
    if result.get("planar_cards"):
        lines += [f"- planar cards: `{result['planar_cards'].get('command', result['command'])}`"]
    lines += ["",
             "| object | run | materials | pixels per material | method | ΔE log mean | change |",
             "|---|---|---|---|---|---|---|"]
    names = {"single": "--materials 1", "auto": "--materials auto",
             "auto_albedo": "--materials auto --albedo-map"}
    for name, entry in result["objects"].items():
        for run in RUNS:
            if run not in entry:
                continue
            r = entry[run]
            for method, value in r["delta_e_log_mean"].items():
                change = entry.get("reduction", {}).get(run, {}).get(method)
                change = "" if change is None else f"{-100 * change:+.0f}%"
                lines.append(f"| {name} | {names[run]} | "
                             f"{r['materials']} | {', '.join(map(str, r['pixels']))} | {method} | "
                             f"{value:.2f} | {change} |")
    lines += ["", "change: against --materials 1 where it was run (pot2), else against "
              "--materials auto."]
    cards = result.get("planar_cards")
    if cards:
        lines += ["", f"Planar cards (flash = {cards['flash_view']}, the other 8 views predicted; "
                  f"{cards['materials']} material(s) found): mean ΔE log "
                  + ", ".join(f"{m} {v:.2f}" for m, v in cards["delta_e_log_mean"].items())
                  + " (one BRDF for the whole card: 17.27 for dsgplvm, planar_cards.md)"
                  + ("; with the albedo map (segment --albedo, render --albedo): "
                     + ", ".join(f"{m} {v:.2f}" for m, v in cards["delta_e_log_mean_albedo"].items())
                     if cards.get("delta_e_log_mean_albedo") else "") + ".", "",
                  f"cards label map (auto): ![cards]({cards['labels_png']})"]
    lines += [""]
    for name, entry in result["objects"].items():
        lines += [f"{name} label map (auto): ![{name}]({entry['labels_png']})", ""]
    return "\n".join(lines)


if __name__ == "__main__":
    sys.exit(main())
