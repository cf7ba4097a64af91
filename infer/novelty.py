"""Whether a flash slice lies outside what a fitted method was trained on, and the warning to print."""

import numpy as np

from flashbrdf.brdf import merl
from flashbrdf.infer.slice_fit import OUT_OF_TRAINING_NOVELTY


MIN_OBSERVED_BINS = 5          # fewer observed θh bins than this: the slice's shape is a guess
MAX_FIRST_THETA_H_DEG = 60.0   # no observed bin below this: the lobe and the diffuse level are unseen


def novelty_warning(method, flash_slice, source="slice"):
    """(novelty score or None, one-line warning or None) for a fitted method and a (90, 3) slice.

    It warns when the slice lies outside the training data (method.novelty > 1), or when it says too
    little to place it at all (fewer than MIN_OBSERVED_BINS bins, or none below
    MAX_FIRST_THETA_H_DEG): the prediction then extrapolates, and its uncertainty is larger than the
    training materials suggest."""
    rho = np.asarray(flash_slice, dtype=float)
    seen = np.isfinite(rho).all(axis=1)
    score = method.novelty(rho)
    reasons = []
    if score is not None and np.isfinite(score) and score > OUT_OF_TRAINING_NOVELTY:
        reasons.append(f"novelty {score:.2f}: farther from every training slice than 99% of them "
                       f"are from their nearest neighbour")
    theta_h = np.degrees(merl.theta_h_centres())
    if seen.sum() < MIN_OBSERVED_BINS or not (seen & (theta_h < MAX_FIRST_THETA_H_DEG)).any():
        first = theta_h[seen].min() if seen.any() else float("nan")
        reasons.append(f"only {int(seen.sum())} theta_h bins observed, the first at {first:.0f} deg")
    if not reasons:
        return score, None
    return score, (f"warning: {source}: the slice lies outside what the model was trained on ("
                   + "; ".join(reasons) + "); the prediction extrapolates")
