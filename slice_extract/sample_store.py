"""Samples pooled over many photos with bounded memory (slice_extract.extract.collect_samples)."""

import numpy as np

from flashbrdf.brdf.angles import merl_bin_index
from flashbrdf.brdf.merl import N_THETA_H


SAMPLE_FIELDS = ("theta_h", "theta_d", "rho", "censored", "pixels", "face", "photo")


class SampleStore:
    """The pooled samples of many photos, bounded: once more than options.sample_budget are held,
    every theta_h bin keeps a uniform random subset of at most options.max_samples_per_bin (each
    sample carries a random key and a bin keeps its smallest keys, so the subset is uniform over
    all the photos seen, whatever their order). Below the budget it keeps every sample, in
    order, so a capture of a few photos gives the slice it always gave."""

    def __init__(self, options, seed=0):
        self.budget, self.cap = options.sample_budget, options.max_samples_per_bin
        self.rng = np.random.default_rng(seed)
        self.parts, self.count, self.subsampled = [], 0, False

    def add(self, part):
        """part: {field: array} of one photo's samples (SAMPLE_FIELDS)."""
        if len(part["theta_h"]):
            self.parts.append(part)
            self.count += len(part["theta_h"])
        if self.count > self.budget:
            self._keep_per_bin()

    def _keep_per_bin(self):
        pooled = self._concatenated()
        bins = merl_bin_index(pooled["theta_h"], 0.0, 0.0)[0]
        keys = pooled.get("key")
        if keys is None:
            keys = self.rng.random(len(bins))
        order = np.lexsort((keys, bins))
        sorted_bins = bins[order]
        first_of_bin = np.searchsorted(sorted_bins, np.arange(N_THETA_H))
        rank = np.arange(len(order)) - first_of_bin[sorted_bins]
        keep = np.zeros(len(bins), bool)
        keep[order[rank < self.cap]] = True
        self.parts = [{name: values[keep] for name, values in {**pooled, "key": keys}.items()}]
        self.count = int(keep.sum())
        self.subsampled = True

    def add_keys(self, part):
        """A part's random keys, once subsampling has started (later parts need them too)."""
        return {**part, "key": self.rng.random(len(part["theta_h"]))}

    def pooled(self):
        """{field: array} of the samples kept (SAMPLE_FIELDS): all of them below the budget,
        else each bin's subset."""
        if self.subsampled:
            self._keep_per_bin()
        return {name: values for name, values in self._concatenated().items() if name != "key"}

    def _concatenated(self):
        if not self.parts:
            return {"theta_h": np.zeros(0), "theta_d": np.zeros(0), "rho": np.zeros((0, 3)),
                    "censored": np.zeros(0, bool), "pixels": np.zeros(0, int),
                    "face": np.zeros(0, np.int32), "photo": np.zeros(0, int)}
        names = [n for n in self.parts[0] if all(n in p for p in self.parts)]
        return {n: (self.parts[0][n] if len(self.parts) == 1
                    else np.concatenate([p[n] for p in self.parts])) for n in names}
