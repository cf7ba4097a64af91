"""segment: a flash photo's pixels labelled by material: labels 1..K per object pixel, 0 elsewhere.

Modules: features (per-sample features, per-bin statistics), slices (the k-slice model and its
residuals), interreflection (non-convex surface, alike merge), clustering (mixture, K, tests),
labels (ring names, clean-up, borders, label checks, per-face labels), segmentation (the entry
point, segment_samples).

Segment a flash photo into materials: labels 1..K per object pixel, 0 elsewhere.

Why here: segmentation reads exactly what extraction reads, each flash pixel's BRDF sample
rho = pixel r^2 / (I cos theta_i) at its theta_h (slice_extract.samples), so it lives beside it
and shares its traced samples (slice_extract.extract.collect_samples); no other stage is needed.

What separates materials is what the photo says about the material, not about shading:
- features (material_features): the chromaticity of rho, r/(r+g+b) and g/(r+g+b), and
  ln(r+g+b) of rho. rho has cos(theta_i)/r^2 divided out, so away from the specular lobe it is
  the material's albedo; inside the lobe (theta_h bins where the per-bin median of ln rho rises
  above its off-lobe level) ln rho is taken relative to that median, so a highlight does not
  become a material of its own. The mixture is fitted on off-lobe pixels where there are enough.
- clustering (scikit-learn GaussianMixture, full covariances, on a subsample): K from 1 to
  max_materials by BIC; then components that are not distinct materials are merged: a pair
  whose means are closer than `separation` pooled standard deviations (Mahalanobis, the
  pair's mean covariance) is one material, and so is a component holding less than
  `min_fraction` of the pixels. A single material's non-Gaussian spread is what makes BIC
  split it; the separation test undoes that, so one material gives K = 1.
- refinement ("k slices"): each pixel goes to the material whose slice (per-bin median of
  ln rho per channel, filled across empty bins) explains its sample best; that fixes highlight
  pixels, whose colour alone is ambiguous. "Explains" (residuals) weighs the sample's
  brightness offset from the slice BRIGHTNESS_WEIGHT times its colour offset: within one
  material brightness varies pixel to pixel (texture, glitter, bumps), colour far less.
- the stated criterion for K > 1: every material but the largest must be explained clearly
  better by its own slice than by the one-slice model of the whole object: the mean residual
  (residuals, capped at 1 per pixel) of its pixels at most `explained` times as large.
  (A material only slightly better explained is a shading or noise split of one material.)
  Or, where two materials share the theta_h bins, its partner must be explained by its own
  slice at most `explained`/2 times as badly as by the two's joint slice (_partner_ratio).
  The alike merge also takes for one material a brighter one that is the other plus its own
  colour squared (interreflection_gaps: light come back after one more bounce on it, in a dent,
  a fold, a bowl), when most of the brighter's pixels lie where the surface can see itself
  (nonconvex_mask, from the normals): interreflection is not in the pixel model, and a coloured
  metal lights its own concavities many times brighter and deeper in colour.
  This test and the alike merge read, for each pixel of the work subsample, the sample 2 px away
  (neighbour_samples) under the pixel's label, so the noise that chose a label is not read back
  as a difference; and they read ln rho above the photo's resolution floor (resolution_floor:
  where an 8-bit or JPEG file holds a channel in a few codes), so quantisation and block
  errors in a metal's dark pixels are not read as colour.
- the last assignment of every pixel (assign_all) first takes off a flash-coloured (white)
  highlight term where the pixel is brighter than a coloured material's slice (added_white,
  dichromatic model): a foil's highlight no longer passes for a paler material.
- names across theta_h rings (align_bin_labels): the assignment decides bin by bin, so where
  two materials' names came out exchanged over some rings, the pixels adjacent across the
  rings' edges put them back.
- spatial clean-up (OpenCV connected components and labelled distance transform): patches
  smaller than `min_area_fraction` of the object merge into the nearest larger patch (unless
  the photo's frame cuts them, or the material has no larger patch: a pattern of dots), and
  object pixels without a sample (silhouette ring, grazing, clipped, shadowed) take the
  nearest label.

Labels are numbered by decreasing pixel count (1 = the largest material).
"""

from flashbrdf.slice_extract.segment.clustering import (Segmentation, SegmentOptions,
                                                        cluster_samples)
from flashbrdf.slice_extract.segment.features import material_features, resolution_floor
from flashbrdf.slice_extract.segment.interreflection import (interreflection_gaps,
                                                             nonconvex_mask, normal_noise)
from flashbrdf.slice_extract.segment.labels import (BORDER_MIN_BIN, align_bin_labels,
                                                    border_width_px, check_labels,
                                                    clean_label_image, face_label_agreement,
                                                    face_labels, material_interior)
from flashbrdf.slice_extract.segment.segmentation import (coarse_faces_warning, segment_samples,
                                                          segment_scene)

__all__ = ["BORDER_MIN_BIN", "Segmentation", "SegmentOptions", "align_bin_labels",
           "border_width_px", "check_labels", "clean_label_image", "cluster_samples",
           "coarse_faces_warning", "face_label_agreement", "face_labels", "interreflection_gaps",
           "material_features", "material_interior", "nonconvex_mask", "normal_noise",
           "resolution_floor", "segment_samples", "segment_scene"]
