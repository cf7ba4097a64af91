"""The paper's Table 2: spheres under environment maps, each method's BRDF against the truth.

For every material and map, a unit sphere (render_sphere) is rendered with the ground-truth table
and with each method's prediction, with the same seed (common random numbers: the envmap samples
coincide, so the difference reflects the BRDFs more than the noise). The score of one render is
`delta_e_log_mean` over the sphere pixels (compare_images); the table reports its mean and median
across materials, per map and over all maps.
"""

import json
import os
import time
from pathlib import Path

import matplotlib
import numpy as np
from tqdm import tqdm

from flashbrdf.files.atomic import atomic_path, write_text
from flashbrdf.files.errors import InputError
from flashbrdf.brdf.merl import list_merl, read_merl
from flashbrdf.render.compare import compare_images
from flashbrdf.render.envmap import EnvMap, default_envmaps
from flashbrdf.render.images import tonemap
from flashbrdf.render.scene_render import render_sphere, sphere_view

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (after choosing the file-only backend)

METHODS = ("dsgplvm", "dsgplvm-paper", "pca", "noll", "chandraker", "ashikhmin", "oracle")


def table2(merl_dir, out_dir, predict, names=None, methods=METHODS, envmaps=None, size=128,
           spp=64, seed=0, figure_materials=3, progress=True):
    """Render Table 2 and write OUT_DIR/table2.json, table2.md and table2.png.

    predict(name, method) -> (90, 90, 180, 3) or (90, 90, 3) table in 1/sr, or None to skip.
    names: materials (default every *.binary in merl_dir), their truth read from merl_dir.
    Returns the result dict (also in table2.json).
    """
    tables = dict(list_merl(merl_dir))
    names = list(tables) if names is None else list(names)
    unknown = [n for n in names if n not in tables]
    if unknown:
        raise InputError(merl_dir, f"no table for material {unknown[0]!r}")
    if envmaps:
        envmap_paths = [Path(p) for p in envmaps]
        maps = {p.stem.split("_latlong")[0]: EnvMap.from_file(p) for p in envmap_paths}
    else:  # the project's own maps, made in code
        maps = {name: EnvMap(pixels) for name, pixels in default_envmaps().items()}
        envmap_paths = [f"procedural:{name}" for name in maps]
    mask = sphere_view(size)[0]
    scores = {m: {e: {} for e in maps} for m in methods}
    shown = {}
    start = time.perf_counter()
    iterator = names
    if progress:
        iterator = tqdm(names, desc="Table 2", unit="material", disable=None)
    for k, name in enumerate(iterator):
        truth = read_merl(tables[name])
        predictions = {m: predict(name, m) for m in methods}
        for env_name, env in maps.items():
            ref = render_sphere(truth, env, size=size, spp=spp, seed=seed)
            for method, table in predictions.items():
                if table is None:
                    continue
                image = render_sphere(np.asarray(table), env, size=size, spp=spp, seed=seed)
                metrics, delta_e = compare_images(image, ref, mask)
                scores[method][env_name][name] = metrics["delta_e_log_mean"]
                if k < figure_materials and env_name == next(iter(maps)):
                    shown.setdefault(name, {"truth": ref})[method] = (image, delta_e)
    result = {"size": size, "spp": spp, "seed": seed, "materials": names,
              "envmaps": [str(p) for p in envmap_paths], "envmap_names": list(maps),
              "seconds": time.perf_counter() - start,
              "per_material": scores, "summary": _summary(scores)}
    os.makedirs(out_dir, exist_ok=True)
    write_text(os.path.join(out_dir, "table2.json"), json.dumps(result, indent=1) + "\n")
    write_text(os.path.join(out_dir, "table2.md"), _markdown(result))
    if shown:
        present = [m for m in methods if any(m in entry for entry in shown.values())]
        _figure(os.path.join(out_dir, "table2.png"), shown, present, mask, next(iter(maps)))
    return result


def _summary(scores):
    out = {}
    for method, per_env in scores.items():
        entry = {}
        every = []
        for env_name, values in per_env.items():
            v = np.array([x for x in values.values() if x is not None], dtype=float)
            every.extend(v.tolist())
            entry[env_name] = ({"mean": float(v.mean()), "median": float(np.median(v))}
                               if v.size else None)
        entry["all"] = ({"mean": float(np.mean(every)), "median": float(np.median(every))}
                        if every else None)
        out[method] = entry
    return out


def _markdown(result):
    envs = list(result["envmap_names"]) + ["all"]   # the summary's keys (a path's stem or sky)
    lines = ["# Table 2: render error (log-CIELAB Delta E*ab, mean over sphere pixels)", "",
             f"{len(result['materials'])} materials; {result['size']}^2 sphere, "
             f"{result['spp']} spp, seed {result['seed']}; mean / median across materials.", "",
             "dsgplvm is what `flashbrdf infer` does (slice anchoring, feature space picked on "
             "validation); dsgplvm-paper is the paper's DS-GPLVM (docs/methods.md lists its "
             "departures).", "",
             "| method | " + " | ".join(envs) + " |", "|---|" + "---|" * len(envs)]
    for method, entry in result["summary"].items():
        cells = [f"{entry[e]['mean']:.3f} / {entry[e]['median']:.3f}" if entry.get(e) else "n/a"
                 for e in envs]
        lines.append(f"| {method} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def _figure(path, shown, methods, mask, env_name):
    """Truth, each method and its Delta E map, a row pair per material."""
    cols = 1 + len(methods)
    fig, axes = plt.subplots(2 * len(shown), cols, figsize=(1.6 * cols, 3.4 * len(shown)),
                             squeeze=False)
    im = None
    for r, (name, entry) in enumerate(shown.items()):
        exposure = None
        lum = entry["truth"][mask] @ np.array([0.2126, 0.7152, 0.0722])
        if np.any(lum > 0):
            exposure = 1.0 / np.percentile(lum[lum > 0], 99)
        axes[2 * r][0].imshow(tonemap(entry["truth"], exposure))
        axes[2 * r][0].set_title(f"{name}\ntruth ({env_name})", fontsize=7)
        for c, method in enumerate(methods, start=1):
            if method in entry:
                image, delta_e = entry[method]
                axes[2 * r][c].imshow(tonemap(image, exposure))
                im = axes[2 * r + 1][c].imshow(np.ma.masked_invalid(delta_e), cmap="inferno",
                                               vmin=0, vmax=10)
                axes[2 * r][c].set_title(method, fontsize=7)
        for ax in axes[2 * r].tolist() + axes[2 * r + 1].tolist():
            ax.set_axis_off()
    if im is not None:
        # from every column alike: taken from the last alone, it drew that method smaller
        fig.colorbar(im, ax=axes.ravel().tolist(), fraction=0.05, label="$\\Delta E^*_{ab}$ (log)")
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=100)
    plt.close(fig)
