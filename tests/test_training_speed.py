"""The speed-ups of `flashbrdf train` change no result: the validation fits in processes and the
tables read by threads give exactly what the sequential code gives, on synthetic Ashikhmin–Premože
materials (tests/test_infer_baselines.py builds them on MERL bin centres)."""

import numpy as np
import pytest

from brdf import merl
from infer.model_selection import tune_baselines
from infer.training_set import TrainingSet
from tests.test_infer_baselines import ap_material, training_set


@pytest.fixture(scope="module")
def materials():
    rng = np.random.default_rng(11)
    rows = [ap_material(a, r0, rng.uniform(0.1, 1, 3), diffuse=d)
            for a, r0, d in [(0.08, 0.04, 0.1), (0.2, 0.5, 0.3), (0.35, 0.1, 0.02),
                             (0.5, 0.9, 0.5), (0.15, 0.2, 0.05), (0.7, 0.05, 0.8),
                             (0.25, 0.3, 0.2), (0.12, 0.06, 0.4), (0.45, 0.15, 0.1),
                             (0.3, 0.7, 0.6)]]
    return training_set(rows)


def test_parallel_validation_fits_equal_sequential(materials):
    # the two feature spaces fitted in 2 processes or one after the other: the same winner and
    # the same κ to the last bit (each fit is deterministic and runs its BLAS on one thread)
    one = tune_baselines(materials, seed=3, workers=1)
    two = tune_baselines(materials, seed=3, workers=2)
    assert one["dsgplvm"] == two["dsgplvm"]
    assert one["pca"] == two["pca"]
    assert one["dsgplvm"]["calibration"] > 0


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
