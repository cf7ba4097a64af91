"""`evaluate` on Dask: the Table 1 experiments as tasks give the sequential run's numbers.

Two --quick experiments (2D metrics; the 3D phase's tasks are left to the benchmark, to keep this
test short) on the 12 proxy tables of test_infer_cli, once in a loop and once on two single-thread
Dask workers. The workers are threads
of this process (processes=False) so that the test can switch off the tracemalloc peak of
experiment 0 in both runs (it makes that experiment ten times slower and measures only memory);
`flashbrdf batch`'s tests cover worker processes. Every error must agree to 1e-9 relative (the
same code on the same inputs; only the BLAS thread count differs, which can change the last bits
of a sum), and every hyperparameter choice exactly.
"""

import json
import shutil

import numpy as np
import pytest
from distributed import Client, LocalCluster

from flashbrdf.experiments import evaluate
from flashbrdf.experiments.table1_files import json_leaves
from test_infer_cli import QUICK




@pytest.mark.slow
def test_experiments_on_dask_equal_the_loop(merl_proxy, tmp_path, monkeypatch):
    folder = tmp_path / "merl"
    folder.mkdir()
    for p in merl_proxy(*QUICK):
        shutil.copy(p, folder / p.name)
    monkeypatch.setattr(evaluate, "_measure", lambda fn: (fn(), 0.0, None))
    options = dict(quick=True, experiments=2, experiments_3d=0)
    evaluate.run_evaluation(folder, tmp_path / "loop", **options)
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                      dashboard_address=None) as cluster, Client(cluster) as client:
        evaluate.run_evaluation(folder, tmp_path / "dask", client=client, **options)
    loop, dask = (json.loads((tmp_path / d / "table1.json").read_text()) for d in ("loop", "dask"))
    assert len(loop["per_experiment"]) == 2 and len(loop["ablations"]) >= 5
    for key in ("summary", "per_experiment", "hyperparameters", "ablations", "mean_performing"):
        want, got = json_leaves(loop[key]), json_leaves(dask[key])
        assert got.keys() == want.keys(), key
        for path, value in want.items():
            if isinstance(value, float):
                assert got[path] == pytest.approx(value, rel=1e-9, abs=1e-12), path
            else:
                assert got[path] == value, path
    assert np.isfinite(dask["summary"]["2d"]["dsgplvm"]["lab_log"]["mean"])
