"""Several BRDFs on one object, chosen per point by a label image or per mesh face."""

import numpy as np

from flashbrdf.capture.load import camera_key
from flashbrdf.files.errors import InputError


class MaterialMap:
    """Several BRDFs on one object: material k (1..K) is brdfs[k - 1].

    labels (H, W) int in `camera`'s pixel grid (the flash photo's; 0 = not the object);
    faces (F,) int or None: a label per mesh face, for views from other cameras.
    """

    def __init__(self, brdfs, labels, camera, faces=None):
        self.brdfs, self.labels, self.camera, self.faces = list(brdfs), labels, camera, faces

    def point_labels(self, surface, camera, where="--labels"):
        """(N,) int 1..K of a capture.Surface seen from `camera`: through the label image for
        the labels' own camera, else through the face labels."""
        if camera_key(camera) == camera_key(self.camera):
            labels = self.labels[surface.rows, surface.cols].astype(np.int64)
            unlabelled = labels == 0
            if unlabelled.any():   # a seen pixel the label image leaves at 0
                labels[unlabelled] = (self.faces[surface.face[unlabelled]]
                                      if self.faces is not None and surface.face is not None
                                      else 1)
            return labels
        if self.faces is None or surface.face is None:
            raise InputError(where, "a reference photo from another camera needs face labels "
                                    "(LABELS.faces.npy, written for mesh geometry)")
        return np.asarray(self.faces)[surface.face].astype(np.int64)
