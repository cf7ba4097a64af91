"""slice_extract: from flash pixels and known geometry to the 1D BRDF slice rho(theta_h).

Takes a capture folder (or capture.Scene): flash photos, camera, geometry.
Gives the 90-bin theta_d ~ 0 slice with a robust per-bin estimate, sample counts, spread and a
coverage report; written as the contract's `slice.csv` plus a JSON sidecar (slice_extract.slice_files).

Public API:
  extract_slice(scene_dir_or_scene, options=None) -> SliceResult(rho (90, 3), n (90,),
      spread (90, 3), report dict: coverage, rejected, theta_d_deg, photos, timings_s)
  ExtractOptions(max_theta_d_deg=5.0, min_cos=0.1, outlier_k=3.0, estimator="trimmed_mean",
                 shadow_rays=True, silhouette_px=1, chunk_pixels=2**20)
  robust_bins(bin_index, rho, censored=None, theta_h=None, k=3.0, rel_floor=1e-3,
              estimator="trimmed_mean", n_bins=90, photo=None)
      -> estimate (90, 3), n (90,), spread (90, 3), inlier (N,)
  collect_samples(scene, options=None) -> FlashSamples (every flash pixel's sample, pooled)
  bin_samples(samples) -> SliceResult   # extract_slice = bin_samples(collect_samples(...))
  extract_material_slices(samples, labels (H, W), where, face_labels (F,) or None)
      -> {k: SliceResult or None}   # other views' samples labelled through their mesh faces
  slice_extract.segment.segment_samples(samples, materials="auto"|K) -> Segmentation(labels
      (H, W) uint16, k, criterion); face_labels(labels, face_image, centroids)
  half_diff_thetas(wi, wo, normal) -> theta_h, theta_d
  silhouette_mask(object_mask, width_px) -> (H, W) bool
"""

from flashbrdf.slice_extract.binning import robust_bins
from flashbrdf.slice_extract.extract import (ExtractOptions, FlashSamples, SliceResult, bin_samples,
                                             collect_samples, extract_material_slices,
                                             extract_slice)
from flashbrdf.slice_extract.visibility import silhouette_mask
from flashbrdf.slice_extract.samples import half_diff_thetas

__all__ = ["ExtractOptions", "FlashSamples", "SliceResult", "bin_samples", "collect_samples",
           "extract_material_slices", "extract_slice", "half_diff_thetas", "robust_bins",
           "silhouette_mask"]
