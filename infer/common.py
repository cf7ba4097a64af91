"""Shared pieces of every inference method: the training set, the bin geometry and the estimator base.

Frames and units: BRDF values ρ in 1/sr; angles in radians on MERL bin centres (brdf.merl); a
"flash slice" is ρ(θh) at θd bin 0, shape (90, 3), NaN where the bin is empty (missing data, never 0).
A 2D table is (90, 90, 3) over (θh, θd); a 3D table is (90, 90, 180, 3) over (θh, θd, φd); both NaN
where MERL's layout has no data (below the horizon).
"""

import functools
import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np
from sklearn.base import BaseEstimator

from brdf import merl, views
from brdf.errors import InputError


# ----------------------------------------------------------------------------- bin geometry
@functools.lru_cache(maxsize=1)
def valid_bins_3d():
    """Flat indices of MERL's valid 3D bins: (ih, id, kd) int arrays, each (n_valid,) (1,096,216)."""
    ih, jd, kd = np.nonzero(merl.merl_valid_mask())
    return ih.astype(np.int16), jd.astype(np.int16), kd.astype(np.int16)


@functools.lru_cache(maxsize=1)
def valid_flat_3d():
    """valid_bins_3d() as flat indices phi_d + 180*(theta_d + 90*theta_h), (n_valid,) int64."""
    ih, jd, kd = (b.astype(np.int64) for b in valid_bins_3d())
    return kd + merl.N_PHI_D * (jd + merl.N_THETA_D * ih)


@functools.lru_cache(maxsize=1)
def valid_mask_2d():
    """(90, 90) bool: (θh, θd) bins with at least one valid φd bin."""
    return merl.merl_valid_mask().any(axis=2)


def cos_in_out(theta_h, theta_d, phi_d):
    """cos θi, cos θo of the light/view pair at half/difference angles (any broadcastable shapes).

    With h = Ry(θh)·z and the difference vector d in the half-vector frame, ωi = Ry(θh)·d and
    ωo = 2(ωi·h)h − ωi, so cos θi = cos θd cos θh − sin θd cos φd sin θh and cos θo the same with +.
    """
    a = np.cos(theta_d) * np.cos(theta_h)
    b = np.sin(theta_d) * np.cos(phi_d) * np.sin(theta_h)
    return a - b, a + b


@functools.lru_cache(maxsize=1)
def cos_in_out_valid():
    """cos θi, cos θo at every valid 3D bin centre, each (n_valid,) float64."""
    ih, jd, kd = valid_bins_3d()
    return cos_in_out(merl.theta_h_centres()[ih], merl.theta_d_centres()[jd], merl.phi_d_centres()[kd])


def mean_over_phi_d(values_valid):
    """Mean over valid φd bins of per-valid-bin values (n_valid, ...) -> (90, 90, ...), NaN where none."""
    ih, jd, _ = valid_bins_3d()
    flat = ih.astype(np.int64) * 90 + jd
    rest = values_valid.shape[1:]
    columns = values_valid.reshape(len(flat), -1)
    count = np.bincount(flat, minlength=8100).astype(float)
    out = np.full((8100, columns.shape[1]), np.nan)
    seen = count > 0
    for c in range(columns.shape[1]):
        out[seen, c] = np.bincount(flat, columns[:, c], minlength=8100)[seen] / count[seen]
    return out.reshape((90, 90) + rest)


def scatter_valid(values_valid):
    """(n_valid, 3) values on valid bins -> (90, 90, 180, 3) table, NaN elsewhere."""
    table = np.full((90, 90, 180, 3), np.nan)
    ih, jd, kd = valid_bins_3d()
    table[ih, jd, kd] = values_valid
    return table


# ----------------------------------------------------------------------------- slices
def check_slice(flash_slice):
    """Validate a flash slice: (90, 3) float, finite or NaN, ≥ 0. Returns float64 copy. InputError."""
    rho = np.array(flash_slice, dtype=float)
    if rho.shape != (90, 3):
        raise InputError("slice", f"expected 90 theta_h bins x 3 channels, got shape {rho.shape}")
    if np.isinf(rho).any():
        raise InputError("slice", "infinite BRDF value")
    if (rho < 0).any():
        raise InputError("slice", "negative BRDF value")
    if not np.isfinite(rho).all(axis=1).any():
        raise InputError("slice", "no theta_h bin has a sample")
    rho[~np.isfinite(rho).all(axis=1)] = np.nan
    return rho


def fill_slice(rho, offset=1e-3):
    """Fill empty θh bins of a checked slice by linear interpolation of ln(1 + ρ/offset) over the bin
    index (nearest value beyond the ends). For methods that need ρ at every θh; (90, 3) -> (90, 3)."""
    ok = np.isfinite(rho).all(axis=1)
    if ok.all():
        return rho.copy()
    idx = np.arange(90)
    out = np.empty_like(rho)
    for c in range(3):
        out[:, c] = np.interp(idx, idx[ok], np.log1p(rho[ok, c] / offset))
    return np.expm1(out) * offset


# ----------------------------------------------------------------------------- training set
@dataclass
class TrainingSet:
    """Training materials: names (N,), flash slices (N, 90, 3), 2D tables (N, 90, 90, 3), in 1/sr.

    3D tables are never all held in memory: `table_3d_valid(i)` reads one at a time, either from
    `paths` (MERL .binary files) or from `valid_3d` (N, n_valid, 3) stored rows (array or memmap).
    """
    names: list
    slices: np.ndarray
    tables_2d: np.ndarray
    paths: list = None
    valid_3d: np.ndarray = field(default=None, repr=False)

    def __len__(self):
        return len(self.names)

    @classmethod
    def from_merl_dir(cls, folder, names=None, keep_3d=False):
        """Read the MERL tables of `folder` (all, or those in `names`, in that order).
        keep_3d: also hold their valid 3D bins as float32 rows (N × 1.1 M × 3 × 4 B)."""
        found = dict(merl.list_merl(folder))
        if not found:
            raise InputError(folder, "no .binary MERL tables in this folder")
        names = list(found) if names is None else list(names)
        missing = [n for n in names if n not in found]
        if missing:
            raise InputError(folder, f"missing MERL tables: {', '.join(missing[:5])}")
        slices, tables, rows = [], [], []
        ih, jd, kd = valid_bins_3d()
        for n in names:
            table = merl.read_merl(found[n])
            slices.append(views.flash_slice(table)[0])
            tables.append(views.table_2d(table))
            if keep_3d:
                rows.append(table[ih, jd, kd].astype(np.float32))
        return cls(names, np.array(slices), np.array(tables), [found[n] for n in names],
                   np.array(rows) if keep_3d else None)

    @classmethod
    def from_merl_dirs(cls, folders, keep_3d=False):
        """Every MERL table of every folder in `folders` (a list of paths), folder by folder, in
        one set. Names must be unique across folders and no folder may be empty (InputError,
        checked before any table is read: brdf.merl.list_merl_dirs)."""
        merl.list_merl_dirs(folders)
        parts = [cls.from_merl_dir(f, keep_3d=keep_3d) for f in folders]
        return cls(names=[n for p in parts for n in p.names],
                   slices=np.concatenate([p.slices for p in parts]),
                   tables_2d=np.concatenate([p.tables_2d for p in parts]),
                   paths=[q for p in parts for q in p.paths],
                   valid_3d=np.concatenate([p.valid_3d for p in parts]) if keep_3d else None)

    def subset(self, index):
        index = list(index)
        return TrainingSet([self.names[i] for i in index], self.slices[index], self.tables_2d[index],
                           None if self.paths is None else [self.paths[i] for i in index],
                           None if self.valid_3d is None else self.valid_3d[index])

    def has_3d(self):
        return self.valid_3d is not None or self.paths is not None

    def table_3d_valid(self, i, dtype=np.float64):
        """ρ on the valid 3D bins of material i, (n_valid, 3) of `dtype`."""
        if self.valid_3d is not None:
            return np.asarray(self.valid_3d[i], dtype=dtype)
        if self.paths is None:
            raise InputError("--merl-dir", "3D prediction needs the training tables: give --merl-dir "
                             "or train with --views 1d,2d,3d")
        return merl.read_merl_bins(self.paths[i], valid_flat_3d(), dtype)


# ----------------------------------------------------------------------------- estimator base
class InferenceMethod(BaseEstimator):
    """Base of every method: fit(training) then predict(flash_slice, view) -> (table, variance).

    table: (90, 90, 3) for view "2d", (90, 90, 180, 3) for "3d", 1/sr, NaN where MERL has no data.
    variance: per-bin predictive variance in the method's feature space (same shape), or None.
    Methods whose 3D prediction is a weighted sum of training tables in some mapped space implement
    `combination(flash_slice)` -> (weights (N,), LinearSpace); the 3D table is then streamed.

    The scikit-learn contract: __init__ only stores its arguments (get_params/clone/set_params
    come from BaseEstimator), fit sets attributes ending in "_" and returns self, and never changes
    a constructor argument. Optional abilities are declared here, so callers ask for them instead
    of testing names:
    - evaluation_only: the method predicts from the true table (predict_truth), not from a slice;
    - closed_form_3d: predict_valid_3d(rho, sel) gives 3D bins directly, without training tables;
    - has_uncertainty: predict returns a per-bin variance (bin_variance).
    """
    name = "base"
    evaluation_only = False
    closed_form_3d = False
    has_uncertainty = False

    def fit(self, training):
        raise NotImplementedError

    def predict(self, flash_slice, view="2d"):
        rho = check_slice(flash_slice)
        if view == "2d":
            return self._predict_2d(rho)
        if view == "3d":
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
    workers = workers or int(os.environ.get("FLASHBRDF_THREADS") or min(os.cpu_count() or 1, 4))
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


ANCHOR_SMOOTHING_BINS = 2.0  # see anchor_to_slice; chosen in benchmarks, not on test data


def anchor_log_correction(first_row, flash_slice, smoothing_bins=None):
    """ln c (90, 3): the per-θh, per-channel correction that takes a predicted θd = 0 row
    `first_row` (90, 3) to the observed `flash_slice` (90, 3, NaN where empty), both in 1/sr.

    c = (ρ_obs + e) / (ρ_pred + e), e = brdf.colour.FEATURE_OFFSET, i.e. a shift in the ln(1 + ρ/e)
    feature space. Empty slice bins take ln c interpolated along θh (held constant beyond the
    observed range). ln c is then smoothed along θh with a Gaussian of `smoothing_bins` bins (None:
    ANCHOR_SMOOTHING_BINS): a bump of the prediction's θd = 0 row that its other rows lack is the
    blend's own artefact, and cancelling it bin by bin would stamp a dark line across every θd.
    0 makes the θd = 0 row pass exactly through the observation. None when no bin is observed.
    """
    from scipy.ndimage import gaussian_filter1d

    from brdf.colour import FEATURE_OFFSET as e
    if smoothing_bins is None:
        smoothing_bins = ANCHOR_SMOOTHING_BINS
    log_c = (np.log(np.asarray(flash_slice, dtype=float) + e)
             - np.log(np.maximum(np.asarray(first_row, dtype=float), 0.0) + e))
    known = np.isfinite(log_c).all(axis=1)
    if not known.any():
        return None
    bins = np.arange(90)
    log_c = np.stack([np.interp(bins, bins[known], log_c[known, c]) for c in range(3)], axis=1)
    if smoothing_bins > 0:
        log_c = gaussian_filter1d(log_c, smoothing_bins, axis=0, mode="nearest")
    return log_c


def apply_log_correction(rho, log_c):
    """ρ' = (ρ + e)·exp(ln c) − e, clamped ≥ 0, NaN kept; ρ (..., 3), ln c broadcastable to it."""
    from brdf.colour import FEATURE_OFFSET as e
    rho = np.asarray(rho, dtype=float)
    out = np.maximum((np.maximum(rho, 0.0) + e) * np.exp(log_c) - e, 0.0)
    out[np.isnan(rho)] = np.nan
    return out


def anchor_to_slice(table, flash_slice, smoothing_bins=None):
    """Correct a predicted table so that its θd = 0 row follows the observed slice, like Nöll et
    al.'s correction functions: anchor_log_correction of its θd = 0 row (the φd-mean for a 3D
    table), carried over every θd (and φd). table: (90, 90, 3) or (90, 90, 180, 3) in 1/sr, NaN
    where no data; flash_slice: (90, 3), NaN where empty. Returns a new table.
    """
    table = np.asarray(table, dtype=float)
    first = table[:, 0] if table.ndim == 3 else np.nanmean(table[:, 0], axis=1)
    log_c = anchor_log_correction(first, flash_slice, smoothing_bins)
    if log_c is None:
        return table.copy()
    return apply_log_correction(table, log_c.reshape((90, 1, 3) if table.ndim == 3 else (90, 1, 1, 3)))


class AnchoredSpace(LinearSpace):
    """Another method's combination space whose inverse also applies a θh correction ln c (90, 3)
    (anchor_log_correction), so streamed 3D predictions are anchored like the 2D ones."""

    def __init__(self, base, log_c):
        self.base, self.log_c = base, log_c
        self.clip_to_training = base.clip_to_training

    def forward(self, rho, sel=slice(None)):
        return self.base.forward(rho, sel)

    def inverse(self, mapped, sel=slice(None)):
        return apply_log_correction(self.base.inverse(mapped, sel),
                                    self.log_c[valid_bins_3d()[0][sel]])
