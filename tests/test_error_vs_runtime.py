"""experiments/runtime_plot.py (evaluate's and benchmarks/error_vs_runtime.py's figure): the label column
never overlaps, on crowded synthetic points."""

import numpy as np
from matplotlib.text import Text

import flashbrdf.experiments.runtime_plot as evr


def test_spread_keeps_order_pitch_and_range():
    wanted = np.array([0.5, 0.5, 0.51, 0.2, 0.98, 0.99, 1.0])
    placed = evr.spread(wanted, 0.05, 0.0, 1.0)
    order = np.argsort(wanted, kind="stable")
    assert (np.diff(placed[order]) >= 0.05 - 1e-12).all()       # sorted, one pitch apart
    assert placed.min() >= 0.0 and placed.max() <= 1.0           # 7 x 0.05 fits in [0, 1]
    assert placed[3] == 0.2                                      # an isolated label stays put
    too_many = evr.spread(np.zeros(30), 0.05, 0.0, 1.0)          # 30 x 0.05 does not fit
    assert np.allclose(np.diff(np.sort(too_many)), 0.05)


def test_crowded_points_get_labels_that_do_not_overlap():
    rng = np.random.default_rng(1)
    # 30 settings of one grid and a few methods, all within 3 ms and 1 error unit of each other.
    merl = [{"label": f"pca n_components={k},ridge={r}", "method": "pca",
             "x": 2.8 + 0.01 * i, "y": 5.0 + rng.uniform(0, 1)}
            for i, (k, r) in enumerate((k, r) for k in (3, 6, 12, 24, None)
                                       for r in (1e-3, 1e-2, 0.1, 1.0, 10.0, 100.0))]
    merl += [{"label": m, "method": m, "x": 3.0, "y": 5.5 + 0.01 * i}
             for i, m in enumerate(("dsgplvm", "noll", "chandraker", "ashikhmin", "oracle"))]
    ood = ([{"label": m, "method": m, "x": 3.0 + 0.001 * i, "y": 12.0 + 0.001 * i}
             for i, m in enumerate(("dsgplvm", "pca", "noll", "chandraker", "ashikhmin"))],
           {"pca": 11.0}, "test")
    for p in merl:
        p["labelled"] = True                   # every label drawn: the hardest case
    fig = evr.make_figure(merl, "synthetic", ood, note="test")
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    for ax in fig.axes:
        # the text's own box (an Annotation's extent also spans its leader line)
        boxes = [Text.get_window_extent(t, renderer) for t in ax.texts]
        assert len(boxes) == (35 if ax is fig.axes[0] else 5)
        for i in range(len(boxes)):
            for j in range(i + 1, len(boxes)):
                assert not boxes[i].overlaps(boxes[j]), (ax.texts[i].get_text(),
                                                         ax.texts[j].get_text())
    evr.plt.close(fig)
