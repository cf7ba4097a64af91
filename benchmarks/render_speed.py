"""Render speed and convergence of the environment-map integrator (a benchmark, not a test).

1. Speed: a 512 x 512 sphere (orthographic, unit sphere filling the frame) with a 3D MERL table
   under `pisa`, at 16, 64, 256 and 1024 samples per pixel (target: 64 spp < 20 s, 2 cores).
   One sample = one envmap direction + one BRDF direction, combined by MIS (pbrt/Mitsuba's
   convention); a single strategy alone draws one direction per sample.
2. Error against run time: relative RMSE of each spp against a converged render (many spp) of
   the same view at a smaller size (the error is a per-pixel statistic, so size only sets cost).
3. Variance against spp under the very high dynamic range maps grace (peak ~3500) and
   royal_esplanade (~5e4), for MIS and for each strategy alone.

Writes benchmarks/results/render_speed.json, render_speed.png (error vs time) and
render_variance.png (error vs spp). Usage:
    python -m benchmarks.render_speed [--merl-dir DIR] [--material NAME] [--quick]
Without --merl-dir the table is generated with ../shared/tools/merl_proxy.py into a temp folder.
"""

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("FLASHBRDF_SHARED", REPO.parent / "shared"))
if not SHARED.exists():
    SHARED = Path("/work/shared")
ENVMAPS = SHARED / "data" / "envmaps"
RESULTS = REPO / "benchmarks" / "results"

from flashbrdf.brdf.merl import read_merl                     
from flashbrdf.brdf.models import TabulatedBRDF        
from flashbrdf.render.envmap import EnvMap                    
from flashbrdf.render.integrator import render_envmap         
from flashbrdf.render.scene_render import sphere_view         


def table_path(args, name):
    if args.merl_dir:
        return Path(args.merl_dir) / f"{name}.binary"
    folder = Path(tempfile.mkdtemp(prefix="merl_proxy_"))
    subprocess.run([sys.executable, str(SHARED / "tools" / "merl_proxy.py"), "--out", str(folder),
                    "--materials", name], check=True, capture_output=True)
    return folder / f"{name}.binary"


def rel_rmse(image, reference):
    return float(np.sqrt(np.sum((image - reference) ** 2) / np.sum(reference ** 2)))


def timed_render(size, brdf, env, spp, seed=1, **kw):
    mask, normals, view = sphere_view(size)
    start, cpu = time.perf_counter(), time.process_time()
    values = render_envmap(normals, normals, view, brdf, env, spp=spp, seed=seed, **kw)
    CPU_SECONDS[0] = time.process_time() - cpu
    return values, time.perf_counter() - start


CPU_SECONDS = [0.0]  # process CPU time (both threads) of the last timed_render


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--merl-dir")
    ap.add_argument("--material", default="gold-metallic-paint")
    ap.add_argument("--glossy", default="specular-black-phenolic")
    ap.add_argument("--quick", action="store_true", help="smaller sizes, for a smoke run")
    ap.add_argument("--replot", action="store_true",
                    help="redraw the figures and markdown from results/render_speed.json")
    args = ap.parse_args()
    if args.replot:
        plot(json.loads((RESULTS / "render_speed.json").read_text()))
        return
    RESULTS.mkdir(parents=True, exist_ok=True)
    spps = [16, 64, 256, 1024]
    big, small, ref_spp = (128, 48, 2048) if args.quick else (512, 128, 8192)
    var_size = 32 if args.quick else 64
    result = {"machine": {"cpus": os.cpu_count(), "load_average": os.getloadavg(),
                          "python": platform.python_version()},
              "material": args.material, "size": big, "error_size": small,
              "reference_spp": ref_spp, "variance_size": var_size, "speed": [], "variance": {}}
    brdf = TabulatedBRDF(read_merl(table_path(args, args.material)))
    pisa = EnvMap.from_file(ENVMAPS / "pisa_latlong_256x128.hdr")

    # 1-2. speed at 512^2 and error against a converged render at the smaller size
    reference, t_ref = timed_render(small, brdf, pisa, ref_spp, seed=12345)
    for spp in spps:
        small_img, small_s = timed_render(small, brdf, pisa, spp)
        _, seconds = timed_render(big, brdf, pisa, spp)
        cpu = CPU_SECONDS[0]
        entry = {"spp": spp, "seconds": round(seconds, 3), "rel_rmse": rel_rmse(small_img, reference),
                 "cpu_seconds_both_threads": round(cpu, 3),
                 "seconds_error_size": round(small_s, 3)}
        result["speed"].append(entry)
        print(f"pisa {big}^2 spp {spp}: {seconds:.2f} s wall, {cpu:.2f} s CPU; rel RMSE at {small}^2 "
              f"{entry['rel_rmse']:.4f}", flush=True)

    # 3. variance against spp under very HDR maps, MIS against each strategy alone
    glossy = TabulatedBRDF(read_merl(table_path(args, args.glossy)))
    for name in ("grace_latlong_256x128", "royal_esplanade_1k"):
        env = EnvMap.from_file(ENVMAPS / f"{name}.hdr")
        for label, model in ((args.material, brdf), (args.glossy, glossy)):
            ref, _ = timed_render(var_size, model, env, ref_spp, seed=999)
            curves = {}
            for strategies in (("envmap", "brdf"), ("envmap",), ("brdf",)):
                key = "+".join(strategies)
                curves[key] = []
                for spp in spps[:3] if key != "envmap+brdf" else spps:
                    img, s = timed_render(var_size, model, env, spp, strategies=strategies)
                    curves[key].append({"spp": spp, "rel_rmse": rel_rmse(img, ref),
                                        "seconds": round(s, 3)})
            result["variance"][f"{name}/{label}"] = curves
            print(name, label, {k: [round(e["rel_rmse"], 4) for e in v]
                                for k, v in curves.items()}, flush=True)

    (RESULTS / "render_speed.json").write_text(json.dumps(result, indent=1) + "\n")
    plot(result)


def markdown(result):
    m = result["machine"]
    lines = ["# Render speed and convergence (benchmarks/render_speed.py)", "",
             f"{m['cpus']} CPUs, load average at start {m['load_average'][0]:.1f} (the machine is "
             "shared: wall times are inflated, CPU time is the sum over both threads).", "",
             f"## {result['size']}^2 sphere, pisa, {result['material']} (3D table), MIS", "",
             "| spp | wall s | CPU s | rel. RMSE vs converged |", "|---|---|---|---|"]
    for e in result["speed"]:
        lines.append(f"| {e['spp']} | {e['seconds']:.1f} | {e.get('cpu_seconds_both_threads', 0):.1f}"
                     f" | {e['rel_rmse']:.4f} |")
    lines += ["", f"Error measured at {result['error_size']}^2 against {result['reference_spp']} "
              "spp.", "", f"## Variance against spp ({result['variance_size']}^2, rel. RMSE vs "
              f"{result['reference_spp']} spp)", "", "| map / material | strategy | " +
              " | ".join(str(s) for s in (16, 64, 256, 1024)) + " |", "|---|---|---|---|---|---|"]
    for key, curves in result["variance"].items():
        for strategy, curve in curves.items():
            cells = [f"{e['rel_rmse']:.4f}" for e in curve] + ["-"] * (4 - len(curve))
            lines.append(f"| {key} | {strategy} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def plot(result):
    (RESULTS / "render_speed.md").write_text(markdown(result))
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(5, 4))
    t = [e["seconds"] for e in result["speed"]]
    err = [e["rel_rmse"] for e in result["speed"]]
    ax.loglog(t, err, "o-")
    for e in result["speed"]:
        ax.annotate(f"{e['spp']} spp", (e["seconds"], e["rel_rmse"]), textcoords="offset points",
                    xytext=(5, 5))
    ax.set_xlabel(f"render time, {result['size']}$^2$ sphere (s)")
    ax.set_ylabel("relative RMSE vs converged")
    ax.set_title(f"pisa, {result['material']} (MIS)")
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(RESULTS / "render_speed.png", dpi=100)
    plt.close(fig)

    keys = list(result["variance"])
    fig, axes = plt.subplots(1, len(keys), figsize=(4 * len(keys), 3.6), squeeze=False)
    for ax, key in zip(axes[0], keys):
        for strategy, curve in result["variance"][key].items():
            ax.loglog([e["spp"] for e in curve], [e["rel_rmse"] for e in curve], "o-",
                      label=strategy)
        s = np.array([16, 1024])
        first = result["variance"][key]["envmap+brdf"][0]["rel_rmse"]
        ax.loglog(s, first * np.sqrt(16 / s), "k:", label="$N^{-1/2}$")
        ax.set_title(key.replace("_latlong_256x128", "").replace("_1k", ""), fontsize=9)
        ax.set_xlabel("spp")
        ax.grid(True, which="both", alpha=0.3)
    axes[0][0].set_ylabel("relative RMSE")
    axes[0][0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(RESULTS / "render_variance.png", dpi=100)
    plt.close(fig)


if __name__ == "__main__":
    main()
