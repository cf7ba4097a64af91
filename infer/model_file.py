"""One MODEL.npz for `flashbrdf train` / `infer`: the DS-GPLVM plus what every baseline needs.

Arrays: format, names (N,), slices (N, 90, 3), tables_2d (N, 90, 90, 3) in 1/sr, params (JSON text:
per-method hyperparameters), dsgplvm (uint8: the DSGPLVM's own .npz bytes), optional valid_3d
(N, n_valid, 3) float32 ρ of the valid 3D bins (when trained with the 3D view).
"""

import json
import os
import tempfile
import time
import zipfile

import numpy as np

from flashbrdf.brdf import merl
from flashbrdf.brdf.bins import valid_mask_2d
from flashbrdf.files.atomic import atomic_path
from flashbrdf.files.errors import DECODE_ERRORS, InputError
from flashbrdf.infer.adapter import table_features
from flashbrdf.infer.dsgplvm import DSGPLVM
from flashbrdf.infer.methods import METHODS, make_method, method_from_model
from flashbrdf.infer.training_set import TrainingSet
from flashbrdf.infer.viewdata import restore_rows

FORMAT = "flashbrdf-infer-model-1"
PCA_STATE = ("ref", "mean", "var", "dual")  # PCA.state()'s arrays, stored as pca_<name>


def _model_bytes(model):
    # The 2D (and 3D) training rows are not stored twice: the file's tables_2d rebuild them on load.
    with tempfile.TemporaryDirectory() as folder:
        path = os.path.join(folder, "dsgplvm.npz")
        model.save(path, store_views=(model.source_view,))
        with open(path, "rb") as f:
            return np.frombuffer(f.read(), np.uint8)


def save_model(path, training, params, dsgplvm=None, merl_dir="", pca_state=None):
    """Write MODEL.npz atomically. params: {method: {hyperparameter: value}}. merl_dir: the
    training folder, or a list of them (all recorded in `merl_dirs`; `merl_dir` keeps the first).
    pca_state: infer.baselines.pca.PCA.state() of a PCA fitted on these tables, restored at load
    (TrainingSet.fitted_pca) instead of refitted."""
    merl_dirs = [str(merl_dir)] if isinstance(merl_dir, (str, os.PathLike)) else \
        [str(d) for d in merl_dir]
    # float32 keeps 7 digits, far below the feature map's resolution, and halves the file.
    arrays = {"format": np.array(FORMAT), "names": np.array(training.names),
              "slices": training.slices, "tables_2d": np.asarray(training.tables_2d, np.float32),
              "params": np.array(json.dumps(params)),
              "merl_dir": np.array(merl_dirs[0] if merl_dirs else ""),
              "merl_dirs": np.array(merl_dirs, dtype=str)}
    if dsgplvm is not None:
        arrays["dsgplvm"] = _model_bytes(dsgplvm)
    if training.valid_3d is not None:
        arrays["valid_3d"] = np.asarray(training.valid_3d, np.float32)
    if pca_state is not None:
        arrays["pca_params"] = np.array(json.dumps(pca_state["params"]))
        arrays.update({f"pca_{k}": np.asarray(pca_state[k]) for k in PCA_STATE})
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            np.savez_compressed(f, **arrays)


def _unreadable(path, err):
    return InputError(path, f"cannot read model ({type(err).__name__}: {err}); a truncated or "
                            "damaged copy?")


def check_model_file(path):
    """InputError unless `path` is a whole flashbrdf model: a readable zip whose every member
    passes its CRC (a truncated or damaged copy fails here in ~0.1 s) and whose format matches.
    Reads no array beyond the format tag; read_model does the full read."""
    try:
        with zipfile.ZipFile(path) as archive:
            bad = archive.testzip()
        if bad is not None:
            raise InputError(path, f"damaged model file: member {bad} fails its CRC check")
        with np.load(path, allow_pickle=False) as z:
            found = str(z["format"]) if "format" in z.files else None
    except InputError:
        raise
    except DECODE_ERRORS as err:
        raise _unreadable(path, err) from None
    if found != FORMAT:
        raise InputError(path, f"not a flashbrdf model (format {found})")


def read_model(path, merl_dir=None):
    """-> (TrainingSet, params dict, dsgplvm npz bytes or None). 3D tables come from the stored rows,
    else lazily from merl_dir, a folder or a list of folders (matched by material name, so a model
    trained on several folders reads its tables from all of them). InputError on a bad file."""
    try:
        z = np.load(path, allow_pickle=False)
        if str(z["format"]) != FORMAT:
            raise InputError(path, f"not a flashbrdf model (format {z['format']})")
        names = [str(n) for n in np.atleast_1d(z["names"])]
        slices, tables_2d = z["slices"], np.asarray(z["tables_2d"], np.float64)
        n = len(names)
        for key, array, shape in (("slices", slices, (n, merl.N_THETA_H, 3)),
                                  ("tables_2d", tables_2d, (n,) + merl.MERL_SHAPE[:2] + (3,))):
            if n == 0 or array.shape != shape or not np.issubdtype(array.dtype, np.floating):
                raise InputError(path, f"damaged model: {key} has shape {array.shape} "
                                       f"({array.dtype}), expected {shape} floats")
            # rho in 1/sr, NaN where a table has no data: never inf or negative, and each
            # material has some data (inf made noll raise a traceback, the rest exit 0 with a
            # table of NaN or garbage)
            with np.errstate(invalid="ignore"):
                odd = np.isinf(array).any() or bool((array < 0).any())
            empty = np.isnan(array).reshape(n, -1).all(axis=1)
            if odd or empty.any():
                raise InputError(path, f"damaged model: {key} holds " + (
                    "infinite or negative values" if odd else
                    f"no value for material {names[int(np.argmax(empty))]!r}"))
        training = TrainingSet(names, slices, tables_2d)
        if "valid_3d" in z.files:
            training.valid_3d = z["valid_3d"]
            shape = (n, int(np.count_nonzero(merl.merl_valid_mask())), 3)
            if training.valid_3d.shape != shape:
                raise InputError(path, f"damaged model: valid_3d has shape "
                                       f"{training.valid_3d.shape}, expected {shape}")
        if "pca_params" in z.files and all(f"pca_{k}" in z.files for k in PCA_STATE):
            training.fitted_pca = _pca_state(z, n, path)
        params = json.loads(str(z["params"]))
        if not isinstance(params, dict):
            raise InputError(path, "damaged model: params is not a JSON object")
        blob = z["dsgplvm"].tobytes() if "dsgplvm" in z.files else None
    except InputError:
        raise
    except DECODE_ERRORS as err:
        raise _unreadable(path, err) from None
    if training.valid_3d is None and merl_dir is not None:
        found = merl.list_merl_dirs(merl_dir)
        missing = [n for n in names if n not in found]
        if len(missing) == len(names):
            where = merl_dir if isinstance(merl_dir, (str, os.PathLike)) else ", ".join(
                map(str, merl_dir))
            raise InputError(where, f"holds none of the model's training tables "
                                    f"(e.g. {', '.join(missing[:3])})")
        # A model trained on several folders (e.g. MERL + a user's own tables) read with only
        # some of them: the absent tables stand in by their stored 2D tables copied across phi_d
        # (TrainingSet.table_3d_valid), and the caller warns (TrainingSet.missing_3d).
        training.paths = [found.get(n) for n in names]
    return training, params, blob


def _pca_state(z, n, path):
    """The stored PCA state (TrainingSet.fitted_pca), checked: finite arrays of the shapes a fit
    on n tables gives; InputError naming the model when damaged."""
    params = json.loads(str(z["pca_params"]))
    state = {k: np.asarray(z[f"pca_{k}"], np.float64) for k in PCA_STATE}
    bins = int(np.count_nonzero(valid_mask_2d()))
    k = len(state["var"]) if state["var"].ndim == 1 else -1
    shapes = {"ref": (bins, 3), "mean": (3 * bins,), "var": (k,), "dual": (n, k)}
    for name, shape in shapes.items():
        if state[name].shape != shape or not np.all(np.isfinite(state[name])):
            raise InputError(path, f"damaged model: pca_{name} has shape {state[name].shape}, "
                                   f"expected {shape} finite values")
    if not isinstance(params, dict) or not 0 < k < n or np.any(state["var"] <= 0):
        raise InputError(path, "damaged model: its stored PCA is not a fit of its tables")
    return {"params": params, **state}


def load_dsgplvm(blob, training=None, feature_space="lab", features_2d=None):
    """The DSGPLVM in `blob`; views stored without training rows get them back from `training`
    (its 2D tables' features: features_2d when the caller has them, infer.adapter.table_features)."""
    with tempfile.TemporaryDirectory() as folder:
        path = os.path.join(folder, "dsgplvm.npz")
        with open(path, "wb") as f:
            f.write(blob)
        model = DSGPLVM.load(path)
    if training is not None and model.view_data_["2d"].data is None:
        if features_2d is None:
            features_2d = table_features(training.tables_2d, feature_space)
        restore_rows(model, "2d", features_2d)
    return model


def _finite(value):
    return isinstance(value, (int, float)) and not isinstance(value, bool) and \
        bool(np.isfinite(value))


def _count(value):
    return isinstance(value, int) and not isinstance(value, bool) and value >= 1


# what a stored hyperparameter must be (train never writes anything else): a value outside
# these gave a traceback (a feature space of "xyz"), or numbers of no meaning at exit 0 (a
# negative calibration made variances negative; ashikhmin's r0 of -3 wrote 28,062 bins of -1)
HYPERPARAMETER_RULES = {
    "calibration": ("a positive number", lambda v: _finite(v) and v > 0),
    "ridge": ("a number >= 0", lambda v: _finite(v) and v >= 0),
    "r0": ("a number in (0, 1] or null", lambda v: v is None or (_finite(v) and 0 < v <= 1)),
    "n_components": ("a count >= 1 or null", lambda v: v is None or _count(v)),
    "q": ("a count >= 1 or null", lambda v: v is None or _count(v)),
    "beta": ("a number >= 0", lambda v: _finite(v) and v >= 0),
    "seed": ("an integer", lambda v: isinstance(v, int) and not isinstance(v, bool)),
    "feature_space": ('"lab" or "rgb"', lambda v: v in ("lab", "rgb")),
    "views": ('views among "1d", "2d", "3d" with "1d" and "2d"',
              lambda v: isinstance(v, list) and {"1d", "2d"} <= set(v) <= {"1d", "2d", "3d"}),
}


def check_hyperparameters(path, name, params, stored=True):
    """InputError naming the model file and the hyperparameter when a stored value is one train
    never writes (HYPERPARAMETER_RULES); pca_params is checked as pca's own. stored=False: the
    values are a caller's overrides, and the error names them, not the file."""
    where, head = (path, "damaged model: ") if stored else (f"{name} override", "")
    for key, value in params.items():
        if key == "pca_params" and value is not None:
            if not isinstance(value, dict):
                raise InputError(where, f"{head}params[{name!r}]['pca_params'] is not a JSON "
                                        "object")
            check_hyperparameters(path, f"{name}.pca_params", value, stored)
            continue
        what, ok = HYPERPARAMETER_RULES.get(key, (None, None))
        if ok is not None and not ok(value):
            raise InputError(where, f"{head}params[{name!r}][{key!r}] is {value!r}, expected "
                                    f"{what}")


def load_method(path, name, merl_dir=None, **overrides):
    """A fitted method `name` from MODEL.npz (see infer.make_method), as `flashbrdf infer` uses
    it: dsgplvm is the shipped default (anchor=True; anchor=False is the paper's method).
    `overrides` replace stored hyperparameters that act at prediction time."""
    if name == "dsgplvm":
        overrides = {"anchor": True, **overrides}
    return load_methods(path, [name], merl_dir, {name: overrides})[name]


def load_methods(path, names, merl_dir=None, overrides=None, fit_seconds=None):
    """{name: fitted method} for several methods from one read of MODEL.npz (a model with a 3D
    view holds GBs of rows: read once, shared). overrides: {name: {hyperparameter: value}}.
    fit_seconds: a dict that receives each method's load-and-fit wall time, if given."""
    unknown = [name for name in names if name not in METHODS]
    if unknown:  # the caller's word, not the file's: before reading it
        raise InputError("method", f"unknown method {unknown[0]!r} (expected one of "
                                   f"{', '.join(METHODS)})")
    training, params, blob = read_model(path, merl_dir)
    methods = {}
    for name in names:
        start = time.perf_counter()
        stored = params.get(name, {})
        if not isinstance(stored, dict):
            raise InputError(path, f"damaged model: params[{name!r}] is not a JSON object of "
                                   "hyperparameters")
        kw = {**stored, **(overrides or {}).get(name, {})}
        try:
            make_method(name, **kw)  # hyperparameters the method does not take: a damaged file
        except (TypeError, ValueError) as err:
            raise InputError(path, f"damaged model: params[{name!r}] ({err})") from None
        check_hyperparameters(path, name, stored)  # the file's word
        check_hyperparameters(path, name, (overrides or {}).get(name, {}), stored=False)
        if name == "dsgplvm":
            if blob is None:
                raise InputError(path, "model holds no DS-GPLVM")
            # models written before the relative representation store none: they are absolute
            kw.setdefault("representation", "absolute")
            absolute = kw["representation"] == "absolute"
            # the 2D tables' features, computed once: the rows the model is restored from and
            # the ranges the method clips to (a third of the load's time)
            features = (table_features(training.tables_2d, kw.get("feature_space", "lab"))
                        if absolute else None)
            try:
                model = load_dsgplvm(blob, training if absolute else None,
                                     kw.get("feature_space", "lab"), features)
            except DECODE_ERRORS as err:
                raise InputError(path, f"cannot read the DS-GPLVM stored in the model "
                                       f"({type(err).__name__}: {err})") from None
            extra = {"features_2d": features} if absolute else {}
            methods[name] = method_from_model(name, model, training, **extra, **kw)
        else:
            methods[name] = make_method(name, **kw).fit(training)
        if fit_seconds is not None:
            fit_seconds[name] = time.perf_counter() - start
    return methods
