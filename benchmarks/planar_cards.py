"""Real-photo validation on flash-planar-cards-blue: infer from one phone-flash view, predict 8 others.

    python -m benchmarks.planar_cards [--flash-view 0] [--model MODEL.npz]
        [--merl-dir /work/merl] [--methods dsgplvm,pca,noll,chandraker,ashikhmin] [--work DIR]

The capture is written as 9 per-view scene folders (benchmarks/planar_scenes.py: exact pinhole cameras for
the rectified photos, flash = point light at the lens). The flash view is extracted and inferred
(`extract`, `infer` per method); every other view is rendered (`render`) and compared with its photo.
The cards are printed in several materials (gold foil, teal foil, grey felt), so one BRDF cannot
fit them all: the benchmark clusters the pixels by colour, extracts one slice per cluster, and
reports the error per cluster, to show where the single-BRDF assumption breaks.
Writes benchmarks/results/planar_cards.{json,md,png}; where extract or render is not built yet,
the benchmark's own direct implementation of the contract pixel model stands in (and says so).
"""

import json
import sys
import time
from pathlib import Path

import numpy as np

from benchmarks._real_common import (RESULTS, argument_parser, direct_extract,
                                     direct_render, infer_all, resolve_model, run_cli,
                                     theta_h_deg, write_json)

N_CLUSTERS = 3


def _geometry(scene):
    """Per-pixel (wi = wo, normal, I/r^2) for a view: all (N,3), from the scene's own camera."""
    from benchmarks.planar_scenes import plane_point_from_pixel
    cam = scene["camera"]
    pose = np.array(cam["world_from_camera"])
    lens = pose[:3, 3]
    v, u = np.mgrid[0:cam["height"], 0:cam["width"]]
    side = cam["width"] * lens[2] / cam["fx"]
    points = plane_point_from_pixel(u.ravel(), v.ravel(), side, cam["width"], cam["height"])
    light = scene["photos"][0]["light"]
    light_world = pose[:3, :3] @ np.array(light["position"]) + lens
    to_light, to_lens = light_world - points, lens - points
    r2 = np.einsum("ij,ij->i", to_light, to_light)
    wi = to_light / np.sqrt(r2)[:, None]
    wo = to_lens / np.linalg.norm(to_lens, axis=1, keepdims=True)
    factor = np.asarray(light["intensity_rgb"])[None, :] / r2[:, None]
    return wi, wo, np.broadcast_to([0.0, 0.0, 1.0], points.shape), factor


def _photo(view):
    from flashbrdf.pipeline.report import read_image
    scene = json.loads((view / "scene.json").read_text())
    return scene, read_image(view / scene["photos"][0]["file"])


def _clusters(views):
    """Material labels (H*W,) from the median chromaticity over all views (robust to highlights)."""
    import cv2
    chroma = []
    for view in views:
        _, image = _photo(view)
        flat = np.nan_to_num(image.reshape(-1, 3), nan=1.0)
        chroma.append(flat / np.maximum(flat.sum(1, keepdims=True), 1e-6))
    features = np.median(np.stack(chroma), axis=0)[:, :2].astype(np.float32)
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 50, 1e-4)
    cv2.setRNGSeed(0)
    _, labels, centres = cv2.kmeans(features, N_CLUSTERS, None, criteria, 3, cv2.KMEANS_PP_CENTERS)
    return labels.ravel(), centres


def _fitted_scale(render, photo):
    """exp(median log(photo / render)) over pixels where both are positive: a robust per-view gain."""
    r, p = np.nansum(render, axis=2), np.nansum(photo, axis=2)
    ok = (r > 0) & (p > 0) & np.all(np.isfinite(photo), axis=2)
    return float(np.exp(np.median(np.log(p[ok] / r[ok])))) if ok.any() else float("nan")


def _cross_view_consistency(views, labels):
    """Per cluster: each view's own flash slice (direct extraction) and the spread across views.

    If the scene description is right and each cluster were one BRDF, every view would measure the
    same rho(theta_h) per cluster; the max/min ratio across views at shared bins says how far off.
    """
    per_cluster = []
    for c in range(N_CLUSTERS):
        slices = []
        for view in views:
            scene, photo = _photo(view)
            wi, wo, normal, factor = _geometry(scene)
            m = labels == c
            slices.append(direct_extract(photo.reshape(-1, 3)[m], wi[m], wo[m], normal[m],
                                         factor[m])[0].mean(axis=1))
        slices = np.array(slices)
        shared = np.all(np.isfinite(slices) & (slices > 0), axis=0)
        ratio = slices[:, shared].max(0) / slices[:, shared].min(0)
        per_cluster.append({"label": c, "shared_bins": int(shared.sum()),
                            "max_over_min_across_views_median": float(np.median(ratio)),
                            "slices_grey": slices})
    return per_cluster


def _flat_table(rho):
    """A 2D table (90,90,3) from a slice: empty theta_h bins interpolated (ends held), copied over
    theta_d (Chandraker's assumption); the same recipe for a pooled and a per-cluster slice."""
    index = np.arange(90)
    filled = np.stack([np.interp(index, index[np.isfinite(rho[:, c])], rho[np.isfinite(rho[:, c]), c])
                       for c in range(3)], axis=1)
    return np.repeat(filled[:, None, :], 90, axis=1)


def _per_cluster_vs_pooled(views, flash_view, labels, pooled_rho, cluster_slices):
    """Delta E log per predicted view for one flat BRDF from the pooled slice against one flat BRDF
    per colour cluster (each from its own slice of the flash view): what spatial variation costs."""
    from flashbrdf.pipeline.report import image_errors
    pooled = _flat_table(pooled_rho)
    per_cluster = [_flat_table(c[0]) for c in cluster_slices]
    rows = []
    for view in views:
        if view == flash_view:
            continue
        scene, photo = _photo(view)
        geometry = _geometry(scene)
        single = direct_render(pooled, *geometry)
        several = np.zeros_like(single)
        for c, table in enumerate(per_cluster):
            m = labels == c
            several[m] = direct_render(table, *(g[m] for g in geometry))
        full = np.ones(photo.shape[:2])
        rows.append({"view": view.name,
                     "single_brdf": image_errors(single.reshape(photo.shape), photo, full)[1],
                     "one_brdf_per_cluster": image_errors(several.reshape(photo.shape), photo, full)[1]})
    return rows


def main(argv=None):
    ap = argument_parser(__doc__.splitlines()[0], "flash-planar-cards-blue", "flashbrdf_bench_planar_cards")
    ap.add_argument("--flash-view", type=int, default=0)
    args = ap.parse_args(argv)
    from flashbrdf.files.errors import InputError
    from flashbrdf.brdf.merl import read_merl
    from flashbrdf.brdf.views import read_slice_csv, write_slice_csv
    from benchmarks.planar_scenes import planar_card_scenes
    from flashbrdf.pipeline.report import image_errors
    log = lambda msg: print(msg, flush=True)  # noqa: E731
    work = args.work
    work.mkdir(parents=True, exist_ok=True)
    views = planar_card_scenes(args.data, work / "scenes")
    flash_view = views[args.flash_view]
    scene, flash_photo = _photo(flash_view)
    wi, wo, normal, factor = _geometry(scene)
    pixels = flash_photo.reshape(-1, 3)
    rc, err, seconds = run_cli(["extract", flash_view, "--out", work / "slice.csv"])
    extractor = "extract stage"
    if rc == 0:
        try:
            read_slice_csv(work / "slice.csv")
        except InputError as bad:  # the stage wrote a slice its own reader rejects
            rc, err = 1, str(bad)
    if rc != 0:
        log(f"extract stage unusable (exit {rc}: {err}): using the benchmark's direct extraction")
        extractor = f"direct (benchmark stand-in; extract stage: {err})"
        rho, n, _ = direct_extract(pixels, wi, wo, normal, factor)
        write_slice_csv(work / "slice.csv", rho, n, comments=["direct extraction (stand-in)"])
    rho, n = read_slice_csv(work / "slice.csv")
    labels, centres = _clusters(views)
    cluster_slices = [direct_extract(pixels[labels == c], wi[labels == c], wo[labels == c],
                                     normal[labels == c], factor[labels == c])
                      for c in range(N_CLUSTERS)]
    start = time.perf_counter()
    model = resolve_model(args.model, args.merl_dir, work, log)
    brdfs = infer_all(work / "slice.csv", work, args.methods.split(","), model, args.merl_dir, log)
    result = {"command": "python -m benchmarks.planar_cards " + " ".join(argv or sys.argv[1:]),
              "flash_view": flash_view.name, "extractor": extractor,
              "model": None if model is None else str(model),
              "slice_bins_observed": int((n > 0).sum()),
              "slice_theta_h_range_deg": [float(theta_h_deg()[n > 0].min()),
                                          float(theta_h_deg()[n > 0].max())],
              "clusters": [{"label": c, "pixel_fraction": float(np.mean(labels == c)),
                            "chromaticity_rg": centres[c].tolist(),
                            "slice_rho": cluster_slices[c][0], "slice_n": cluster_slices[c][1]}
                           for c in range(N_CLUSTERS)],
              "pooled_slice_rho": rho, "methods": {}, "per_view": [],
              "cross_view": _cross_view_consistency(views, labels),
              "single_vs_per_cluster": _per_cluster_vs_pooled(views, flash_view, labels, rho,
                                                              cluster_slices)}
    if not brdfs:
        result["status"] = "not run: no infer method available on this checkout"
        write_json(RESULTS / "planar_cards.json", result)
        log(result["status"])
        return 1
    result["infer_seconds"] = time.perf_counter() - start
    gallery = {}
    for method, (path, _) in brdfs.items():
        table = read_merl(path)
        out = work / f"render_{method}"
        renderer = "render stage"
        info = result["methods"].setdefault(method, {"renderer": renderer})
        for view in views:
            if view == flash_view:
                continue
            vscene, photo = _photo(view)
            rc, err, seconds = run_cli(["render", view, "--brdf", path, "--out", out / view.name])
            if rc == 0:
                from flashbrdf.pipeline.report import read_image
                render = read_image(out / view.name / Path(vscene["photos"][1]["file"]).with_suffix(".exr"))
            else:
                info["renderer"] = "direct (benchmark stand-in)"
                render = direct_render(table, *_geometry(vscene)).reshape(photo.shape)
            de, mean, median, rel, count = image_errors(render, photo, np.ones(photo.shape[:2]))
            per_cluster = {int(c): float(np.nanmean(de.ravel()[labels == c])) for c in range(N_CLUSTERS)}
            # Each phone shot has its own (unknown) exposure and the flash power is an estimate:
            # also score the render after one fitted scale per view, to separate scale from shape.
            scale = _fitted_scale(render, photo)
            _, mean_scaled, _, rel_scaled, _ = image_errors(render * scale, photo,
                                                            np.ones(photo.shape[:2]))
            result["per_view"].append({"view": view.name, "method": method, "delta_e_log_mean": mean,
                                       "delta_e_log_median": median, "rel_rmse": rel,
                                       "pixels": count, "delta_e_log_mean_per_cluster": per_cluster,
                                       "fitted_scale": scale, "delta_e_log_mean_scaled": mean_scaled,
                                       "rel_rmse_scaled": rel_scaled})
            if view == views[(args.flash_view + 1) % len(views)]:
                gallery[method] = (photo, render, de)
        mine = [r for r in result["per_view"] if r["method"] == method]
        info["delta_e_log_mean"] = float(np.mean([r["delta_e_log_mean"] for r in mine]))
        info["rel_rmse"] = float(np.mean([r["rel_rmse"] for r in mine]))
        for key in ("delta_e_log_mean_scaled", "rel_rmse_scaled", "fitted_scale"):
            info[key] = float(np.mean([r[key] for r in mine]))
        info["delta_e_log_mean_per_cluster"] = {
            c: float(np.mean([r["delta_e_log_mean_per_cluster"][c] for r in mine]))
            for c in range(N_CLUSTERS)}
        log(f"{method}: ΔE log mean {info['delta_e_log_mean']:.2f}, rel_rmse {info['rel_rmse']:.3f}")
    write_json(RESULTS / "planar_cards.json", result)
    _plot(result, labels.reshape(flash_photo.shape[:2]), gallery, RESULTS / "planar_cards.png")
    (RESULTS / "planar_cards.md").write_text(_markdown(result))
    log(f"wrote {RESULTS / 'planar_cards.md'}")
    return 0


def _ratio_note(result):
    """How far apart the per-cluster slices are: max/min of their medians over shared bins."""
    slices = np.array([c["slice_rho"] for c in result["clusters"]], float).mean(axis=2)  # (K,90)
    shared = np.all(np.isfinite(slices), axis=0)
    if not shared.any():
        return "the clusters share no θh bin"
    ratio = slices[:, shared].max(0) / np.maximum(slices[:, shared].min(0), 1e-9)
    return (f"over the {int(shared.sum())} θh bins all clusters share, the brightest cluster's ρ "
            f"is {np.median(ratio):.1f}× the darkest's (median; up to {ratio.max():.1f}×)")


def _markdown(result):
    lines = ["# Flash planar cards: infer from one phone-flash view, predict the other 8", "",
             f"Command: `{result['command']}`. Flash view {result['flash_view']} (slice from the "
             f"{result['extractor']}: {result['slice_bins_observed']} θh bins, θh "
             f"{result['slice_theta_h_range_deg'][0]:.1f}°–{result['slice_theta_h_range_deg'][1]:.1f}°"
             "). Each view is an exact pinhole at the phone's position (rectified photo), flash at "
             "the lens, photos linearised with (x/255)^2.2, light power 1500 (an estimate).", "",
             "| method | renderer | ΔE log mean over 8 views | rel_rmse | ΔE per colour cluster | "
             "after one fitted gain per view: ΔE log / rel_rmse (mean gain) |",
             "|---|---|---|---|---|---|"]
    for method, info in result["methods"].items():
        per = ", ".join(f"c{c}: {v:.2f}" for c, v in info["delta_e_log_mean_per_cluster"].items())
        lines.append(f"| {method} | {info['renderer']} | {info['delta_e_log_mean']:.2f} | "
                     f"{info['rel_rmse']:.3f} | {per} | {info['delta_e_log_mean_scaled']:.2f} / "
                     f"{info['rel_rmse_scaled']:.3f} ({info['fitted_scale']:.2f}×) |")
    lines += ["", "## Where one BRDF cannot describe this material", "",
              "The pixels fall into colour clusters (k-means on chromaticity, median over the 9 "
              "views): " + ", ".join(f"c{c['label']} {100 * c['pixel_fraction']:.0f}% (rg "
                                     f"{c['chromaticity_rg'][0]:.2f},{c['chromaticity_rg'][1]:.2f})"
                                     for c in result["clusters"]) + ". Their own flash slices "
              f"differ: {_ratio_note(result)}. A single slice averages them, so every method "
              "predicts one compromise BRDF: the per-cluster ΔE above shows which material pays.",
              "", "Is the scene description itself consistent? Each cluster's slice measured "
              "independently in each of the 9 views (same θh bins) agrees to within a factor of "
              + ", ".join(f"{c['max_over_min_across_views_median']:.1f} (c{c['label']}, "
                          f"{c['shared_bins']} bins)" for c in result["cross_view"])
              + " (median max/min across views): smaller than the spread between clusters, but "
              "not small; it is what the per-view exposure, the estimated flash power and the "
              "variation inside a cluster leave. The 'fitted gain' column removes one scale per "
              "view and barely helps: the error is the pattern, not the exposure.", "",
              "What one BRDF costs, measured directly (the benchmark's own renderer, flat-in-θd "
              "tables built the same way from the flash view's slices): ΔE log mean over the 8 "
              "predicted views is "
              f"{np.mean([r['single_brdf'] for r in result['single_vs_per_cluster']]):.2f} with one "
              "BRDF from the pooled slice and "
              f"{np.mean([r['one_brdf_per_cluster'] for r in result['single_vs_per_cluster']]):.2f} "
              f"with one BRDF per colour cluster ({N_CLUSTERS} clusters).",
              "", "## Per view", "", "| view | method | ΔE log mean | rel_rmse |", "|---|---|---|---|"]
    lines += [f"| {r['view']} | {r['method']} | {r['delta_e_log_mean']:.2f} | {r['rel_rmse']:.3f} |"
              for r in result["per_view"]]
    lines += ["", "![clusters, slices, errors and one predicted view](planar_cards.png)", ""]
    return "\n".join(lines)


def _plot(result, label_map, gallery, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from flashbrdf.pipeline.report_figures import exposure_for, tone_map
    fig, axes = plt.subplots(2, 3, figsize=(14, 8.5))
    axes[0, 0].imshow(label_map, cmap="tab10", vmin=0, vmax=9)
    axes[0, 0].set_title("colour clusters (c0, c1, c2)")
    th = theta_h_deg()
    for c in result["clusters"]:
        axes[0, 1].semilogy(th, np.array(c["slice_rho"], float).mean(1), "o", ms=2,
                            label=f"c{c['label']} ({100 * c['pixel_fraction']:.0f}%)")
    axes[0, 1].semilogy(th, np.array(result["pooled_slice_rho"], float).mean(1), "k-", label="pooled")
    axes[0, 1].set_xlabel("θh (degrees)")
    axes[0, 1].set_ylabel("ρ grey (1/sr)")
    axes[0, 1].set_title("flash slice per cluster vs pooled")
    axes[0, 1].legend(fontsize=7)
    for method in result["methods"]:
        mine = [r for r in result["per_view"] if r["method"] == method]
        axes[0, 2].plot([r["view"][-2:] for r in mine], [r["delta_e_log_mean"] for r in mine], "o-",
                        ms=3, label=method)
    axes[0, 2].set_title("ΔE log mean per predicted view")
    axes[0, 2].legend(fontsize=7)
    method = next(iter(gallery))
    photo, render, de = gallery[method]
    scale = exposure_for(photo)
    for ax, image, title in ((axes[1, 0], tone_map(photo, scale), "photo"),
                             (axes[1, 1], tone_map(render, scale), f"{method} render")):
        ax.imshow(image)
        ax.set_title(title)
        ax.axis("off")
    im = axes[1, 2].imshow(de, cmap="inferno", vmin=0, vmax=max(5, np.nanpercentile(de, 99)))
    axes[1, 2].set_title(f"ΔE log ({method})")
    axes[1, 2].axis("off")
    fig.colorbar(im, ax=axes[1, 2], shrink=0.8)
    fig.savefig(path, dpi=80, bbox_inches="tight")
    plt.close(fig)


if __name__ == "__main__":
    sys.exit(main())
