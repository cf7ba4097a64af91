"""Compatibility only: the names infer.common used to hold, now each in the module of its concern.

- brdf.bins: MERL bin geometry (valid_bins_3d, valid_flat_3d, valid_mask_2d, cos_in_out,
  cos_in_out_valid, mean_over_phi_d, scatter_valid);
- infer.slices: check_slice, fill_slice;
- infer.training_set: TrainingSet;
- infer.estimator: InferenceMethod, LinearSpace, stream_combination, clip_to_range;
- infer.anchoring: anchor_log_correction, apply_log_correction, anchor_to_slice, AnchoredSpace.

Import from those. This module is kept so that branches written against the old layout still
import while they are merged; nothing in this tree imports it.
"""

from brdf.bins import (cos_in_out, cos_in_out_valid, mean_over_phi_d, scatter_valid,  # noqa: F401
                       valid_bins_3d, valid_flat_3d, valid_mask_2d)
from infer.anchoring import (ANCHOR_SMOOTHING_BINS, AnchoredSpace,  # noqa: F401
                             anchor_log_correction, anchor_to_slice, apply_log_correction)
from infer.estimator import (InferenceMethod, LinearSpace, clip_to_range,  # noqa: F401
                             stream_combination)
from infer.slices import check_slice, fill_slice  # noqa: F401
from infer.training_set import TrainingSet  # noqa: F401
