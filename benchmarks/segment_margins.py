"""How far `segment --materials auto` is from choosing another K: its criterion's margins.

    nice -n 10 python benchmarks/segment_margins.py [--merl-dir /work/data/merl] [--work DIR]

Objects: the real captures (DiLiGenT pot2 and ball, flash = shot 052; the sample capture; the
flash planar cards' view 00) and synthetic ones rendered through the contract's pixel model
(tests/synthetic.py: trimesh rays, not ours) with Poisson noise of 2000 photons at the mean
pixel: one material (a sphere, and a sphere behind a torus that shadows it) for a diffuse, a
glossy and a metallic MERL (NBRDF proxy) table; two and three materials split by planes; and
one material with a printed diffuse albedo (stripes of +-30%), which auto is not asked to keep
whole (the albedo map is for that) but whose K is reported.

For each: K chosen, and the three tests' margins (slice_extract.segment):
- separation: pooled-sigma distance of the closest pair of mixture components kept apart
  (>= 3 keeps them) and the largest merged;
- alike: ln-rho slice gaps of cluster pairs (< 0.1 merges them);
- explained: own-slice against one-slice residual ratio of the worst material (<= 0.6 keeps it).
The last column is the third test alone (separation and alike merging off): a single material
is split only if all three fail. Writes benchmarks/results/segment_margins.{json,md}.
"""

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from benchmarks._real_common import REPO, RESULTS, SHARED, run_cli  # noqa: E402

PHOTONS = 2000


def _synthetic(work, merl_dir):
    """{name: (scene folder, true K)} of the synthetic objects (rendered once into work)."""
    from flashbrdf.brdf.merl import read_merl
    from synthetic import (by_region, combine, pinhole_camera, point_light, sphere_mesh,
                           table_brdf, torus_mesh, write_synthetic_scene)
    table = {}

    def brdf(name):
        if name not in table:
            table[name] = table_brdf(read_merl(Path(merl_dir) / f"{name}.binary"))
        return table[name]

    cam = pinhole_camera(256, 256, 1000.0)
    flash = [point_light([0.03, 0, 0])]
    sphere = sphere_mesh()
    shadowed = combine(sphere_mesh(radius=0.07, centre=(0, 0, 1.1)),
                       torus_mesh(centre=(0.0, 0.0, 0.98)))
    half = lambda p: (p[:, 0] + 0.5 * p[:, 1] > 0.02).astype(int)  # noqa: E731
    third = lambda p: np.digitize(p[:, 0] - 0.3 * p[:, 1], [-0.03, 0.035])  # noqa: E731
    cases = {}
    for material in ("white-diffuse-bball", "blue-acrylic", "gold-metallic-paint", "nickel"):
        cases[f"1 material: {material}, sphere"] = (sphere, brdf(material), 1)
        cases[f"1 material: {material}, sphere + torus (shadows)"] = (shadowed, brdf(material), 1)
    cases["2 materials: red-specular-plastic / blue-acrylic"] = (
        sphere, by_region([brdf("red-specular-plastic"), brdf("blue-acrylic")], half), 2)
    cases["2 materials: gray-plastic / white-paint (similar colour)"] = (
        sphere, by_region([brdf("gray-plastic"), brdf("white-paint")], half), 2)
    cases["3 materials: yellow-paint / blue-acrylic / nickel"] = (
        sphere, by_region([brdf("yellow-paint"), brdf("blue-acrylic"), brdf("nickel")], third), 3)
    cases["1 material, printed albedo: gray-plastic + stripes"] = (sphere, _printed(brdf), 1)
    out = {}
    for i, (name, (mesh, fn, k)) in enumerate(cases.items()):
        folder = work / f"synthetic_{i:02d}"
        if not (folder / "scene.json").is_file():
            write_synthetic_scene(folder, mesh, fn, cam, flash, photons=PHOTONS, seed=i)
        out[name] = (folder, k)
    return out


def _printed(brdf):
    base = brdf("gray-plastic")

    def fn(wi, wo, normal, points):
        up = (np.sum(wi * normal, -1) > 0) & (np.sum(wo * normal, -1) > 0)
        stripes = 0.5 * (1 + np.sin(2 * np.pi * (points[:, 0] + points[:, 1]) / 0.05))
        return base(wi, wo, normal) * (0.7 + 0.6 * stripes[:, None] * np.array([1, 0.6, 0.3])) \
            * up[:, None]
    fn.spatial = True
    return fn


def _real(work):
    from flashbrdf.pipeline.real_scenes import planar_card_scenes
    out = {}
    for name, folder in (("pot2", "diligent-pot2"), ("ball", "diligent-ball")):
        scene = work / f"{name}_scene"
        if not (scene / "scene.json").is_file():
            rc, err, _ = run_cli(["import-diligent", SHARED / "data" / "real" / folder,
                                  "--flash", 52, "--out", scene])
            if rc != 0:
                raise SystemExit(f"import-diligent {folder} failed: {err}")
        out[f"DiLiGenT {name}"] = (scene, 2 if name == "pot2" else 1)
    out["sample capture"] = (REPO / "sample_data" / "capture", 1)
    cards = work / "planar_scenes"
    if not (cards / "view_00" / "scene.json").is_file():
        planar_card_scenes(SHARED / "data" / "real" / "flash-planar-cards-blue", cards)
    out["planar cards, view 00"] = (cards / "view_00", None)
    return out


def _margins(criterion):
    m = criterion.get("margins", {})
    gaps = m.get("alike_gaps", [])
    return {"bic_k": criterion.get("bic_k"), "merged_k": criterion.get("merged_k"),
            "separation_kept": m.get("separation_kept"),
            "separation_merged_max": max(m.get("separations_merged", []), default=None),
            "alike_gap_min": min(gaps, default=None),
            "alike_gap_max_merged": max((g for g in gaps if g < 0.1), default=None),
            "worst_own_vs_one_slice": m.get("worst_own_vs_one_slice", []),
            "reason": criterion.get("reason")}


def main(argv=None):
    from flashbrdf import capture
    from flashbrdf.slice_extract.extract import ExtractOptions, collect_samples
    from flashbrdf.slice_extract.segment import SegmentOptions, segment_samples
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--merl-dir", default="/work/data/merl", type=Path)
    ap.add_argument("--work", default=Path("/tmp/flashbrdf_bench_margins"), type=Path)
    args = ap.parse_args(argv)
    args.work.mkdir(parents=True, exist_ok=True)
    objects = {**_real(args.work), **_synthetic(args.work, args.merl_dir)}
    rows = []
    for name, (scene, true_k) in objects.items():
        start = time.perf_counter()
        samples = collect_samples(capture.load_scene(scene), ExtractOptions())
        seg = segment_samples(samples)
        seconds = time.perf_counter() - start
        # the last test alone: separation and slice-alike merging switched off
        alone = segment_samples(samples, options=SegmentOptions(separation=0.0, alike=0.0))
        row = {"object": name, "true_k": true_k, "k": seg.k, **_margins(seg.criterion),
               "explained_test_alone": {"k": alone.k, "worst_own_vs_one_slice": alone.criterion
                                        .get("margins", {}).get("worst_own_vs_one_slice", [])},
               "seconds": round(seconds, 2)}
        rows.append(row)
        print(json.dumps(row), flush=True)
    command = "nice -n 10 python benchmarks/segment_margins.py " + " ".join(argv or sys.argv[1:])
    (RESULTS / "segment_margins.json").write_text(json.dumps({"command": command, "rows": rows},
                                                             indent=1) + "\n")
    (RESULTS / "segment_margins.md").write_text(_markdown(command, rows))
    return 0


def _fmt(v):
    if v is None:
        return "–"
    if isinstance(v, list):
        return ", ".join(f"{x:.2f}" for x in v) or "–"
    return f"{v:.2f}" if isinstance(v, float) else str(v)


def _markdown(command, rows):
    lines = ["# `segment --materials auto`: the K criterion's margins", "",
             f"Command: `{command}`. Thresholds: components closer than 3.0 pooled sigmas merge; "
             "cluster slices closer than 0.1 (mean |Δ ln ρ|) merge; a material is kept when its "
             "own slice leaves at most 0.6 of the one-slice residual. Synthetic objects: "
             f"{PHOTONS}-photon noise, MERL (NBRDF proxy) tables.", "",
             "| object | true K | K | BIC K | after separation | closest kept apart (≥ 3) | "
             "largest merged (< 3) | smallest slice gap (≥ 0.1 keeps) | worst own/one ratio "
             "per round (≤ 0.6 keeps) | the ratio test alone: K, worst ratio per round |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['object']} | {_fmt(r['true_k'])} | {r['k']} | {_fmt(r['bic_k'])} | "
                     f"{_fmt(r['merged_k'])} | {_fmt(r['separation_kept'])} | "
                     f"{_fmt(r['separation_merged_max'])} | {_fmt(r['alike_gap_min'])} | "
                     f"{_fmt(r['worst_own_vs_one_slice'])} | {r['explained_test_alone']['k']}: "
                     f"{_fmt(r['explained_test_alone']['worst_own_vs_one_slice'])} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    sys.exit(main())
