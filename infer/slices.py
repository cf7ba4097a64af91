"""Flash slices as every method takes them: checked, and filled where a method needs every bin.

A flash slice is ρ(θh) at θd bin 0 in 1/sr, shape (90, 3) over MERL's θh bins (brdf.merl), NaN
where the bin is empty (missing data, never 0).
"""

import numpy as np

from flashbrdf.files.errors import InputError
from flashbrdf.brdf.merl import N_THETA_H, theta_h_centres


def check_slice(flash_slice):
    """Validate a flash slice: (90, 3) float, finite or NaN, ≥ 0. Returns float64 copy. InputError."""
    rho = np.array(flash_slice, dtype=float)
    if rho.shape != (N_THETA_H, 3):
        raise InputError("slice", f"expected {N_THETA_H} theta_h bins x 3 channels, got shape "
                                  f"{rho.shape}")
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
    idx = np.arange(N_THETA_H)
    out = np.empty_like(rho)
    for c in range(3):
        out[:, c] = np.interp(idx, idx[ok], np.log1p(rho[ok, c] / offset))
    return np.expm1(out) * offset


# The last θh bins a photo fills lie on its periphery: the grazing rim of a curved object, the far
# corners of a flat one. There the pixel model is least exact (silhouette mixing, normal error,
# vignetting, the flash's cone) and a bin's few pixels come from one patch, so they do not average
# it out. Anchoring (infer.anchoring) carries the last observed bin's correction over every θh
# past it, so that one bin would set the whole unobserved tail. 20 samples is the count below
# which the issue's own checks call a bin incomparable; on the planar cards' view 00 any count
# from 10 to 100 trims the same bins (docs/results.md, one-off: sparse_tail). A small photo (or a
# small material region) has few samples in every bin: there "sparse" is relative, a quarter of
# the fullest bin's count, so a 450-sample slice is not half thrown away.
MIN_TAIL_SAMPLES = 20


def tail_threshold(n, min_samples=MIN_TAIL_SAMPLES):
    """The sample count (float) below which a peripheral θh bin is sparse: min_samples, or a
    quarter of the fullest bin's count when that is smaller. n (90,) counts."""
    return float(min(min_samples, np.max(n) / 4.0)) if np.size(n) else float(min_samples)


def sparse_tail(n, min_samples=MIN_TAIL_SAMPLES):
    """(90,) bool: the θh bins past the last one holding ≥ tail_threshold(n) samples, among those
    that hold any. n (90,) sample counts per bin (the slice.csv `n`). None of them when n is None
    or holds no sample."""
    if n is None:
        return np.zeros(N_THETA_H, dtype=bool)
    n = np.asarray(n)
    tail = np.zeros(N_THETA_H, dtype=bool)
    if not (n > 0).any():
        return tail
    well = np.flatnonzero(n >= tail_threshold(n, min_samples))
    tail[well[-1] + 1:] = n[well[-1] + 1:] > 0
    return tail


def sample_counts(rho, n):
    """n (90,) with 0 for every bin whose value is missing (a bin with no value holds no sample,
    whatever its n says), or None when n is None. rho (90, 3), NaN where empty. Pass these counts
    to sparse_tail_record and sparse_tail_note, so that they tell the threshold that was used."""
    if n is None:
        return None
    return np.where(np.isfinite(np.asarray(rho, dtype=float)).all(axis=1), np.asarray(n), 0)


def without_sparse_tail(rho, n, min_samples=MIN_TAIL_SAMPLES):
    """(rho (90, 3) with the sparse_tail bins emptied (NaN), their θh bin indices (list of int)):
    the slice inference reads. rho in 1/sr, NaN where empty; n (90,) counts or None. A bin whose
    value is missing counts as holding no sample, whatever its n says (sample_counts)."""
    rho = np.array(rho, dtype=float)
    n = sample_counts(rho, n)
    tail = sparse_tail(n, min_samples)
    rho[tail] = np.nan
    return rho, [int(i) for i in np.flatnonzero(tail)]


def sparse_tail_record(ignored, n):
    """The BRDF.json entry for the bins without_sparse_tail emptied: None when none were, else
    {"min_samples": the threshold used, "theta_h_deg": [bin centres], "n": [their counts]}."""
    if not ignored:
        return None
    centres = np.degrees(theta_h_centres())
    return {"min_samples": tail_threshold(n), "theta_h_deg": [float(centres[i]) for i in ignored],
            "n": [int(n[i]) for i in ignored]}


MAX_COUNTS_LISTED = 6  # sparse_tail_note lists the counts of at most this many bins


def sparse_tail_note(ignored, n):
    """One line for the terminal and the report about the bins without_sparse_tail emptied."""
    centres = np.degrees(theta_h_centres())
    where = (f"{centres[ignored[0]]:.1f} deg" if len(ignored) == 1 else
             f"{centres[ignored[0]]:.1f}-{centres[ignored[-1]]:.1f} deg")
    counts = [int(n[i]) for i in ignored]
    # a handful of counts, each; more, their range (89 of them made a 500-character line)
    told = (", ".join(map(str, counts)) + " samples" if len(counts) <= MAX_COUNTS_LISTED else
            f"{counts[0]} sample{'s' * (counts[0] != 1)} each" if min(counts) == max(counts) else
            f"{min(counts)} to {max(counts)} samples")
    return (f"note: {len(ignored)} theta_h bin(s) past the last one of >= {tail_threshold(n):g} "
            f"samples ({where}, {told}) lie on the photo's periphery; inference treats them as "
            "missing")
