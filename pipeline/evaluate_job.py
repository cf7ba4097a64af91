"""The job of `flashbrdf evaluate`: the paper's Table 1 protocol (and Table 2 with render), or an
external test set (test_dir), written all or nothing into one folder."""

import sys
from pathlib import Path

import numpy as np

from flashbrdf.files.errors import InputError
from flashbrdf.files.outputs import check_outputs, staged_output_dir
from flashbrdf.pipeline.dask_engine import check_engine_options, dask_client
from flashbrdf.pipeline.infer_jobs import merl_dirs_list, merl_inputs

MAX_EXPERIMENTS = 10000


def check_protocol_options(experiments, time_budget):
    """InputError for experiments below 1 (0 would silently mean all 25) or above
    MAX_EXPERIMENTS, or a time budget that is not a positive number of seconds."""
    if experiments is not None and experiments < 1:
        raise InputError("--experiments", f"must be at least 1, got {experiments}")
    if experiments is not None and experiments > MAX_EXPERIMENTS:
        # each trains the models (seconds to minutes); 10**9 hung drawing its splits
        raise InputError("--experiments", f"must be at most {MAX_EXPERIMENTS}, got {experiments}")
    if time_budget is not None and not (np.isfinite(time_budget) and time_budget > 0):
        raise InputError("--time-budget", f"must be a positive number of seconds, got "
                                          f"{time_budget}")


def render_envmaps(envmaps, render):
    """Table 2's lat-long maps: every given file, or None for the project's own maps
    (render.envmap.default_envmaps, made in code: never a file outside the project that no flag
    names). Each file is read once here, before the long run, so a missing or malformed map is
    bad input at once (InputError)."""
    from flashbrdf.render.envmap import read_envmap_pixels
    if envmaps and not render:
        raise InputError("--envmap", "names Table 2's maps: give it with --render")
    if not render or not envmaps:
        return None
    paths = [Path(p) for p in envmaps]
    names = [path.stem.split("_latlong")[0] for path in paths]  # Table 2's column names
    if len(set(names)) < len(names):
        raise InputError("--envmap", f"two maps share the name {max(names, key=names.count)!r}: "
                                     "Table 2 names a map by its file name")
    for path in paths:
        read_envmap_pixels(path)
    return paths


def evaluate(merl_dirs, out, *, test_dir=None, render=False, envmaps=None, quick=False,
             experiments=None, time_budget=None, workers=None, scheduler=None, force=False,
             seed=0):
    """The paper's Table 1 protocol on the one MERL folder (experiments.evaluate); with render
    also its Table 2 (experiments.table2) on the mean-performing experiment's test materials, 2D
    predictions. With test_dir: trained on every table of merl_dirs, scored on test_dir's tables
    (experiments.test_set)."""
    folders = merl_dirs_list(merl_dirs)
    check_engine_options(workers, scheduler)
    check_protocol_options(experiments, time_budget)
    if test_dir:
        if envmaps and not render:
            raise InputError("--envmap", "names Table 2's maps: give it with --render")
        if render:
            raise InputError("--render", "renders the cross-validation protocol's materials; "
                                         "not with --test-dir")
        ignored = [flag for flag, given in (("--quick", quick), ("--experiments", experiments),
                                            ("--time-budget", time_budget),
                                            ("--workers", workers), ("--scheduler", scheduler))
                   if given]
        if ignored:  # the cross-validation protocol's options: one training here, in process
            print(f"warning: {', '.join(ignored)} shape the cross-validation protocol; with "
                  "--test-dir the model is trained once and every test table scored in this "
                  "process, so they change nothing", file=sys.stderr)
        from flashbrdf.experiments.test_set import run_test_set
        check_outputs(inputs=merl_inputs(folders + [test_dir]), outputs=[out], folders=[out])
        with staged_output_dir(out, force=force, command="evaluate") as staged:
            run_test_set(folders, test_dir, staged, seed=seed)
        print(f"test set scores -> {Path(out) / 'test_set.md'}")
        return
    if len(folders) != 1:
        raise InputError("--merl-dir", "the cross-validation protocol takes one folder; give "
                                       "--test-dir to train on several")
    from flashbrdf.experiments.evaluate import (check_protocol_tables, experiment_predictor,
                                                run_evaluation)
    merl_dir = folders[0]
    maps = render_envmaps(envmaps, render)
    check_outputs(inputs=merl_inputs(folders) + (maps or []), outputs=[out], folders=[out])
    options = dict(quick=quick, experiments=experiments, time_budget=time_budget)
    # never more local workers than experiments: a spare one costs its start and sits idle
    workers = workers and min(workers, experiments or (1 if quick else 25))
    with staged_output_dir(out, force=force, command="evaluate") as staged:
        check_protocol_tables(merl_dir)  # before a cluster starts, not in run_evaluation
        if workers or scheduler:
            with dask_client(workers, scheduler) as client:  # experiments as Dask tasks
                result = run_evaluation(merl_dir, staged, client=client, **options)
        else:
            result = run_evaluation(merl_dir, staged, **options)
        if render:
            # experiments.table2 (renderer, figures) adds 1.7-2.2 s to import (python -X importtime)
            from flashbrdf.experiments.table2 import table2
            names, predict = experiment_predictor(merl_dir, result)
            table2(merl_dir, staged, predict, names=names, envmaps=maps)
