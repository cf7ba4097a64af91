"""Samples pooled over many photos with bounded memory (slice_extract.extract.collect_samples)."""

import numpy as np

from flashbrdf.brdf.angles import merl_bin_index
from flashbrdf.brdf.merl import N_THETA_H


# the key histogram's levels per bin (_smallest_keys_per_bin): a full bin's boundary level holds
# ~1/16384 of its samples
KEY_LEVELS = 1 << 14

SAMPLE_FIELDS = ("theta_h", "theta_d", "rho", "censored", "pixels", "face", "photo")


# once subsampling starts the store keeps what binning reads, compactly (binning works in float32)
COMPACT = {"theta_h": np.float32, "theta_d": np.float32, "rho": np.float32, "pixels": np.int32,
           "face": np.int32, "photo": np.int32, "key": np.float32,
           "log_gradient": np.float32}


class SampleStore:
    """The pooled samples of many photos, bounded: once more than options.sample_budget are held,
    every theta_h bin keeps a uniform random subset of at most options.max_samples_per_bin (each
    sample carries a random key and a bin keeps its smallest keys, so the subset is uniform over
    all the photos seen, whatever their order), stored compactly (float32). Below the budget it
    keeps every sample, in order and as given, so a capture of a few photos gives the slice it
    always gave. The subset is taken part by part (only the bins and keys are pooled), so memory
    peaks at the budget plus one photo's samples, not twice that."""

    def __init__(self, options, seed=0):
        self.budget, self.cap = options.sample_budget, options.max_samples_per_bin
        self.rng = np.random.default_rng(seed)
        self.parts, self.count, self.subsampled = [], 0, False
        # per bin, the largest key kept once the bin holds `cap` (inf before): a later sample
        # with a key at or above it can never be kept, so it is dropped on arrival, not sorted
        self.key_limit = np.full(N_THETA_H, np.inf, np.float32)

    def sieve(self, theta_h):
        """Before a photo's costly per-sample work (shadow rays): None below the budget (every
        sample is kept), else (wanted (M,) bool, keys (K,) float32 of the wanted samples), each
        sample's random key drawn now: one at or above its bin's limit could never be kept.
        Pass the keys on with the part (field "key"); samples dropped after this (shadowed) take
        theirs with them, so each bin's subset stays uniform over what it could keep."""
        if not self.subsampled:
            return None
        keys = self.rng.random(len(theta_h), np.float32)
        wanted = self._could_keep(keys, theta_h)
        return wanted, keys[wanted]

    def _could_keep(self, keys, theta_h):
        """(N,) bool: keys under their theta_h bin's limit (the others can never be kept)."""
        return keys < self.key_limit[merl_bin_index(theta_h, 0.0, 0.0)[0]]

    def add(self, part):
        """part: {field: array} of one photo's samples (SAMPLE_FIELDS, and "key" when sieved)."""
        if self.subsampled and "key" not in part:
            part = self._compact(part)
            wanted = self._could_keep(part["key"], part["theta_h"])
            if not wanted.all():
                part = {name: values[wanted] for name, values in part.items()}
        elif self.subsampled:  # sieved: its keys already passed their bins' limits
            part = self._compact(part)
        if len(part["theta_h"]):
            self.parts.append(part)
            self.count += len(part["theta_h"])
        if self.count > self.budget:
            self._keep_per_bin()

    def _compact(self, part):
        """The part in COMPACT dtypes, with its random keys."""
        if "key" not in part:
            part = {**part, "key": self.rng.random(len(part["theta_h"]), np.float32)}
        return {name: (values.astype(COMPACT[name], copy=False) if name in COMPACT else values)
                for name, values in part.items()}

    def _keep_per_bin(self):
        if not self.subsampled:
            self.parts = [self._compact(p) for p in self.parts]
            self.subsampled = True
        bins = np.concatenate([merl_bin_index(p["theta_h"], 0.0, 0.0)[0].astype(np.int16)
                               for p in self.parts])
        keys = np.concatenate([p["key"] for p in self.parts])
        keep = self._smallest_keys_per_bin(bins, keys)
        del bins, keys
        start, kept = 0, []
        for part in self.parts:
            mine = keep[start:start + len(part["theta_h"])]
            start += len(mine)
            if mine.any():
                kept.append({name: values[mine] for name, values in part.items()})
        self.parts = kept
        self.count = int(keep.sum())

    def _smallest_keys_per_bin(self, bins, keys):
        """(N,) bool: per bin the `cap` samples of smallest key, ties by position (what one
        stable sort by bin then key keeps), and each full bin's key limit updated. A histogram
        of quantised keys per bin finds the level where each bin reaches `cap` in one pass;
        only the samples on that level are sorted: a full sort of every held sample, once per
        photo or two past the budget, was a tenth of a 30-view full-resolution extraction."""
        level = np.minimum((keys * np.float32(KEY_LEVELS)).astype(np.int32), KEY_LEVELS - 1)
        cumulative = np.cumsum(np.bincount(bins.astype(np.int32) * KEY_LEVELS + level,
                                           minlength=N_THETA_H * KEY_LEVELS
                                           ).reshape(N_THETA_H, KEY_LEVELS), axis=1)
        full = cumulative[:, -1] >= self.cap
        boundary = np.where(full, np.argmax(cumulative >= self.cap, axis=1), KEY_LEVELS)
        below = np.where(full & (boundary > 0),
                         cumulative[np.arange(N_THETA_H), np.maximum(boundary - 1, 0)], 0)
        keep = level < boundary[bins]
        tied = np.flatnonzero(level == boundary[bins])  # only full bins have such a level
        tied = tied[np.lexsort((keys[tied], bins[tied]))]  # stable: ties stay in position order
        first = np.searchsorted(bins[tied], np.arange(N_THETA_H))
        rank = np.arange(len(tied)) - first[bins[tied]]
        need = self.cap - below  # what each full bin takes from its boundary level (>= 1)
        keep[tied[rank < need[bins[tied]]]] = True
        self.key_limit[full] = keys[tied[first[full] + need[full] - 1]]
        return keep

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
