"""The options of slice extraction (slice_extract.extract): what a caller may set, with the
ranges each must lie in."""

from dataclasses import dataclass


@dataclass(frozen=True)
class ExtractOptions:
    max_theta_d_deg: float = 5.0
    min_cos: float = 0.1
    outlier_k: float = 3.0
    estimator: str = "trimmed_mean"  # or "median"
    shadow_rays: bool = True  # False only to diagnose (or to show what shadows would cost)
    silhouette_px: int = 1  # reject pixels this close to the object's outline (0: keep them)
    chunk_pixels: int = 1 << 20  # pixels traced per batch: bounds memory, keeps arrays in cache
    # Many photos at full resolution (30 x 24 MP) give far more samples than a bin needs: past
    # sample_budget pooled samples, each theta_h bin keeps a uniform random subset of at most
    # max_samples_per_bin (its robust estimate moves by ~1/sqrt(80,000) of its spread), so
    # memory stays bounded whatever the number of photos. Below the budget nothing is dropped.
    sample_budget: int = 8_000_000
    max_samples_per_bin: int = 80_000
    # an inner occluding contour (a depth jump between neighbouring pixels steeper than
    # atan(depth_edge_slope) ~ 87 deg) is rejected like the outline: a pose a pixel off puts
    # the surface behind, or the background, there (0: off)
    depth_edge_slope: float = 20.0
    # refine each flash view's pose against the pooled slice first (pose_refine.py):
    # a pose a pixel off blurs the specular lobe; costs up to 3 more passes over the photos
    refine_poses: bool = False
    # each sample also carries grad ln I at its pixel (pose_refine.log_gradient), for the
    # refinement's passes: they then read every photo once
    log_gradients: bool = False

    def __post_init__(self):
        """ValueError naming the first option out of its range (the command line checks its
        flags before, naming them)."""
        rules = (("max_theta_d_deg", 0 < self.max_theta_d_deg <= 90, "degrees in (0, 90]"),
                 ("min_cos", 0 <= self.min_cos < 1, "a value in [0, 1)"),
                 ("outlier_k", self.outlier_k > 0, "a positive number of sigmas"),
                 ("estimator", self.estimator in ("trimmed_mean", "median"),
                  "'trimmed_mean' or 'median'"),
                 ("silhouette_px", self.silhouette_px >= 0, "pixels >= 0"),
                 ("chunk_pixels", self.chunk_pixels >= 1, "at least 1"),
                 ("sample_budget", self.sample_budget >= 1, "at least 1"),
                 ("max_samples_per_bin", self.max_samples_per_bin >= 1, "at least 1"),
                 ("depth_edge_slope", self.depth_edge_slope >= 0, "a slope >= 0 (0: off)"))
        for name, ok, expected in rules:
            if not ok:
                raise ValueError(f"ExtractOptions.{name}: expected {expected}, got "
                                 f"{getattr(self, name)!r}")
