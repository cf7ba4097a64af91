"""One MODEL.npz for `flashbrdf train` / `infer`: the DS-GPLVM plus what every baseline needs.

Arrays: format, names (N,), slices (N, 90, 3), tables_2d (N, 90, 90, 3) in 1/sr, params (JSON text:
per-method hyperparameters), dsgplvm (uint8: the DSGPLVM's own .npz bytes), optional valid_3d
(N, n_valid, 3) float32 ρ of the valid 3D bins (when trained with the 3D view).
"""

import json
import os
import tempfile

import numpy as np

from brdf.atomic import atomic_path
from brdf.errors import InputError
from infer.common import TrainingSet

FORMAT = "flashbrdf-infer-model-1"


def _model_bytes(model):
    with tempfile.TemporaryDirectory() as folder:
        path = os.path.join(folder, "dsgplvm.npz")
        model.save(path)
        with open(path, "rb") as f:
            return np.frombuffer(f.read(), np.uint8)


def save_model(path, training, params, dsgplvm=None, merl_dir=""):
    """Write MODEL.npz atomically. params: {method: {hyperparameter: value}}."""
    arrays = {"format": np.array(FORMAT), "names": np.array(training.names),
              "slices": training.slices, "tables_2d": training.tables_2d,
              "params": np.array(json.dumps(params)), "merl_dir": np.array(str(merl_dir))}
    if dsgplvm is not None:
        arrays["dsgplvm"] = _model_bytes(dsgplvm)
    if training.valid_3d is not None:
        arrays["valid_3d"] = np.asarray(training.valid_3d, np.float32)
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            np.savez(f, **arrays)


def read_model(path, merl_dir=None):
    """-> (TrainingSet, params dict, dsgplvm npz bytes or None). 3D tables come from the stored rows,
    else lazily from merl_dir (matched by material name). InputError on a bad file."""
    try:
        z = np.load(path, allow_pickle=False)
        if str(z["format"]) != FORMAT:
            raise InputError(path, f"not a flashbrdf model (format {z['format']})")
        names = [str(n) for n in z["names"]]
        training = TrainingSet(names, z["slices"], z["tables_2d"])
        if "valid_3d" in z.files:
            training.valid_3d = z["valid_3d"]
        params = json.loads(str(z["params"]))
        blob = z["dsgplvm"].tobytes() if "dsgplvm" in z.files else None
    except InputError:
        raise
    except (OSError, ValueError, KeyError, EOFError) as err:
        raise InputError(path, f"cannot read model: {err}") from None
    if training.valid_3d is None and merl_dir is not None:
        from brdf import merl
        found = dict(merl.list_merl(merl_dir))
        missing = [n for n in names if n not in found]
        if missing:
            raise InputError(merl_dir, f"lacks training tables of the model: {', '.join(missing[:5])}")
        training.paths = [found[n] for n in names]
    return training, params, blob


def load_dsgplvm(blob):
    from infer.adapter import _model_class
    with tempfile.TemporaryDirectory() as folder:
        path = os.path.join(folder, "dsgplvm.npz")
        with open(path, "wb") as f:
            f.write(blob)
        return _model_class().load(path)


def load_method(path, name, merl_dir=None):
    """A fitted method `name` from MODEL.npz (see infer.make_method)."""
    from infer import make_method
    training, params, blob = read_model(path, merl_dir)
    kw = dict(params.get(name, {}))
    if name == "dsgplvm":
        if blob is None:
            raise InputError(path, "model holds no DS-GPLVM")
        kw["model"] = load_dsgplvm(blob)
    return make_method(name, **kw).fit(training)


