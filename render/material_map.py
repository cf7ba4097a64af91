"""Several BRDFs on one object, chosen per point by a label image or per mesh face."""

import numpy as np

from flashbrdf.capture.scene import camera_key
from flashbrdf.files.errors import InputError


class MaterialMap:
    """Several BRDFs on one object: material k (1..K) is brdfs[k - 1].

    labels (H, W) int in `camera`'s pixel grid (the flash photo's; 0 = not the object);
    faces (F,) int or None: a label per mesh face, for views from other cameras.
    """

    def __init__(self, brdfs, labels, camera, faces=None):
        self.brdfs, self.labels, self.camera, self.faces = list(brdfs), labels, camera, faces
        self._filled = None

    def point_labels(self, surface, camera, where="--labels"):
        """(N,) int 1..K of a capture.Surface seen from `camera`: through the label image for
        the labels' own camera, else through the face labels."""
        if camera_key(camera) == camera_key(self.camera):
            labels = self.labels[surface.rows, surface.cols].astype(np.int64)
            unlabelled = labels == 0
            if unlabelled.any():   # a seen pixel the label image leaves at 0 ("unused")
                labels[unlabelled] = (
                    self.faces[surface.face[unlabelled]]
                    if self.faces is not None and surface.face is not None
                    else self._nearest_label()[surface.rows[unlabelled],
                                               surface.cols[unlabelled]])
            return labels
        if self.faces is None or surface.face is None:
            raise InputError(where, "a reference photo from another camera needs face labels "
                                    "(LABELS.faces.npy, written for mesh geometry)")
        return np.asarray(self.faces)[surface.face].astype(np.int64)

    def _nearest_label(self):
        """(H, W) the label of each pixel's nearest labelled pixel (computed once): an object
        pixel left at 0 (a band along a border, say) takes its neighbourhood's material, not
        material 1's."""
        if self._filled is None:
            from scipy.ndimage import distance_transform_edt
            nearest = distance_transform_edt(self.labels == 0, return_distances=False,
                                             return_indices=True)
            self._filled = np.asarray(self.labels)[tuple(nearest)]
        return self._filled
