"""Export benchmark: the Mitsuba plugin against our renderer, and the Principled fit's error.

Parts (each writes benchmarks/results/export_<part>.json; every run rewrites export_fit.md from
the JSON files present):
- plugin:   a sphere of MERL (NBRDF proxy) materials under pisa, rendered by Mitsuba 3 through
            `flashbrdf_tabulated` (llvm_ad_rgb) and by our renderer (render_sphere, the code
            `flashbrdf render` runs), same camera and map, twice each (seeds 0 and 1) at --spp.
            Relative RMSE of 4x4 block means (blocks wholly on the sphere), both times, and the
            per-pixel noise: RMS of (seed 0 - seed 1) / sqrt 2, relative to the mean pixel.
- recovery: Principled tabulated at known parameters into the MERL layout, fitted back.
- measured: the fit on every MERL (NBRDF proxy) and RGL (NBRDF proxy) table: 2D LAB-log error,
            fit seconds, and (for --render-every k-th material) the sphere Delta E under pisa.

    nice -n 10 python -m benchmarks.export_fit --part plugin --spp 1024 --size 128
    nice -n 10 python -m benchmarks.export_fit --part recovery
    nice -n 10 python -m benchmarks.export_fit --part measured --merl-dir /work/data/merl \
        --rgl-dir /work/data/rgl
"""

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
# the paper's pisa probe (research use only: read from ../shared, never shipped)
PISA = (Path(os.environ.get("FLASHBRDF_SHARED", ROOT.parent / "shared")) / "data" / "envmaps"
        / "pisa_latlong_256x128.hdr")

from flashbrdf.files.atomic import write_text
from flashbrdf.brdf.merl import list_merl, read_merl
from flashbrdf.brdf.metrics import brdf_error
from flashbrdf.brdf.models.principled import tabulate_principled
from flashbrdf.brdf.models.principled_fit import fit_principled
from flashbrdf.brdf.views import table_2d
from flashbrdf.render.export import fit_quality

RESULTS = ROOT / "benchmarks" / "results"
KNOWN = {
    "rough_dielectric": {"base_color": [0.6, 0.3, 0.2], "roughness": 0.7, "specular": 0.5},
    "glossy_dielectric": {"base_color": [0.1, 0.3, 0.6], "roughness": 0.2, "specular": 0.5},
    "rough_metal": {"base_color": [0.9, 0.6, 0.3], "roughness": 0.5, "metallic": 1.0},
    "glossy_metal": {"base_color": [0.95, 0.93, 0.88], "roughness": 0.15, "metallic": 1.0},
    "clearcoat_paint": {"base_color": [0.5, 0.05, 0.05], "roughness": 0.5, "clearcoat": 1.0,
                        "clearcoat_gloss": 0.8},
    "sheen_fabric": {"base_color": [0.2, 0.4, 0.2], "roughness": 0.9, "sheen": 1.0,
                     "sheen_tint": 0.5, "specular": 0.3},
}
# Material kinds by name, for "what Principled cannot represent".
KINDS = (("colour-changing / iridescent", ("cc_", "irid", "chm_", "cm_", "vch_",
                                            "color-changing")),
         ("paper / diffuse", ("paper", "cardboard", "spectralon", "matte")),
         ("metal / metallic paint", ("alum", "brass", "chrome", "nickel", "steel", "silver",
                                     "gold", "copper", "tungsten", "metal", "aluminium",
                                     "bronze", "ss440", "hematite")),
         ("paint", ("paint",)),
         ("fabric", ("fabric", "felt", "velvet", "satin", "silk", "cloth", "denim", "leather")),
         ("plastic/acrylic/rubber", ("plastic", "acrylic", "phenolic", "rubber", "pvc", "delrin",
                                     "resin", "polyethylene", "polyurethane", "nylon", "teflon")))


def kind_of(name):
    for kind, words in KINDS:
        if any(w in name for w in words):
            return kind
    return "other"


def block_means(image, mask, block=4):
    """Means of block x block tiles wholly on the mask: (n_blocks, 3)."""
    h, w = mask.shape
    tiles = image[:h - h % block, :w - w % block].reshape(h // block, block, w // block, block, 3)
    full = mask[:h - h % block, :w - w % block].reshape(h // block, block, w // block, block)
    keep = full.all(axis=(1, 3))
    return tiles.mean(axis=(1, 3))[keep]


def _mitsuba_spheres(args):
    """(mitsuba_bsdf module, pisa envmap path, sphere mask (size, size), [(name, path)]) for the
    Mitsuba parts: llvm_ad_rgb registered, one MERL table per --plugin-materials name."""
    import flashbrdf.render.mitsuba_bsdf as mbsdf
    from flashbrdf.render.scene_render import sphere_view
    if not mbsdf.llvm_available():
        raise SystemExit("llvm_ad_rgb unavailable: pip install -e '.[mitsuba]', apt-get install "
                         "libllvm19")
    mbsdf.register("llvm_ad_rgb")
    materials = [(name, Path(args.merl_dir) / f"{name}.binary")
                 for name in args.plugin_materials.split(",")]
    return mbsdf, PISA, sphere_view(args.size)[0], materials


def part_plugin(args):
    from flashbrdf.render.scene_render import render_sphere
    mbsdf, pisa, mask, materials = _mitsuba_spheres(args)
    rows = []
    for name, path in materials:
        table = read_merl(path)
        images, times = {"mitsuba": [], "ours": []}, {"mitsuba": [], "ours": []}
        for seed in (0, 1):
            start = time.perf_counter()
            image, _ = mbsdf.render_sphere_mitsuba(
                {"type": "flashbrdf_tabulated", "filename": str(path)}, pisa, size=args.size,
                spp=args.spp, seed=seed)
            times["mitsuba"].append(time.perf_counter() - start)
            images["mitsuba"].append(image)
            start = time.perf_counter()
            images["ours"].append(render_sphere(table, pisa, size=args.size, spp=args.spp,
                                                seed=seed))
            times["ours"].append(time.perf_counter() - start)
        a, b = block_means(images["mitsuba"][0], mask), block_means(images["ours"][0], mask)
        row = {"material": name, "size": args.size, "spp": args.spp,
               "block_rel_rmse": float(np.sqrt(np.sum((a - b) ** 2) / np.sum(b * b))),
               "seconds": {k: float(np.mean(v)) for k, v in times.items()}}
        for k, (i0, i1) in images.items():
            noise = np.sqrt(np.mean((i0[mask] - i1[mask]) ** 2) / 2.0)
            row[f"noise_rel_{k}"] = float(noise / np.mean(i0[mask]))
        print(row, flush=True)
        rows.append(row)
        np.save(RESULTS / f"export_plugin_{name}.npy",
                np.stack([images["mitsuba"][0], images["ours"][0]]).astype(np.float16))
    return {"command": "nice -n 10 python -m benchmarks.export_fit --part plugin "
                       f"--spp {args.spp} --size {args.size} --plugin-materials "
                       f"{args.plugin_materials}", "envmap": str(pisa), "rows": rows}


def part_noise(args):
    """Per-pixel noise of the plugin against Mitsuba's own BSDFs of a similar look, all through
    Mitsuba's path integrator with the same sampler and spp: the plugin's sampling against
    roughplastic's and principled's (fitted to the same table)."""
    mbsdf, pisa, mask, materials = _mitsuba_spheres(args)
    rows = []
    for name, path in materials:
        p = fit_principled(read_merl(path))["params"]
        bsdfs = {
            "flashbrdf_tabulated": {"type": "flashbrdf_tabulated", "filename": str(path)},
            "principled (fitted)": {"type": "principled", **{
                k: ({"type": "rgb", "value": v} if k == "base_color" else v)
                for k, v in p.items()}},
            "roughplastic (GGX, alpha = fitted roughness^2)": {
                "type": "roughplastic", "distribution": "ggx",
                "alpha": max(0.001, p["roughness"] ** 2),
                "diffuse_reflectance": {"type": "rgb", "value": p["base_color"]}}}
        for label, bsdf in bsdfs.items():
            start = time.perf_counter()
            i0, _ = mbsdf.render_sphere_mitsuba(bsdf, pisa, size=args.size, spp=args.spp, seed=0)
            i1, _ = mbsdf.render_sphere_mitsuba(bsdf, pisa, size=args.size, spp=args.spp, seed=1)
            noise = np.sqrt(np.mean((i0[mask] - i1[mask]) ** 2) / 2.0) / np.mean(i0[mask])
            rows.append({"material": name, "bsdf": label, "size": args.size, "spp": args.spp,
                         "noise_rel": float(noise),
                         "seconds": (time.perf_counter() - start) / 2})
            print(rows[-1], flush=True)
    return {"command": "nice -n 10 python -m benchmarks.export_fit --part noise "
                       f"--spp {args.spp} --size {args.size} --plugin-materials "
                       f"{args.plugin_materials}", "rows": rows}


def part_recovery(args):
    rows = []
    for name, truth in KNOWN.items():
        table = tabulate_principled(truth)
        result = fit_principled(table)
        fit = result["params"]
        rows.append({"material": name, "truth": truth, "fit": fit, "seconds": result["seconds"],
                     "cpu_seconds": result["cpu_seconds"],
                     "lab_log_2d": brdf_error(table_2d(tabulate_principled(fit)),
                                              table_2d(table))})
        print(name, rows[-1]["lab_log_2d"], result["seconds"], flush=True)
    return {"command": "nice -n 10 python -m benchmarks.export_fit --part recovery", "rows": rows}


def part_measured(args):
    pisa = PISA
    rows = []
    sets = [("MERL (NBRDF proxy)", args.merl_dir), ("RGL (NBRDF proxy)", args.rgl_dir)]
    jobs = [[(label, name, path) for name, path in list_merl(folder)] for label, folder in sets
            if folder]
    # Shuffle each set (seed 0) and interleave them, so a run cut short is a random subset of both.
    jobs = [[group[i] for i in np.random.default_rng(0).permutation(len(group))] for group in jobs]
    order = [job for group in _interleave(jobs) for job in group]
    command = ("nice -n 10 python -m benchmarks.export_fit --part measured --merl-dir "
               f"{args.merl_dir} --rgl-dir {args.rgl_dir} --render-every {args.render_every}")
    for k, (label, name, path) in enumerate(order):
        table = read_merl(path)
        result = fit_principled(table)
        render = args.render_every and k % args.render_every == 0
        quality = fit_quality(table, result["params"], pisa if render else None)
        rows.append({"set": label, "material": name, "kind": kind_of(name),
                     "lab_log_2d": quality["lab_log_2d"], "seconds": result["seconds"],
                     "render_delta_e_log": (quality["render"]["delta_e_log_mean"]
                                            if quality["render"] else None),
                     "params": result["params"]})
        print(label, name, f"{quality['lab_log_2d']:.2f}", f"{result['seconds']:.1f}s",
              flush=True)
        # Written after every material: a run stopped early keeps what it measured.
        write_text(RESULTS / "export_measured.json", json.dumps(
            {"command": command, "complete": k + 1 == len(order), "rows": rows}, indent=1))
    return {"command": command, "complete": True, "rows": rows}


def _interleave(lists):
    """[[a0, b0], [a1, b1], ...] from [[a0, a1, ...], [b0, b1, ...]] (shorter lists end early),
    with the shorter list spread evenly."""
    longest = max(len(x) for x in lists)
    slots = [[] for _ in range(longest)]
    for items in lists:
        for i, item in enumerate(items):
            slots[int(i * longest / len(items))].append(item)
    return slots


BANDS = ((0, 30), (30, 60), (60, 75), (75, 90))


def part_bands(args):
    """Where the measured fits err: log-CIELAB Delta E of the 2D views per theta_d band (degrees),
    for every material in export_measured.json, from its stored parameters."""
    from flashbrdf.brdf.metrics import delta_e_log
    measured = json.loads((RESULTS / "export_measured.json").read_text())
    folders = {"MERL (NBRDF proxy)": args.merl_dir, "RGL (NBRDF proxy)": args.rgl_dir}
    rows = []
    for r in measured["rows"]:
        table = read_merl(Path(folders[r["set"]]) / f"{r['material']}.binary")
        de = delta_e_log(table_2d(tabulate_principled(r["params"])), table_2d(table))
        rows.append({"set": r["set"], "material": r["material"],
                     "bands": {f"{lo}-{hi}": float(np.nanmean(de[:, lo:hi])) for lo, hi in BANDS}})
    return {"command": "nice -n 10 python -m benchmarks.export_fit --part bands", "rows": rows}


def _stats(values):
    v = np.asarray([x for x in values if x is not None], dtype=float)
    if not v.size:
        return "n/a"
    return (f"{v.mean():.2f} / {np.median(v):.2f} / {np.percentile(v, 90):.2f} / {v.max():.2f} "
            f"(n={v.size})")


def plugin_figure():
    """export_plugin.png from the saved renders: Mitsuba (plugin), ours, and their difference."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from flashbrdf.files.atomic import atomic_path
    from flashbrdf.render.images import tonemap
    saved = sorted(RESULTS.glob("export_plugin_*.npy"))
    if not saved:
        return None
    fig, axes = plt.subplots(len(saved), 3, figsize=(7.5, 2.6 * len(saved)), squeeze=False)
    for row, path in zip(axes, saved):
        mitsuba, ours = np.load(path).astype(np.float32)
        exposure = 1.0 / max(float(np.percentile(ours[ours > 0], 99)), 1e-6)
        row[0].imshow(tonemap(mitsuba, exposure))
        row[1].imshow(tonemap(ours, exposure))
        diff = np.abs(mitsuba - ours).mean(axis=-1) * exposure
        im = row[2].imshow(diff, cmap="inferno", vmin=0, vmax=0.2)
        name = path.stem.replace("export_plugin_", "")
        row[0].set_title(f"{name}: Mitsuba 3 + plugin", fontsize=8)
        row[1].set_title("flashbrdf renderer", fontsize=8)
        row[2].set_title("|difference| (exposed)", fontsize=8)
        for ax in row:
            ax.set_axis_off()
        fig.colorbar(im, ax=row[2], fraction=0.046)
    with atomic_path(RESULTS / "export_plugin.png") as tmp:
        fig.savefig(tmp, format="png", dpi=100)
    plt.close(fig)
    return "export_plugin.png"


def markdown():
    lines = ["# Export: the Mitsuba plugin and the Principled fit", ""]
    plugin = RESULTS / "export_plugin.json"
    if plugin.exists():
        res = json.loads(plugin.read_text())
        lines += ["## Plugin against our renderer (sphere under pisa)", "",
                  f"`{res['command']}`", "",
                  "| material | size | spp | rel. RMSE of 4x4 block means | Mitsuba s | ours s | "
                  "noise Mitsuba | noise ours |", "|---|---|---|---|---|---|---|---|"]
        for r in res["rows"]:
            lines.append(f"| {r['material']} | {r['size']} | {r['spp']} | "
                         f"{100 * r['block_rel_rmse']:.2f}% | {r['seconds']['mitsuba']:.1f} | "
                         f"{r['seconds']['ours']:.1f} | {100 * r['noise_rel_mitsuba']:.2f}% | "
                         f"{100 * r['noise_rel_ours']:.2f}% |")
        lines += ["", "Noise: per-pixel RMS of (seed 0 - seed 1) / sqrt 2 over the sphere, relative "
                  "to the mean pixel, at the same spp.", ""]
        figure = plugin_figure()
        if figure:
            lines += [f"![plugin against our renderer]({figure})", ""]
    noise = RESULTS / "export_noise.json"
    if noise.exists():
        res = json.loads(noise.read_text())
        lines += ["## Plugin sampling against Mitsuba's own BSDFs (same integrator and sampler)",
                  "", f"`{res['command']}`", "",
                  "| material | BSDF | size | spp | per-pixel noise | s per render |",
                  "|---|---|---|---|---|---|"]
        lines += [f"| {r['material']} | {r['bsdf']} | {r['size']} | {r['spp']} | "
                  f"{100 * r['noise_rel']:.2f}% | {r['seconds']:.1f} |" for r in res["rows"]]
        lines.append("")
    recovery = RESULTS / "export_recovery.json"
    if recovery.exists():
        res = json.loads(recovery.read_text())
        lines += ["## Fit recovers known parameters", "", f"`{res['command']}`", "",
                  "| material | roughness true / fit | metallic true / fit | base_color true | "
                  "base_color fit | LAB-log 2D | s (CPU s) |", "|---|---|---|---|---|---|---|"]
        for r in res["rows"]:
            t, f = r["truth"], r["fit"]
            lines.append(
                f"| {r['material']} | {t['roughness']:.2f} / {f['roughness']:.3f} | "
                f"{t.get('metallic', 0.0):.2f} / {f['metallic']:.3f} | "
                f"{', '.join(f'{c:.2f}' for c in t['base_color'])} | "
                f"{', '.join(f'{c:.3f}' for c in f['base_color'])} | {r['lab_log_2d']:.4f} | "
                f"{r['seconds']:.1f} ({r.get('cpu_seconds', float('nan')):.1f}) |")
        lines.append("")
    measured = RESULTS / "export_measured.json"
    if measured.exists():
        res = json.loads(measured.read_text())
        rows = res["rows"]
        for r in rows:   # kinds from the current KINDS, not those stored when measured
            r["kind"] = kind_of(r["material"])
        lines += ["## Fit on measured materials", "", f"`{res['command']}`", ""]
        if not res.get("complete", True):
            lines += [f"The run was stopped after {len(rows)} materials (the two sets interleaved); "
                      "these are the ones measured.", ""]
        lines += [
                  "2D LAB-log error of the fitted Principled against the table (mean / median / "
                  "90th percentile / max); fit seconds (wall, at nice 10 on 2 cores: they rise "
                  "with the machine's load; the recovery table's CPU seconds are the fit's own "
                  "cost); sphere Delta E log under pisa where rendered (tabulated fit against "
                  "the table, same seed, 256 spp: each samples its own table, so noise adds a "
                  "little).", "",
                  "| group | LAB-log 2D | fit s | sphere Delta E log |", "|---|---|---|---|"]
        groups = [("all", rows)] + [(s, [r for r in rows if r["set"] == s])
                                    for s in dict.fromkeys(r["set"] for r in rows)]
        groups += [(f"kind: {k}", [r for r in rows if r["kind"] == k])
                   for k in dict.fromkeys(r["kind"] for r in rows)]
        for label, group in groups:
            lines.append(f"| {label} | {_stats(r['lab_log_2d'] for r in group)} | "
                         f"{_stats(r['seconds'] for r in group)} | "
                         f"{_stats(r['render_delta_e_log'] for r in group)} |")
        bands = RESULTS / "export_bands.json"
        if bands.exists():
            res_b = json.loads(bands.read_text())
            lines += ["", "Where the error is: mean log-CIELAB Delta E of the 2D views per theta_d "
                      f"band, over the {len(res_b['rows'])} fitted materials "
                      f"(`{res_b['command']}`):", "",
                      "| set | " + " | ".join(f"theta_d {lo}-{hi} deg" for lo, hi in BANDS) + " |",
                      "|---|" + "---|" * len(BANDS)]
            for label in ["all"] + list(dict.fromkeys(r["set"] for r in res_b["rows"])):
                group = [r for r in res_b["rows"] if label in ("all", r["set"])]
                lines.append(f"| {label} | " + " | ".join(
                    f"{np.mean([r['bands'][f'{lo}-{hi}'] for r in group]):.2f}"
                    for lo, hi in BANDS) + " |")
        worst = sorted(rows, key=lambda r: -r["lab_log_2d"])[:12]
        lines += ["", "Worst fits:", "", "| set | material | kind | LAB-log 2D | metallic | "
                  "roughness | clearcoat |", "|---|---|---|---|---|---|---|"]
        for r in worst:
            p = r["params"]
            lines.append(f"| {r['set']} | {r['material']} | {r['kind']} | {r['lab_log_2d']:.2f} | "
                         f"{p['metallic']:.2f} | {p['roughness']:.2f} | {p['clearcoat']:.2f} |")
        lines += ["", "| set | material | kind | LAB-log 2D | s |", "|---|---|---|---|---|"]
        lines += [f"| {r['set']} | {r['material']} | {r['kind']} | {r['lab_log_2d']:.2f} | "
                  f"{r['seconds']:.1f} |" for r in rows]
    write_text(RESULTS / "export_fit.md", "\n".join(lines) + "\n")


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--part", choices=["plugin", "noise", "recovery", "measured", "bands",
                                      "markdown"],
                   required=True)
    p.add_argument("--merl-dir", default="/work/data/merl")
    p.add_argument("--rgl-dir", default="/work/data/rgl")
    p.add_argument("--spp", type=int, default=1024)
    p.add_argument("--size", type=int, default=128)
    p.add_argument("--plugin-materials", default="blue-acrylic,alum-bronze")
    p.add_argument("--render-every", type=int, default=5)
    args = p.parse_args()
    RESULTS.mkdir(parents=True, exist_ok=True)
    if args.part != "markdown":
        result = {"plugin": part_plugin, "noise": part_noise, "recovery": part_recovery,
                  "measured": part_measured, "bands": part_bands}[args.part](args)
        write_text(RESULTS / f"export_{args.part}.json", json.dumps(result, indent=1) + "\n")
    markdown()


if __name__ == "__main__":
    main()
