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



@pytest.mark.slow
def test_evaluate_quick_workers_runs_the_3d_phase_too(merl_proxy, tmp_path):
    """`evaluate --quick --workers 2` (worker processes, as a user runs it) runs the 3D phase
    right after the 2D one and scatters the same data again: with content-hashed keys the second
    scatter took the first's key, whose release then dropped it under the 3D tasks ("lost
    dependencies", exit 1 every time). The experiment's 3D metrics must come out whole."""
    from flashbrdf.cli.main import main
    folder = tmp_path / "merl"
    folder.mkdir()
    for p in merl_proxy(*QUICK):
        shutil.copy(p, folder / p.name)
    assert main(["evaluate", "--merl-dir", str(folder), "--out", str(tmp_path / "out"),
                 "--quick", "--workers", "2"]) == 0
    experiment = json.loads((tmp_path / "out" / "table1.json").read_text())["per_experiment"][0]
    per_material = experiment["errors_3d"]["dsgplvm"]          # one per test table
    assert len(per_material) == len(experiment["test"]) > 0
    assert all(np.isfinite(m["lab_log"]) and m["lab_log"] > 0 for m in per_material)
