"""The report's figures (matplotlib, Agg): each function writes one PNG atomically and returns nothing.

Units: BRDF values rho in 1/sr; images linear RGB in the photos' pixel units; Delta E in CIE76 units
of log-CIELAB (see pipeline/report.py for what the numbers mean).
"""

import numpy as np

from flashbrdf.files.atomic import atomic_path
from flashbrdf.brdf.colour import srgb_encode
from flashbrdf.pipeline.report_data import downsample, uniform_value

CHANNELS = ("R", "G", "B")
CHANNEL_COLOURS = ("tab:red", "tab:green", "tab:blue")
_METHOD_STYLES = ("-", "--", "-.", ":")


def _pyplot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _save(fig, path):
    plt = _pyplot()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=90, bbox_inches="tight", format="png")
    plt.close(fig)


def slice_plot(path, theta_h_deg, observed, predictions):
    """Observed flash-slice bins (error bars = spread) and each method's theta_d = 0 curve, log axis.

    theta_h_deg: (90,). observed: {"rho": (90,3), "n": (90,), "spread": (90,3) or None} or None.
    predictions: {method: (90,3) theta_d = 0 curve in 1/sr}.
    """
    plt = _pyplot()
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.8), sharey=True)
    for c, ax in enumerate(axes):
        if observed is not None:
            rho, n = observed["rho"][:, c], observed["n"]
            ok = np.isfinite(rho) & (rho > 0) & (n > 0)
            spread = observed.get("spread")
            err = None if spread is None else np.minimum(np.nan_to_num(spread[ok, c]), rho[ok] * 0.999)
            ax.errorbar(theta_h_deg[ok], rho[ok], yerr=err, fmt="o", ms=3, color="k", lw=0.8,
                        capsize=1.5, label="observed (flash photo)")
        for m, (method, curve) in enumerate(predictions.items()):
            y = np.where(curve[:, c] > 0, curve[:, c], np.nan)
            ax.plot(theta_h_deg, y, _METHOD_STYLES[m % 4], color=f"C{m % 10}", lw=1.3,
                    label=f"{method}: predicted θd = 0")
        ax.set_yscale("log")
        ax.set_xlabel("θh (degrees)")
        ax.set_title(f"{CHANNELS[c]} channel", color=CHANNEL_COLOURS[c])
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_ylabel("ρ (1/sr)")
    axes[0].legend(fontsize=7, loc="best")
    _save(fig, path)


def brdf_images(path, method, table_2d, uncertainty=None, uncertainty_label="uncertainty"):
    """The 2D BRDF as theta_h x theta_d images per channel (log10 rho), uncertainty beside them.

    table_2d: (90,90,3) 1/sr [theta_h, theta_d, RGB]; uncertainty: (90,90,3) or (90,90) or None.
    """
    plt = _pyplot()
    unc = None if uncertainty is None else np.asarray(uncertainty, dtype=float)
    if unc is not None:
        unc = np.repeat(unc[..., None], 3, axis=2) if unc.ndim == 2 else unc
        values = unc[np.isfinite(unc)]
        if not values.size:
            unc = None
        elif uniform_value(values) is not None:  # one number in every bin: said, not painted
            unc = uniform_value(values)
    cols = 3 if unc is None else (4 if isinstance(unc, float) else 6)
    fig, axes = plt.subplots(1, cols, figsize=(2.7 * cols, 3.0))
    log_rho = np.log10(np.where(table_2d > 0, table_2d, np.nan))
    finite = log_rho[np.isfinite(log_rho)]
    lo, hi = (np.percentile(finite, [1, 99.5]) if finite.size else (-3, 1))
    extent = (0, 90, 90, 0)  # theta_d along x, theta_h down the image (both in degrees)
    for c in range(3):
        im = axes[c].imshow(log_rho[:, :, c], vmin=lo, vmax=hi, cmap="magma", extent=extent,
                            aspect="auto")
        axes[c].set_title(f"{method}: log10 ρ {CHANNELS[c]}", fontsize=9)
    fig.colorbar(im, ax=axes[:3].tolist(), shrink=0.8, label="log10 ρ (1/sr)")
    # Uncertainty in the feature space has CIELAB channels, not RGB ones.
    names = ("L*", "a*", "b*") if "CIELAB" in uncertainty_label else CHANNELS
    if isinstance(unc, float):
        axes[3].axis("off")
        axes[3].text(0.0, 0.5, f"{uncertainty_label}:\n{unc:.3g} in every bin and channel\n"
                     f"(std {np.sqrt(max(unc, 0.0)):.3g})", fontsize=8, va="center", wrap=True)
        axes = axes[:3]
    elif unc is not None:
        top = np.nanpercentile(unc, 99)
        for c in range(3):
            im = axes[3 + c].imshow(unc[:, :, c], vmin=0, vmax=top, cmap="viridis", extent=extent,
                                    aspect="auto")
            axes[3 + c].set_title(f"variance {names[c]}", fontsize=9)
        fig.colorbar(im, ax=axes[3:].tolist(), shrink=0.8, label=uncertainty_label)
    # Rows are MERL's square-root-spaced theta_h bins: label them in degrees where they fall.
    theta_ticks = np.array([0, 2, 5, 10, 20, 40, 60, 90])
    for ax in axes:
        ax.set_xlabel("θd (deg)", fontsize=8)
        ax.set_yticks(90 * np.sqrt(theta_ticks / 90), [str(t) for t in theta_ticks], fontsize=7)
    axes[0].set_ylabel("θh (deg; MERL's square-root spacing)", fontsize=8)
    _save(fig, path)


def tone_map(image, scale):
    """Linear RGB -> displayable sRGB-encoded [0,1]: times `scale`, clipped, sRGB curve; NaN -> 0.
    render.images.tonemap (the PNG previews) rolls highlights off softly instead; the report keeps
    its hard clip, so its figures stay as they were. Both share brdf.colour.srgb_encode."""
    return srgb_encode(np.clip(np.nan_to_num(np.asarray(image, np.float32) * np.float32(scale)),
                               0.0, 1.0))


def exposure_for(reference):
    """The scale that maps the 99th percentile of a linear image's lit pixels to 1 (display only)."""
    lit = np.asarray(reference, float)
    lit = lit[np.isfinite(lit) & (lit > 0)]
    return 1.0 / np.percentile(lit, 99) if lit.size else 1.0


FIGURE_MAX_SIDE = 1024  # pixels of an image shown in a figure panel, at most


def reference_figure(path, photo, reference, renders, delta_e_maps, delta_e_means, vmax=None):
    """Reference photo and each method's render (one shared exposure), Delta E maps below.

    reference: (H,W,3) linear or None; renders: {method: (H,W,3) linear or None};
    delta_e_maps: {method: (H,W) Delta E, or (H,W,3) an already false-coloured image, or None};
    delta_e_means: {method: float}.
    """
    plt = _pyplot()
    crop = _object_box([m for m in delta_e_maps.values() if m is not None and np.ndim(m) == 2])
    if crop is not None:  # show the object, not a mostly empty frame
        reference = None if reference is None else reference[crop]
        renders = {k: (None if r is None else r[crop]) for k, r in renders.items()}
        delta_e_maps = {k: (None if m is None else m[crop]) for k, m in delta_e_maps.items()}
    # a panel is a few hundred pixels wide: block-averaged first (24 MP images tone-mapped in
    # float64 made the report's memory peak, 2 GB a panel)
    side = max((max(np.shape(i)[:2]) for i in [reference, *renders.values(),
                                              *delta_e_maps.values()] if i is not None),
               default=1)
    factor = -(-side // FIGURE_MAX_SIDE)
    if factor > 1:
        reference, renders, delta_e_maps = (
            None if reference is None else downsample(reference, factor),
            {k: None if r is None else downsample(r, factor) for k, r in renders.items()},
            {k: None if m is None else (downsample(m, factor) if np.ndim(m) == 2
                                        else np.asarray(m)[::factor, ::factor])
             for k, m in delta_e_maps.items()})
    methods = list(renders)
    # Top row: the reference, then each method's render; bottom row: each method's Delta E map.
    fig, axes = plt.subplots(2, 1 + len(methods), figsize=(2.6 * (1 + len(methods)), 5.4),
                             squeeze=False)
    scale = exposure_for(reference) if reference is not None else \
        exposure_for(next((r for r in renders.values() if r is not None), np.ones(1)))
    if vmax is None:
        maps = [m for m in delta_e_maps.values() if m is not None and np.ndim(m) == 2]
        finite = np.concatenate([m[np.isfinite(m)].ravel() for m in maps]) if maps else np.zeros(1)
        vmax = max(5.0, float(np.percentile(finite, 99))) if finite.size else 5.0
    _show(axes[0, 0], None if reference is None else tone_map(reference, scale), f"{photo}: reference")
    axes[1, 0].axis("off")
    axes[1, 0].text(0.5, 0.5, "per-pixel ΔE log\n(render vs reference)", ha="center",
                    va="center", fontsize=9, transform=axes[1, 0].transAxes)
    image = None
    for m, method in enumerate(methods, start=1):
        render = renders[method]
        _show(axes[0, m], None if render is None else tone_map(render, scale), f"{method}: render")
        de = delta_e_maps.get(method)
        title = f"{method}: mean ΔE {delta_e_means.get(method, float('nan')):.2f}"
        if de is not None and np.ndim(de) == 2:
            image = axes[1, m].imshow(np.where(np.isfinite(de), de, np.nan), cmap="inferno",
                                      vmin=0, vmax=vmax)
            axes[1, m].set_title(title, fontsize=8)
            axes[1, m].axis("off")
        else:
            _show(axes[1, m], de, title)
    if image is not None:
        fig.colorbar(image, ax=axes[1].tolist(), shrink=0.8, label="ΔE log (CIE76)")
    _save(fig, path)


def _object_box(maps, margin=0.1):
    """Slices of the bounding box (plus a margin) of the pixels measured in any Delta E map."""
    if not maps or any(m.shape != maps[0].shape for m in maps):
        return None
    measured = np.any([np.isfinite(m) for m in maps], axis=0)
    if not measured.any() or measured.mean() > 0.5:
        return None
    rows, cols = np.nonzero(measured.any(1))[0], np.nonzero(measured.any(0))[0]
    pad = int(margin * max(rows[-1] - rows[0], cols[-1] - cols[0])) + 2
    return (slice(max(rows[0] - pad, 0), rows[-1] + pad + 1),
            slice(max(cols[0] - pad, 0), cols[-1] + pad + 1))


def _show(ax, image, title):
    ax.axis("off")
    ax.set_title(title, fontsize=8)
    if image is None:
        ax.text(0.5, 0.5, "not available", ha="center", va="center", transform=ax.transAxes)
    else:
        ax.imshow(np.clip(image, 0, 1) if np.asarray(image).dtype.kind == "f" else image)


def error_plot(path, rows, x_key=None, x_label="reference photo"):
    """Delta E log mean per reference, one marker series per method (x = `x_key` when given)."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(8, 3.5))
    methods = list(dict.fromkeys(r["method"] for r in rows))
    photos = list(dict.fromkeys(r["photo"] for r in rows))
    for m, method in enumerate(methods):
        mine = [r for r in rows if r["method"] == method]
        xs = [r[x_key] if x_key else photos.index(r["photo"]) for r in mine]
        ax.plot(xs, [r["delta_e_log_mean"] for r in mine], "o" if x_key else "o-", ms=3,
                label=method, alpha=0.8)
    if not x_key and len(photos) <= 30:
        ax.set_xticks(range(len(photos)), photos, rotation=60, fontsize=7)
    ax.set_xlabel(x_label)
    ax.set_ylabel("ΔE log mean")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    _save(fig, path)


def label_map(path, labels):
    """A material label image (H, W) int (0 = not the object) in distinct colours, with a key."""
    plt = _pyplot()
    from matplotlib.colors import ListedColormap
    k = int(labels.max())
    colours = ["#000000"] + [plt.get_cmap("tab10")(j % 10) for j in range(k)]
    fig, ax = plt.subplots(figsize=(5, 5 * labels.shape[0] / max(labels.shape[1], 1) + 0.4))
    # a 5-inch figure at 90 dpi shows ~450 px: imshow of a 24 MP label image made a float64
    # RGBA copy of every pixel (0.75 GB) and resampled it; every step-th pixel (nearest) first
    step = max(1, max(labels.shape[:2]) // 1500)
    labels = labels[::step, ::step]
    ax.imshow(labels, cmap=ListedColormap(colours), vmin=-0.5, vmax=k + 0.5,
              interpolation="nearest")
    ax.set_axis_off()
    handles = [plt.Rectangle((0, 0), 1, 1, color=colours[j]) for j in range(1, k + 1)]
    ax.legend(handles, [f"material {j}" for j in range(1, k + 1)], fontsize=7, loc="upper right")
    _save(fig, path)
