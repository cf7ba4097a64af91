"""3D Table 1 metrics without holding 3D tables in memory: a float32 cache of every material's valid
3D bins on disk (memmap, N × 1.1 M × 3), read in bin chunks; every method's 3D prediction for every
test material is formed chunk by chunk (linear methods as weights × mapped training rows) and the
contract metrics (brdf.metrics.brdf_errors) are accumulated as count-weighted chunk means.
"""

import os
from typing import NamedTuple

import numpy as np

from flashbrdf.brdf import colour, merl, metrics
from flashbrdf.infer.baselines import dual_weights
from flashbrdf.infer.training_set import fill_missing_3d
from flashbrdf.brdf.bins import valid_bins_3d
from flashbrdf.infer.estimator import clip_to_range

CHUNK = 131_072  # bins per chunk: 60 training rows × 131 k × 3 × 8 B ≈ 190 MB


class RowsView:
    """Lazy row subset of a (N, n_valid, 3) array/memmap: rows[i] reads one material."""

    def __init__(self, array, index):
        self.array, self.index = array, np.asarray(index)

    def __len__(self):
        return len(self.index)

    def __getitem__(self, i):
        if np.ndim(i):
            return RowsView(self.array, self.index[np.asarray(i)])
        return self.array[self.index[i]]


class Cache3D(NamedTuple):
    """build_cache's result: the rows (training's, no-data bins filled) and the filled bins."""
    rows: np.ndarray
    holes: dict


def holes_file(filename):
    """The cache's record of no-data bins, beside it."""
    return filename + ".holes.npz"


def build_cache(paths, filename, tables_2d):
    """Write ρ on the valid bins of every MERL table in `paths` to a float32 memmap, no-data
    bins filled as training fills them (infer.training_set.fill_missing_3d from the filled 2D
    tables_2d (N, 90, 90, 3)), and which bins those were beside it (holes_file). Returns
    Cache3D(rows (N, n_valid, 3) memmap, holes {material index: flat indices of its no-data
    valid bins})."""
    ih, jd, kd = valid_bins_3d()
    shape = (len(paths), len(ih), 3)
    if os.path.exists(filename) and os.path.getsize(filename) == np.prod(shape) * 4 and \
            os.path.exists(holes_file(filename)):
        with np.load(holes_file(filename)) as z:
            holes = {int(k): z[k] for k in z.files}
        return Cache3D(np.memmap(filename, np.float32, "r", shape=shape), holes)
    rows = np.memmap(filename + ".part", np.float32, "w+", shape=shape)
    holes = {}
    for i, path in enumerate(paths):
        raw = merl.read_merl(path)[ih, jd, kd]
        missing = ~np.isfinite(raw).all(axis=-1)
        if missing.any():
            holes[i] = np.flatnonzero(missing)
            raw = fill_missing_3d(raw, tables_2d[i])
        rows[i] = raw
    rows.flush()
    del rows
    with open(holes_file(filename) + ".part", "wb") as f:
        np.savez(f, **{str(i): v for i, v in holes.items()})
    os.replace(holes_file(filename) + ".part", holes_file(filename))
    os.replace(filename + ".part", filename)
    return Cache3D(np.memmap(filename, np.float32, "r", shape=shape), holes)


def _chunks(n_valid, chunk, stride):
    """Bin selections over the valid 3D bins: contiguous slices, or every `stride`-th φd bin."""
    if stride == 1:
        return [slice(start, min(start + chunk, n_valid)) for start in range(0, n_valid, chunk)]
    bins = np.flatnonzero(valid_bins_3d()[2] % stride == 0)
    return [bins[start:start + chunk] for start in range(0, len(bins), chunk)]


def _oracle_weights(cache, oracle, train, test, chunks):
    space = oracle.space_3d()
    idx = np.concatenate([train, test])
    raw = np.zeros((len(idx), len(idx)))
    for sel in chunks:
        m = space.forward(np.asarray(cache[idx][:, sel] if not isinstance(sel, slice)
                                     else cache[idx, sel], float), sel).reshape(len(idx), -1)
        raw += m @ m.T
    n = len(train)
    return np.array([dual_weights(raw[:n, :n], raw[:n, n + t], oracle.ridge)
                     for t in range(len(test))]), space


_EPS = {"lin": lambda x: x, "root": np.sqrt, "log": np.log1p}


def _transformed(rho):
    """{transform: (ε(ρ) (n,3), Lab(ε(ρ)) (n,3))} of ρ clamped ≥ 0 (NaN -> 0), as brdf.metrics."""
    rho = np.where(np.isfinite(rho), np.maximum(rho, 0.0), 0.0)
    out = {}
    for t in metrics.TRANSFORMS:
        e = _EPS[t](rho)
        out[t] = (e, colour.linear_rgb_to_lab(e))
    return out


def _error_sums(pred_t, true_t):
    """Sums over bins of the per-bin Table 1 errors (brdf.metrics' formulas) -> {key: float}."""
    out = {}
    for t in metrics.TRANSFORMS:
        out[f"rgb_{t}"] = float(np.abs(pred_t[t][0] - true_t[t][0]).mean(axis=-1).sum())
        out[f"lab_{t}"] = float(np.linalg.norm(pred_t[t][1] - true_t[t][1], axis=-1).sum())
    return out


def evaluate_3d(cache, train, test, methods, slices, chunk=CHUNK, stride=1, holes=None):
    """3D errors {method: [brdf_errors dict per test material]}.

    cache: (N_all, n_valid, 3) rows; train/test: index arrays into it; methods: {name: fitted
    method} (trained on the `train` rows); slices: (T, 90, 3) test flash slices. stride > 1 keeps
    every stride-th φd bin only (quick smoke runs). holes: {row: flat valid-bin indices} whose
    cached values were filled (build_cache): not scored. Errors equal brdf.metrics.brdf_errors on
    the same bins (the truth's ε and Lab are computed once per chunk and shared by all methods).
    """
    holes = holes or {}
    chunks = _chunks(cache.shape[1], chunk, stride)
    plans = {}
    for name, m in methods.items():
        if m.evaluation_only:
            plans[name] = ("linear",) + _oracle_weights(cache, m, train, test, chunks) + (None,)
        elif m.closed_form_3d:
            plans[name] = ("direct", m)
        else:
            combos = [m.combination(s) for s in slices]
            spaces = [c[1] for c in combos]
            plans[name] = ("linear", np.array([c[0] for c in combos]), spaces[0], spaces)
    sums = {name: [dict.fromkeys(metrics_keys(), 0.0) for _ in test] for name in methods}
    counts = np.zeros(len(test))
    for sel in chunks:
        read = (lambda rows: cache[rows, sel]) if isinstance(sel, slice) else \
            (lambda rows: cache[rows][:, sel])
        true = np.asarray(read(test), np.float64)
        ok = np.isfinite(true).all(axis=-1)
        for t, row in enumerate(test):
            if int(row) in holes:
                ok[t] &= ~_in_chunk(holes[int(row)], sel, ok.shape[1])
        counts += ok.sum(axis=1)
        true_t = [_transformed(true[t][ok[t]]) for t in range(len(test))]
        x_train = np.asarray(read(train), np.float64)
        for name, plan in plans.items():
            if plan[0] == "direct":
                preds = [plan[1].predict_valid_3d(s, sel) for s in slices]
            else:
                _, weights, space, spaces = plan
                mapped = space.forward(x_train, sel).reshape(len(train), -1)
                combined = weights @ mapped
                if space.clip_to_training:   # as stream_combination does for these methods
                    combined = clip_to_range(combined, mapped.min(axis=0), mapped.max(axis=0))
                combined = combined.reshape(len(test), -1, 3)
                preds = [(spaces[t] if spaces else space).inverse(combined[t], sel)
                         for t in range(len(test))]
            for t, pred in enumerate(preds):
                for k, v in _error_sums(_transformed(pred[ok[t]]), true_t[t]).items():
                    sums[name][t][k] += v
    return {name: [{k: v / max(counts[t], 1) for k, v in per.items()} for t, per in enumerate(s)]
            for name, s in sums.items()}


def _in_chunk(flat, sel, size):
    """(size,) bool: which bins of the chunk `sel` (a slice or index array of valid bins) are in
    the sorted flat indices `flat`."""
    if isinstance(sel, slice):
        out = np.zeros(size, bool)
        inside = flat[(flat >= sel.start) & (flat < sel.stop)]
        out[inside - sel.start] = True
        return out
    return np.isin(sel, flat)


def metrics_keys():
    return tuple(f"{s}_{t}" for s in metrics.SPACES for t in metrics.TRANSFORMS)
