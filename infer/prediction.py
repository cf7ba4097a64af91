"""One prediction from a flash slice, as `infer` and `run` make and write it: the MERL table and its
BRDF.json record (method, view, timings, sparse tail, uncertainty, novelty).

The slice's sparse periphery is emptied first (infer.slices.without_sparse_tail), a 2D prediction
is copied across phi_d, and bins below the horizon (or not predicted) are written as MERL's -1.
"""

import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from flashbrdf.brdf import merl
from flashbrdf.files.atomic import write_text
from flashbrdf.files.errors import InputError
from flashbrdf.files.outputs import sidecar_json
from flashbrdf.infer.warning import prediction_warning
from flashbrdf.infer.slices import (sample_counts, sparse_tail_note, sparse_tail_record,
                                    without_sparse_tail)


@dataclass(eq=False)
class Prediction:
    """table (90, 90, 3) or (90, 90, 180, 3) 1/sr, NaN where not predicted; variance or None;
    view "2d" | "3d"; seconds of predict; novelty: infer.warning.prediction_warning's record
    (BRDF.json's "novelty") and warning: its line or None;
    ignored: theta_h bins of the slice's sparse tail left out; n (90,) sample counts;
    observed_bins: theta_h bins the prediction was made from."""
    table: np.ndarray
    variance: object
    view: str
    seconds: float
    novelty: object
    warning: object
    ignored: list
    n: np.ndarray
    observed_bins: int

    @property
    def tail_note(self):
        """One line (or None) saying which sparse bins were left out."""
        return sparse_tail_note(self.ignored, self.n) if self.ignored else None


def predict_slice(method, rho, n, view, source="slice"):
    """Predict from a flash slice rho (90, 3) 1/sr (NaN-empty) with sample counts n (90,) or None,
    by a fitted method; view "2d" or "3d". source names the slice in the warning."""
    n = sample_counts(rho, n)  # an empty bin's n does not set the threshold the note tells
    rho, ignored = without_sparse_tail(rho, n)
    start = time.perf_counter()
    table, variance = method.predict(rho, view=view)
    seconds = time.perf_counter() - start
    check_storable(table, rho, method, source)
    novelty, warning = prediction_warning(method, rho, source)
    return Prediction(table, variance, view, seconds, novelty, warning, ignored, n,
                      int(np.isfinite(rho).all(axis=1).sum()))


def check_storable(table, rho, method, source):
    """InputError naming the slice `source` when the predicted table holds a value no MERL table
    may (stored, ρ / brdf.merl.MERL_SCALE, above brdf.merl.MAX_STORED_VALUE): a method
    extrapolating from a slice far outside its training range (pca from a flat 1e17 1/sr slice
    reached 1.8e28 1/sr, 2.7e31 stored) would write a file that nothing, this tool included,
    reads back."""
    # per channel, no copy of the table (35 MB in 3D): the limit is on rho / MERL_SCALE
    table = np.asarray(table)
    with np.errstate(invalid="ignore"):
        tops = [float(np.nanmax(table[..., c], initial=0.0)) for c in range(3)]
    if max(t / s for t, s in zip(tops, merl.MERL_SCALE)) > merl.MAX_STORED_VALUE:
        raise InputError(source, f"{method.name}'s prediction reaches {max(tops):.3g} 1/sr, "
                                 f"beyond what a MERL table holds ({merl.MAX_STORED_VALUE:g} "
                                 "stored, rho / MERL's scale): the slice (up to "
                                 f"{np.nanmax(rho):.3g} 1/sr) lies far outside the training "
                                 "tables' range; check its units, or use another method")


def merl_table(prediction):
    """The full 3D MERL table (90, 90, 180, 3) to write: a 2D prediction as a read-only view
    across phi_d (written without a copy); NaN where nothing was predicted."""
    if prediction.view == "2d":
        table = np.asarray(prediction.table, dtype=np.float64)
        return np.broadcast_to(table[:, :, None, :], merl.MERL_SHAPE + (3,))
    return prediction.table


def uncertainty_summary(variance, feature_label):
    """BRDF.json's "uncertainty": mean, median, max and mean std of the per-bin variance, or None."""
    if variance is None:
        return None
    v = np.ravel(np.asarray(variance, float))
    v = v[np.isfinite(v)]
    if not v.size:
        return None
    return {"space": f"brdf.colour features ({feature_label}), predictive variance",
            "mean": float(v.mean()), "median": float(np.median(v)), "max": float(v.max()),
            "mean_std": float(np.sqrt(v).mean())}


def brdf_record(prediction, method, method_name, model_path, level=None):
    """The BRDF.json fields every prediction carries; level: the slice's (absolute or relative,
    slice_extract.level), when known."""
    novelty = prediction.novelty
    return {"method": method_name, "model": None if model_path is None else str(model_path),
            "level": level,
            "view": prediction.view,
            "predicted": "3D table" if prediction.view == "3d" else "2D table copied across phi_d",
            "predict_seconds": prediction.seconds,
            "sparse_tail_ignored": sparse_tail_record(prediction.ignored, prediction.n),
            "uncertainty": uncertainty_summary(prediction.variance,
                                               getattr(method, "feature_label", "")),
            "novelty": novelty}


def write_prediction(path, prediction, record):
    """Write the MERL table at `path` and `record` as JSON beside it (files.outputs.sidecar_json:
    x.binary -> x.json), both or neither. record: a dict, or a function giving it once the table
    is written (a record of timings)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    merl.write_merl(path, merl_table(prediction), no_data=~merl.merl_valid_mask())
    try:
        if callable(record):
            record = record()
        write_text(sidecar_json(path),
                   json.dumps(record, indent=2, default=str) + "\n")
    except BaseException:
        path.unlink(missing_ok=True)  # both files or neither
        raise
