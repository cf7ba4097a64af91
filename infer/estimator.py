"""The estimator base of every inference method, and the streamed 3D prediction of methods whose
3D table is a weighted sum of training tables in a mapped space.

Frames and units: BRDF values ρ in 1/sr; angles in radians on MERL bin centres (brdf.merl); a
"flash slice" is ρ(θh) at θd bin 0, shape (90, 3), NaN where the bin is empty (missing data, never 0).
A 2D table is (90, 90, 3) over (θh, θd); a 3D table is (90, 90, 180, 3) over (θh, θd, φd); both NaN
where MERL's layout has no data (below the horizon).
"""

import functools
import inspect
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from flashbrdf.brdf.bins import scatter_valid, valid_flat_3d
from flashbrdf.files.errors import InputError
from flashbrdf.infer.slices import check_slice
from flashbrdf.infer.training_set import default_threads


class NotFittedError(ValueError, AttributeError):
    """predict or novelty asked of a method before fit (scikit-learn's exception of that name
    derives from the same two)."""


class InferenceMethod:
    """Base of every method: fit(training) then predict(flash_slice, view) -> (table, variance).

    table: (90, 90, 3) for view "2d", (90, 90, 180, 3) for "3d", 1/sr, NaN where MERL has no data.
    variance: per-bin predictive variance in the method's feature space (same shape), or None.
    Methods whose 3D prediction is a weighted sum of training tables in some mapped space implement
    `combination(flash_slice)` -> (weights (N,), LinearSpace); the 3D table is then streamed.

    The scikit-learn contract: __init__ only stores its arguments (get_params/set_params read and
    write them, as sklearn.base.BaseEstimator's do; importing sklearn would cost `flashbrdf infer`
    half a second, scipy.stats with it), fit sets attributes ending in "_" and returns self, and
    never changes a constructor argument. Optional abilities are declared here, so callers ask for
    them instead of testing names:
    - evaluation_only: the method predicts from the true table (predict_truth), not from a slice;
    - closed_form_3d: predict_valid_3d(rho, sel) gives 3D bins directly, without training tables;
    - has_uncertainty: predict returns a per-bin variance (bin_variance);
    - needs_fit: predict needs fit first (NotFittedError before it).
    """
    name = "base"
    evaluation_only = False
    closed_form_3d = False
    has_uncertainty = False
    needs_fit = True

    def check_fitted(self):
        """NotFittedError unless fit has run (an attribute ending in "_" is set)."""
        if self.needs_fit and not any(k.endswith("_") and not k.startswith("__")
                                      for k in vars(self)):
            raise NotFittedError(f"this {type(self).__name__} is not fitted yet: call "
                                 "fit(TrainingSet) first, or load a fitted one with "
                                 "flashbrdf.infer.load_method(model_file, name)")

    @classmethod
    def _param_names(cls):
        """The constructor's named arguments, sorted (its **kwargs are not among them)."""
        parameters = inspect.signature(cls.__init__).parameters.values()
        return sorted(p.name for p in parameters if p.name != "self"
                      and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD))

    def get_params(self, deep=True):
        """{constructor argument: its value} (deep: accepted for scikit-learn's signature)."""
        return {name: getattr(self, name) for name in self._param_names()}

    def set_params(self, **params):
        """Set constructor arguments by name (ValueError for any other name); returns self."""
        valid = self.get_params()
        for key, value in params.items():
            if key not in valid:
                raise ValueError(f"invalid parameter {key!r} for {type(self).__name__}; valid: "
                                 f"{sorted(valid)}")
            setattr(self, key, value)
            valid[key] = value
        return self

    def __repr__(self):
        return f"{type(self).__name__}({', '.join(f'{k}={v!r}' for k, v in self.get_params().items())})"

    def fit(self, training):
        raise NotImplementedError

    def predict(self, flash_slice, view="2d"):
        """(table, variance) from a complete flash slice (90, 3) 1/sr, NaN-empty; a slice from
        photos with thin bins at its ends: infer.predict_slice(method, rho, n, view), which
        empties its sparse tail first, as `flashbrdf infer` does."""
        self.check_fitted()
        rho = check_slice(flash_slice)
        if view == "2d":
            return self._predict_2d(rho)
        if view == "3d":
            training = getattr(self, "training_", None)
            if training is not None:    # --merl-dir's tables must be the model's
                training.check_3d_files()
            return self._predict_3d(rho)
        raise InputError("view", f"unknown view {view!r} (expected '2d' or '3d')")

    def _predict_3d(self, rho):
        weights, space = self.combination(rho)
        values = stream_combination(self.training_, weights, space)
        return scatter_valid(values), None

    def predict_truth(self, true_table_2d):
        """Evaluation-only methods (evaluation_only): the prediction from the true 2D table
        (90, 90, 3) -> (90, 90, 3) in 1/sr."""
        raise NotImplementedError(f"{self.name} predicts from a flash slice, not the true table")

    def predict_valid_3d(self, rho, sel=slice(None)):
        """closed_form_3d methods: ρ (n, 3) on the valid 3D bins `sel` (a slice or indices into
        valid_bins_3d()) for a checked slice rho (90, 3)."""
        raise NotImplementedError(f"{self.name} has no closed-form 3D prediction")

    def training_3d(self):
        """Where this fitted method reads its 3D training tables from: "stored" (rows held in
        memory or in the model file), "files" (MERL tables read one at a time) or None."""
        training = getattr(self, "training_", None)
        if training is None:
            return None
        if training.valid_3d is not None:
            return "stored"
        return "files" if training.paths is not None else None

    def can_predict_3d(self):
        """Whether predict(..., "3d") can run: closed-form, or with 3D training tables at hand."""
        return self.closed_form_3d or self.training_3d() is not None

    def novelty(self, flash_slice):
        """How far a slice lies from what the method was trained on (> 1: outside), or None for
        methods that do not measure it."""
        return None

    def fitted_params(self):
        """get_params() with the hyperparameters fit chose filled in, so that
        make_method(name, **fitted_params()).fit(same training) reproduces this fit without search."""
        return self.get_params()


class LinearSpace:
    """A per-bin invertible map ρ -> m in which a method combines training tables linearly.

    `sel` picks the valid 3D bins the rows belong to (a slice or index array into valid_bins_3d()).
    forward(rho (n,3), sel) -> (n,3); inverse(m (n,3), sel) -> ρ (n,3) ≥ 0. Default: identity.
    clip_to_training: the combination is clipped, per bin and channel, to the range of the training
    tables' mapped values before the inverse (a GP mean with large ± weights can otherwise
    extrapolate by many decades at grazing bins).
    """
    clip_to_training = False

    def forward(self, rho, sel=slice(None)):
        return rho

    def inverse(self, mapped, sel=slice(None)):
        return np.maximum(mapped, 0.0)


def stream_combination(training, weights, space, tol=1e-12, workers=None):
    """Σ_i w_i forward(T_i) over the valid 3D bins, reading one training table at a time per worker
    thread, then inverse. Returns ρ on valid bins (n_valid, 3).

    Tables are read and mapped in float32 (the maps are per bin; float32 keeps 7 digits, far below
    the metrics' resolution) and summed in float64. Tables whose weight is negligible are skipped,
    unless space.clip_to_training asks for the range of every table. workers: threads (default:
    $FLASHBRDF_THREADS, else one per core, at most 4); numpy's ufuncs and file reads release the
    GIL, so two cores give almost twice the speed of one.
    """
    weights = np.asarray(weights, dtype=np.float64)
    scale = np.abs(weights).max() if len(weights) else 0.0
    clip = getattr(space, "clip_to_training", False)
    used = [i for i, w in enumerate(weights) if clip or abs(w) > tol * scale]
    workers = workers or default_threads()
    workers = max(1, min(workers, len(used)))

    def partial(part):
        total = np.zeros((len(valid_flat_3d()), 3))
        low = high = None
        for i in part:
            mapped = space.forward(training.table_3d_valid(i, np.float32))
            total += weights[i] * mapped
            if clip:
                low = mapped if low is None else np.fmin(low, mapped)
                high = mapped if high is None else np.fmax(high, mapped)
        return total, low, high

    if workers == 1:
        parts = [partial(used)]
    else:
        with ThreadPoolExecutor(workers) as pool:
            parts = list(pool.map(partial, [used[k::workers] for k in range(workers)]))
    total = sum(p[0] for p in parts)
    if clip and used:
        low = functools.reduce(np.fmin, [p[1] for p in parts if p[1] is not None])
        high = functools.reduce(np.fmax, [p[2] for p in parts if p[2] is not None])
        total = clip_to_range(total, low, high)
    return space.inverse(total)


def clip_to_range(values, low, high):
    """values clipped to [low, high] where those are finite (NaN bounds leave the value alone)."""
    out = np.where(np.isfinite(low) & (values < low), low, values)
    return np.where(np.isfinite(high) & (out > high), high, out)
