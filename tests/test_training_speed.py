"""The speed-ups of `flashbrdf train` change no result: the validation fits in processes and the
tables read by threads give exactly what the sequential code gives, on synthetic Ashikhmin–Premože
materials (tests/test_infer_baselines.py builds them on MERL bin centres)."""

import numpy as np
import pytest

from flashbrdf.brdf import merl
from flashbrdf.infer.model_selection import tune_baselines
from flashbrdf.infer.training_set import TrainingSet
from tests.test_infer_baselines import coloured_ap_set


@pytest.fixture(scope="module")
def materials():
    return coloured_ap_set(11, [(0.08, 0.04, 0.1), (0.2, 0.5, 0.3), (0.35, 0.1, 0.02),
                               (0.5, 0.9, 0.5), (0.15, 0.2, 0.05), (0.7, 0.05, 0.8),
                               (0.25, 0.3, 0.2)])


def test_parallel_validation_fits_equal_sequential(materials):
    # the two feature spaces and the baselines' tuning in 2 processes or one after the other:
    # the same winner, κ and baseline parameters to the last bit (each fit is deterministic and
    # the DS-GPLVM's runs its BLAS on one thread)
    one = tune_baselines(materials, seed=3, workers=1)
    two = tune_baselines(materials, seed=3, workers=2)
    assert one["dsgplvm"] == two["dsgplvm"]
    assert one["pca"] == two["pca"] and one["ashikhmin"] == two["ashikhmin"]
    assert one["dsgplvm"]["calibration"] > 0


def test_the_validation_fits_are_handed_no_3d_rows_and_choose_the_same(materials, monkeypatch):
    """train --views 1d,2d,3d handed each validation worker the 3D rows, which its 2D fits never
    read (100 MERL tables: 3.2 GB in /dev/shm, over 8 GB with two workers). With 3D rows stored
    (a stand-in array here) tune_baselines chooses what it chooses without them, and no task
    receives them."""
    from dataclasses import replace
    import flashbrdf.infer.model_selection as selection
    handed, real_run = [], selection._run

    def recording(tasks, workers):
        handed.extend(a for task in tasks for a in task[1] if isinstance(a, TrainingSet))
        return real_run(tasks, workers)
    monkeypatch.setattr(selection, "_run", recording)
    with_3d = replace(materials, valid_3d=np.zeros((len(materials), 7, 3), np.float32))
    assert tune_baselines(with_3d, seed=3, workers=1) == tune_baselines(materials, seed=3,
                                                                          workers=1)
    assert handed and all(t.valid_3d is None for t in handed)


def test_threaded_table_reading_equals_sequential(materials, tmp_path, monkeypatch):
    # three tables with empty bins (NaN below the horizon and a hole): the same slices, 2D and
    # 3D rows, NaN where they were, read by one thread or three
    for i in range(3):
        full = np.repeat(materials.tables_2d[i][:, :, None, :], 180, axis=2)
        full[i, 3, :7] = np.nan
        merl.write_merl(tmp_path / f"m{i}.binary", full)
    reads = {}
    for threads in ("1", "3"):
        monkeypatch.setenv("FLASHBRDF_THREADS", threads)
        reads[threads] = TrainingSet.from_merl_dir(tmp_path, keep_3d=True)
    a, b = reads["1"], reads["3"]
    assert a.names == b.names == ["m0", "m1", "m2"]
    for field in ("slices", "tables_2d", "valid_3d"):
        assert np.array_equal(getattr(a, field), getattr(b, field), equal_nan=True)
    # the hole is averaged over the 173 φd bins left, not counted as zero
    assert np.isfinite(a.tables_2d[1, 1, 3]).all()
    assert np.allclose(a.tables_2d[1, 1, 3], materials.tables_2d[1, 1, 3], rtol=1e-12)


def test_fit_loo_grid_cache_changes_nothing():
    # the grid's eigendecompositions depend on d2 alone: cached across calls (the ADM cycles),
    # the second call with another latent gives what an uncached call gives, to the last bit
    from flashbrdf.infer.backmap import fit_loo
    from flashbrdf.infer.gp import squared_distances
    rng = np.random.default_rng(2)
    d2 = squared_distances(rng.normal(size=(15, 6)))
    cache = {}
    for k in range(2):
        latent, lag = rng.normal(size=(15, 3)), 0.1 * rng.normal(size=(15, 3))
        plain = fit_loo(d2, latent, lag, 1.5, 0.1, 1e-3)
        assert fit_loo(d2, latent, lag, 1.5, 0.1, 1e-3, cache) == plain
    assert len(cache) == 9                       # the 9 grid points, computed once


def test_adm_schedule_reaches_mu_max_then_settles():
    # the stated schedule: μ × 1.25 a cycle from 1 reaches μ_max = 1e3 after 31 cycles
    # (1.25^30 = 808, 1.25^31 = 1009), then 9 more cycles at μ_max: 40 cycles in all
    from _dsgplvm_data import latent_views
    from flashbrdf.infer.dsgplvm import DSGPLVM
    _, v1, v2 = latent_views(16, seed=4)
    model = DSGPLVM(q=2).fit({"1d": v1, "2d": v2})
    mus = [c["mu"] for c in model.cycle_info_[1:]]
    assert model.n_cycles_ == 40 and model.mu_ == 1e3
    assert mus[29] < 1e3 and mus[30] == 1e3
    assert np.all(np.isfinite(model.latent_))


def test_lab_log_error_against_a_reference_equals_brdf_error():
    # the truth's half of the metric computed once (ashikhmin's fit): the same error to the
    # last bit, NaN and negative predictions included
    from flashbrdf.brdf import metrics
    rng = np.random.default_rng(5)
    true = rng.lognormal(-2, 2, size=(4, 90, 90, 3))
    true[:, 80:, 85:] = np.nan
    pred = true * rng.lognormal(0, 0.3, size=true.shape)
    pred[0, 3, 4] = np.nan
    pred[1, 5, 6, 1] = -1.0
    reference = metrics.lab_log_reference(true)
    assert metrics.lab_log_error(pred, reference) == metrics.brdf_error(pred, true, "log", "lab")
    assert np.isnan(metrics.lab_log_error(pred, metrics.lab_log_reference(np.full((2, 3), np.nan))))
