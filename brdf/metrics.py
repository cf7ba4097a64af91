"""The paper's error metrics (Table 1 and Table 2), exactly as the contract defines them.

epsilon(x) is `lin` (x), `root` (sqrt x) or `log` (ln(1 + x)), applied to rho clamped to >= 0.
- RGB error: mean over valid bins of the mean over channels of |eps(pred) - eps(true)|.
- LAB error: mean over valid bins of Delta E*ab (CIE 1976) between the CIELAB colours of the
  triplets eps(pred) and eps(true), read as linear sRGB, D65 white at Y = 1.
Valid bins are those where the ground truth is finite; a NaN prediction there counts as 0.
"""

import numpy as np

from flashbrdf.brdf.colour import lab_to_linear_rgb, linear_rgb_to_lab

TRANSFORMS = ("lin", "root", "log")
SPACES = ("rgb", "lab")
_EPSILON = {"lin": lambda x: x, "root": np.sqrt, "log": np.log1p}


def _valid_pairs(pred, true):
    pred = np.asarray(pred, dtype=np.float64)
    true = np.asarray(true, dtype=np.float64)
    if pred.shape != true.shape or pred.shape[-1] != 3:
        raise ValueError(f"shapes differ or are not (..., 3): {pred.shape} vs {true.shape}")
    valid = np.all(np.isfinite(true), axis=-1)
    return _clean_pred(pred[valid]), np.maximum(true[valid], 0.0)


def _clean_pred(p):
    """A prediction's values on the valid bins: NaN/inf count as 0, negatives as 0."""
    return np.where(np.isfinite(p), np.maximum(p, 0.0), 0.0)


def _mean_delta_e(lab_p, lab_t):
    """Mean CIE 1976 ΔE*ab between two (n, 3) CIELAB arrays."""
    return float(np.mean(np.linalg.norm(lab_p - lab_t, axis=-1)))


def _error(p, t, transform, space):
    ep, et = _EPSILON[transform](p), _EPSILON[transform](t)
    if space == "rgb":
        return float(np.mean(np.abs(ep - et)))
    if space == "lab":
        return _mean_delta_e(linear_rgb_to_lab(ep), linear_rgb_to_lab(et))
    raise ValueError(f"unknown colour space {space!r}")


def brdf_error(pred, true, transform="log", space="lab"):
    """One Table 1 error between two BRDFs of the same shape (..., 3) in 1/sr: a float."""
    if transform not in _EPSILON:
        raise ValueError(f"unknown transform {transform!r}")
    p, t = _valid_pairs(pred, true)
    if t.size == 0:
        return float("nan")
    return _error(p, t, transform, space)


def lab_log_reference(true):
    """What brdf_error(·, true, "log", "lab") computes of the truth alone, for scoring many
    predictions against one truth (a fit's cost function): (valid mask (...), its CIELAB (n, 3))."""
    true = np.asarray(true, dtype=np.float64)
    valid = np.all(np.isfinite(true), axis=-1)
    return valid, linear_rgb_to_lab(np.log1p(np.maximum(true[valid], 0.0)))


def lab_log_error(pred, reference):
    """brdf_error(pred, true, "log", "lab") with reference = lab_log_reference(true), to the last
    bit: the same operations on the same arrays, the truth's half done once."""
    valid, lab_true = reference
    if not len(lab_true):
        return float("nan")
    p = _clean_pred(np.asarray(pred, dtype=np.float64)[valid])
    return _mean_delta_e(linear_rgb_to_lab(np.log1p(p)), lab_true)


def brdf_errors(pred, true):
    """All six Table 1 errors: {"rgb_lin", "rgb_root", "rgb_log", "lab_lin", "lab_root", "lab_log"}."""
    p, t = _valid_pairs(pred, true)
    return {f"{space}_{transform}": (_error(p, t, transform, space) if t.size else float("nan"))
            for space in SPACES for transform in TRANSFORMS}


def summarise(values):
    """{"mean", "median"} of per-material errors, ignoring NaN."""
    values = np.asarray(values, dtype=np.float64)
    values = values[np.isfinite(values)]
    if values.size == 0:
        return {"mean": float("nan"), "median": float("nan")}
    return {"mean": float(np.mean(values)), "median": float(np.median(values))}


def lab_log_features(rho):
    """CIELAB of ln(1 + rho): the LAB-log metric's space, where its Delta E is Euclidean.

    rho: (..., 3) linear RGB (1/sr, or pixel values), clamped to >= 0; NaN stays NaN.
    Returns (..., 3) float64."""
    return linear_rgb_to_lab(np.log1p(np.maximum(np.asarray(rho, dtype=np.float64), 0.0)))


def rho_from_lab_log(features):
    """rho >= 0 (..., 3) of lab_log_features, its inverse (exp clipped short of overflow)."""
    return np.maximum(np.expm1(np.minimum(lab_to_linear_rgb(features), 700.0)), 0.0)


def delta_e_log(pred, ref):
    """Per-element Delta E*ab between CIELAB(ln(1 + pred)) and CIELAB(ln(1 + ref)).

    pred, ref: (..., 3) linear RGB (pixels or BRDF values), clamped to >= 0. Returns (...).
    This is Table 2's render metric.
    """
    return np.linalg.norm(lab_log_features(pred) - lab_log_features(ref), axis=-1)
