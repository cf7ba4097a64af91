"""The jobs of `merl-slice`, `train` and `infer`: MERL tables and flash slices in, files out.

Each takes values and checks its outputs against its inputs before any slow work
(files.outputs); bad input raises InputError (exit 2).
"""

import math
import os
import sys
import time

from flashbrdf.brdf import merl, views
from flashbrdf.files.errors import InputError
from flashbrdf.files.outputs import check_outputs, check_sidecar_replaceable, sidecar_json
from flashbrdf.pipeline.options import model_path


def merl_dirs_list(value):
    """--merl-dir as a list of folders (the option may be repeated; a str is one folder)."""
    return [value] if isinstance(value, str) else list(value or [])


def merl_inputs(folders):
    """MERL folders and their tables, as inputs no output may touch (InputError when one is not a
    folder of tables)."""
    return [item for folder in merl_dirs_list(folders)
            for item in (folder, *(path for _, path in merl.list_merl(folder)))]


def merl_slice(brdf_path, out):
    """`flashbrdf merl-slice`: the theta_d = 0 slice of a MERL table, as slice.csv."""
    check_outputs(inputs=[brdf_path], outputs=[out])
    table = merl.read_merl(brdf_path)
    rho, n = views.flash_slice(table)
    views.check_flash_slice(rho, brdf_path)  # a slice of 90 empty bins, which infer refuses
    views.write_slice_csv(out, rho, n, comments=[
        f"flashbrdf merl-slice {os.path.basename(brdf_path)}",
        "theta_d = 0 slice: mean over the valid phi_d bins of theta_d bin 0; n = phi_d bins used",
        views.LEVEL_COMMENT + "absolute: a measured table's own values"])


def train(merl_dirs, out, views_text="1d,2d", feature_space="auto", seed=0):
    """`flashbrdf train`: the DS-GPLVM on every MERL table of every folder (infer.training), with
    what the baselines need too."""
    from flashbrdf.infer import TrainingSet
    from flashbrdf.infer.model_selection import check_training_size, small_training_note
    from flashbrdf.infer.training import train_model
    folders = merl_dirs_list(merl_dirs)
    if not 0 <= seed < 2 ** 32:  # scikit-learn's random_state is a uint32: a traceback later
        raise InputError("--seed", f"must be an integer in 0..{2 ** 32 - 1}, got {seed}")
    check_outputs(inputs=merl_inputs(folders), outputs=[out])
    wanted = views_text.split(",")
    training = TrainingSet.from_merl_dirs(folders, keep_3d="3d" in wanted)
    check_training_size(len(training), folders[0] if len(folders) == 1 else "--merl-dir")
    params = train_model(training, out, views=wanted, seed=seed, feature_space=feature_space,
                         merl_dirs=folders)
    for path, count in training.filled_bins.items():
        print(f"note: {path}: {count} (θh, θd) bin(s) hold no data (negative in every φd); "
              "filled from their neighbours for training")
    print(f"trained on {len(training)} materials from {len(folders)} folder(s) in "
          f"{params['train_seconds']:.1f} s -> {out}")
    note = small_training_note(len(training))
    if note:
        print(note, file=sys.stderr)


def infer(model, slice_path, out, method_name="dsgplvm", merl_dirs=None, anchor=True,
          view="auto"):
    """`flashbrdf infer`: a full MERL table at `out` and BRDF.json beside it, from a slice."""
    from flashbrdf.infer import load_method, make_method
    from flashbrdf.infer.prediction import brdf_record, predict_slice, write_prediction
    t0 = time.perf_counter()
    model = model_path(model, [method_name])  # the shipped model, as run takes it; chandraker: none
    check_outputs(inputs=[model, slice_path, *merl_inputs(merl_dirs)],
                  outputs=[out, sidecar_json(out)])
    check_sidecar_replaceable(sidecar_json(out), "method", "BRDF.json")
    rho, n = views.read_slice_csv(slice_path)
    if model is None:
        method, has_3d = make_method("chandraker").fit(None), True
    else:
        overrides = {"anchor": anchor} if method_name == "dsgplvm" else {}
        method = load_method(model, method_name, merl_dirs, **overrides)
        has_3d = method.can_predict_3d()
    if view == "auto":
        view = "3d" if has_3d else "2d"
    elif view == "3d" and not has_3d:
        raise InputError("--merl-dir", "a 3D prediction from a model without stored 3D data needs "
                         "--merl-dir")
    training = getattr(method, "training_", None)
    missing = training.missing_3d if view == "3d" and training is not None else []
    if missing:
        print(f"warning: {len(missing)} of the model's training tables are not in --merl-dir "
              f"(e.g. {', '.join(missing[:3])}); their share of the 3D prediction is their 2D "
              f"table copied across phi_d", file=sys.stderr)
    t1 = time.perf_counter()
    prediction = predict_slice(method, rho, n, view, source=slice_path)
    differing = training.differing_3d if view == "3d" and training is not None else []
    if differing:   # known once the 3D prediction has checked the tables (check_3d_files)
        worst = max(differing, key=lambda d: d[1])
        print(f"warning: {len(differing)} of the --merl-dir tables differ from the ones the model "
              f"was trained on (θd = 0 slice off by a median {100 * math.expm1(worst[1]):.0f}% "
              f"at most, {worst[0]}); the 3D prediction mixes the tables given", file=sys.stderr)
    if prediction.tail_note:
        print(prediction.tail_note, file=sys.stderr)
    if prediction.warning:
        print(prediction.warning, file=sys.stderr)
    t2 = time.perf_counter()
    record = brdf_record(prediction, method, method_name, model)
    record.update(slice=str(slice_path), level=views.slice_level(slice_path),
                  observed_theta_h_bins=prediction.observed_bins,
                  training_tables_2d_only=missing,
                  training_tables_differing={n: round(math.expm1(d), 4) for n, d in differing},
                  params=method.fitted_params())

    def with_timings():  # once the table is written
        t3 = time.perf_counter()
        return record | {"timings": {"load_s": t1 - t0, "predict_s": t2 - t1,
                                     "write_s": t3 - t2, "total_s": t3 - t0}}

    write_prediction(out, prediction, with_timings)
