"""Error against run time, legibly: one point per method and setting, each label in a column beside
its panel, in the order of the points' errors, pushed apart to at least one line height and tied
to its point by a leader line. Deterministic, and no two labels can overlap (adjustText is not a
dependency). Used by `flashbrdf evaluate` (experiments.runtime_plot.write_runtime_plot) and
benchmarks/error_vs_runtime.py (with an out-of-distribution panel).

A point is {"label", "method", "x" (2D inference ms per slice), "y" (2D LAB-log error),
optional "labelled" (default True)}.
"""

import re
import textwrap

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import numpy as np  # noqa: E402

from flashbrdf.files.atomic import atomic_path  # noqa: E402
from flashbrdf.experiments.table1_report import DATASET, METHODS  # noqa: E402

FONT_PT = 7.0
LINE = 1.35          # label pitch in font heights: leaves a gap between neighbouring labels
AXES_IN = (3.6, 4.2)  # plot area of one panel (width, minimum height), inches
LABEL_IN = 2.1       # width of the label column, inches
GRID_LABELS = 4      # a method with more settings than this (pca's 25-setting grid) gets labels on
                     # its best settings only; the rest are small unlabelled dots, counted in a label


def short_label(label):
    """'pca n_components=12,ridge=10.0' -> 'pca k=12 ridge=10'; '…feature_space=rgb' -> '… rgb'."""
    s = label.replace("n_components=", "k=").replace("feature_space=", "").replace("beta=", "β=")
    s = re.sub(r"(\d)\.0\b", r"\1", s)
    return s.replace(",", " ")


def spread(wanted, pitch, low, high):
    """Label positions (same order as `wanted`, any units) at least `pitch` apart, each as close
    to its wanted position as the others allow, inside [low, high] when they fit.

    Sorted, then pushed up from the bottom, then pushed down from the top; if they cannot fit,
    they are centred on the range (and may pass its ends, never each other).
    """
    wanted = np.asarray(wanted, float)
    order = np.argsort(wanted, kind="stable")
    y = np.clip(wanted[order], low, high)
    for i in range(1, len(y)):
        y[i] = max(y[i], y[i - 1] + pitch)
    if len(y) and y[-1] > high:
        y[-1] = high
        for i in range(len(y) - 2, -1, -1):
            y[i] = min(y[i], y[i + 1] - pitch)
    if len(y) and y[0] < low:   # more labels than room: even pitch, centred
        y = (low + high) / 2 + pitch * (np.arange(len(y)) - (len(y) - 1) / 2)
    out = np.empty_like(y)
    out[order] = y
    return out


def colours():
    cycle = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    return dict(zip(METHODS, cycle))


def panel(ax, points, title, xlabel, medians=None):
    """Scatter `points` [{label, method, x, y}] on a log-x axis and label them in a column to the
    right of the axes with leader lines. medians: optional {label: y} drawn as open markers."""
    col = colours()
    xs = np.array([p["x"] for p in points])
    ys = np.array([p["y"] for p in points] + list((medians or {}).values()))
    ax.set_xscale("log")
    lo, hi = xs.min() / 1.6, xs.max() * 1.6
    steps = (1, 2, 3, 5) if hi / lo < 100 else (1, 3) if hi / lo < 1e3 else (1,)  # no crowding
    ticks = [m * 10.0 ** k for k in range(-3, 7) for m in steps if lo <= m * 10.0 ** k <= hi]
    ax.set_xlim(lo, hi)
    ax.xaxis.set_major_locator(matplotlib.ticker.FixedLocator(ticks))
    ax.xaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(lambda v, _: f"{v:g}"))
    ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    pad = 0.06 * (ys.max() - ys.min() or 1.0)
    ax.set_ylim(ys.min() - pad, ys.max() + pad)
    for p in points:
        c = col.get(p["method"], "0.3")
        big = p.get("labelled", True)
        ax.scatter(p["x"], p["y"], s=26 if big else 9, color=c, zorder=3 if big else 2,
                   alpha=1.0 if big else 0.45, edgecolor="white", linewidth=0.5 if big else 0)
        if medians and p["label"] in medians:
            ax.scatter(p["x"], medians[p["label"]], s=26, facecolor="none", edgecolor=c, zorder=3)
            ax.plot([p["x"]] * 2, [p["y"], medians[p["label"]]], color=c, lw=0.8, zorder=2)
    ax.set_title(title, fontsize=9)
    ax.set_xlabel(xlabel, fontsize=8)
    ax.set_ylabel("2D LAB-log error", fontsize=8)
    ax.tick_params(labelsize=7)
    ax.grid(True, which="both", alpha=0.25, lw=0.5)
    # Label column: positions in axes fraction; pitch = one label line in axes-height units.
    fig = ax.figure
    axes_h_pt = ax.get_position().height * fig.get_figheight() * 72
    pitch = LINE * FONT_PT / axes_h_pt
    to_axes = ax.transData + ax.transAxes.inverted()
    labelled = [p for p in points if p.get("labelled", True)]
    wanted = [to_axes.transform((p["x"], p["y"]))[1] for p in labelled]
    placed = spread(wanted, pitch, pitch / 2, 1 - pitch / 2)
    texts = []
    for p, y in zip(labelled, placed):
        c = col.get(p["method"], "0.3")
        texts.append(ax.annotate(short_label(p["label"]), xy=(p["x"], p["y"]), xycoords="data",
                    xytext=(1.04, y), textcoords="axes fraction", fontsize=FONT_PT, va="center",
                    color=c, annotation_clip=False,
                    arrowprops=dict(arrowstyle="-", color=c, lw=0.5, alpha=0.6,
                                    shrinkA=0, shrinkB=3)))
    return texts


def grid_points(runtime_points):
    """Panel points from Table 1's "runtime_points" [{label, method, seconds, error}]:
    [{label, method, x (ms), y, labelled}]. A method with more than GRID_LABELS settings keeps
    labels on its best GRID_LABELS - 1 and its worst; the others become small unlabelled dots."""
    points = [{"label": p["label"], "method": p["method"], "x": 1e3 * p["seconds"],
               "y": p["error"]} for p in runtime_points]
    for method in dict.fromkeys(p["method"] for p in points):
        mine = sorted((p for p in points if p["method"] == method), key=lambda p: p["y"])
        if len(mine) > GRID_LABELS:
            for p in mine[GRID_LABELS - 1:]:
                p["labelled"] = False
            worst = mine[-1]
            worst["labelled"] = True
            worst["label"] += f" (worst of {len(mine)})"
    return points


def make_figure(merl_points, dataset, ood=None, ood_label=None, note=""):
    """The figure: panel 1 from table1_points, panel 2 from ood_points' (points, medians, label)
    when given. Its height grows with the number of labels so that they fit at their pitch."""
    n_labels = max(sum(p.get("labelled", True) for p in merl_points), len(ood[0]) if ood else 0)
    axes_h = max(AXES_IN[1], n_labels * LINE * FONT_PT / 72 + 0.2)
    panels = 2 if ood else 1
    width = panels * (AXES_IN[0] + LABEL_IN + 0.7)
    height = axes_h + 1.3
    fig = plt.figure(figsize=(width, height))
    for k in range(panels):
        left = (k * (AXES_IN[0] + LABEL_IN + 0.7) + 0.6) / width
        fig.add_axes([left, 0.85 / height, AXES_IN[0] / width, axes_h / height])
    panel(fig.axes[0], merl_points, f"{dataset}: Table 1, experiment 0\n(every method and "
          "setting, on its test materials)", "2D inference time per slice (ms)")
    if ood:
        points, medians, label = ood
        panel(fig.axes[1], points, f"Out of distribution: {ood_label or label}\n(filled: mean, "
              "open: median over materials)", "2D inference time per slice (ms)", medians)
    note += (f" Small dots: a method's further settings (more than {GRID_LABELS}: its best "
             f"{GRID_LABELS - 1} and its worst are labelled).")
    fig.text(0.01, 0.01, textwrap.fill(note,
                                        int(width * 20)), fontsize=6, color="0.4")
    return fig


def write_figure(path, fig, dpi=130):
    """Save `fig` atomically (PNG by the path's extension) and close it."""
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=dpi)
    plt.close(fig)


def write_runtime_plot(path, points):
    """LAB-log 2D error against inference time; points [{label, method, seconds, error}], one per
    method and setting (labels in a column that never overlaps)."""
    write_figure(path, make_figure(grid_points(points), DATASET,
                                   note="flashbrdf evaluate (experiments/runtime_plot.py)."))
