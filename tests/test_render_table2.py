"""experiments.table2 (Table 2 of the paper): scores and files on a tiny run."""

import json

import numpy as np
import pytest

from flashbrdf.brdf.merl import read_merl
from flashbrdf.experiments.table2 import table2
from flashbrdf.render.images import write_exr


def test_table2_scores_truth_zero_and_errors_positive(tmp_path, merl_proxy):
    paths = merl_proxy("blue-acrylic", "gold-metallic-paint")
    names = [p.stem for p in paths]
    rng = np.random.default_rng(0)
    env = tmp_path / "sky_latlong.exr"
    write_exr(env, (rng.random((16, 32, 3)) * 4).astype(np.float32))

    def predict(name, method):
        truth = read_merl(paths[names.index(name)])
        return {"oracle": truth, "pca": truth * 1.5}.get(method)

    out = tmp_path / "out"
    result = table2(paths[0].parent, out, predict, names=names, methods=("oracle", "pca", "noll"),
                    envmaps=[env], size=24, spp=8, progress=False)
    summary = result["summary"]
    # same table, same seed: the very same render (common random numbers), Delta E = 0
    assert summary["oracle"]["all"]["mean"] == 0.0
    # 1.5 x the BRDF is 1.5 x every pixel: a clear, nonzero log-Lab difference
    assert summary["pca"]["all"]["mean"] > 0.5
    assert summary["noll"]["all"] is None
    saved = json.loads((out / "table2.json").read_text())
    assert saved["summary"] == summary
    assert set(saved["per_material"]["pca"]["sky"]) == set(names)
    assert (out / "table2.md").read_text().count("|") > 10 and (out / "table2.png").is_file()


def test_table2_figure_draws_every_method_the_same_size(tmp_path, merl_proxy, monkeypatch):
    """The ΔE colour bar takes its room from every column alike: taken from the last column
    alone, it drew the last method's images ~0.7x as wide as the others'."""
    import matplotlib.pyplot as plt
    figures = []
    monkeypatch.setattr(plt, "close", figures.append)
    path = merl_proxy("blue-acrylic")
    truth = read_merl(path)
    table2(path.parent, tmp_path / "out", lambda name, m: truth * 2.0, names=[path.stem],
           methods=("pca", "noll"), size=8, spp=1, progress=False)
    axes = figures[0].axes[:-1]                                 # the last one is the colour bar
    widths = [ax.get_position().width for ax in axes]
    assert len(axes) == 6 and max(widths) == pytest.approx(min(widths), rel=1e-6)


def test_table2_without_envmaps_renders_the_maps_made_in_code(tmp_path, merl_proxy):
    """No envmaps: Table 2 renders under render.envmap.default_envmaps, named as such."""
    path = merl_proxy("blue-acrylic")
    paths = [path]
    truth = read_merl(path)
    result = table2(paths[0].parent, tmp_path / "out", lambda name, m: truth * 2.0,
                    names=[paths[0].stem], methods=("pca",), size=16, spp=4, progress=False)
    assert result["envmaps"] == ["procedural:sky", "procedural:studio"]
    # 2 x the BRDF is 2 x every pixel under any map: a clear log-Lab error under both
    assert all(result["per_material"]["pca"][e][paths[0].stem] > 0.5 for e in ("sky", "studio"))
    # table2.md shows each map's column, as table2.json holds it (it showed n/a under both)
    row = next(line for line in (tmp_path / "out" / "table2.md").read_text().splitlines()
               if line.startswith("| pca"))
    sky, studio = (result["summary"]["pca"][e]["mean"] for e in ("sky", "studio"))
    assert "n/a" not in row and f"{sky:.3f}" in row and f"{studio:.3f}" in row
