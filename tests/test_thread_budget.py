"""files.threads.thread_budget: the one reader of $FLASHBRDF_THREADS, and the stages that use it."""

import os

import pytest
from synthetic import ggx_lambert, pinhole_camera, point_light, sphere_mesh, write_synthetic_scene

from flashbrdf.files.threads import thread_budget


@pytest.mark.parametrize("value, expected", [("3", 3), ("1", 1), (" 2 ", 2)])
def test_a_worker_share_is_taken_as_given(monkeypatch, value, expected):
    monkeypatch.setenv("FLASHBRDF_THREADS", value)
    assert thread_budget(2) == expected   # above the cap too: the worker's share decides


@pytest.mark.parametrize("value", ["", "0", "-1", "two", "1.5"])
def test_unset_or_not_a_positive_integer_means_the_cores_up_to_the_cap(monkeypatch, value):
    monkeypatch.setenv("FLASHBRDF_THREADS", value)
    cores = os.cpu_count() or 1
    assert thread_budget(4) == min(cores, 4)
    assert thread_budget(1) == 1


@pytest.mark.parametrize("threads, prefetches", [("1", False), ("2", True)])
def test_photos_are_decoded_ahead_only_with_a_second_thread(monkeypatch, tmp_path, threads,
                                                            prefetches):
    """capture.iter_flash_images decodes the next photo in a thread named flash-photo, unless
    the budget is one thread (a batch worker's)."""
    import threading

    from flashbrdf.capture import iter_flash_images, load_scene
    folder = write_synthetic_scene(tmp_path, sphere_mesh(subdivisions=2), ggx_lambert(),
                                   pinhole_camera(32, 32),
                                   [point_light([x, 0, 0]) for x in (0.0, 0.01, 0.02)])
    monkeypatch.setenv("FLASHBRDF_THREADS", threads)
    seen = set()
    for _ in iter_flash_images(load_scene(folder)):
        seen |= {t.name for t in threading.enumerate()}
    assert any(name.startswith("flash-photo") for name in seen) == prefetches


@pytest.mark.parametrize("value, expected", [(None, 1), ("two", 1), ("3", 3)])
def test_a_dask_worker_takes_its_share_or_one_thread(monkeypatch, value, expected):
    """pipeline.dask_engine.worker_threads: a local worker's share as dask_client set it, else 1
    (a worker started by hand); inside the block stages read that share, after it the old value
    is back."""
    from flashbrdf.pipeline.dask_engine import worker_threads
    if value is None:
        monkeypatch.delenv("FLASHBRDF_THREADS", raising=False)
    else:
        monkeypatch.setenv("FLASHBRDF_THREADS", value)
    with worker_threads() as threads:
        assert threads == expected and thread_budget(4) == expected
    assert os.environ.get("FLASHBRDF_THREADS") == value
