"""Label images: theta_h rings named consistently, speckle cleared, the border band between
materials, checks of a label image, and labels per mesh face.
"""

import cv2
import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.spatial import cKDTree

from flashbrdf.brdf.merl import N_THETA_H
from flashbrdf.files.errors import InputError
from flashbrdf.files.threads import thread_budget

# a theta_h bin's materials are renamed (align_bin_labels) only when the new names agree with at
# least this many times as many pixels adjacent across the bin's edge as the old: a region of one
# material is far wider than a bin's ring, so right names agree on most such pairs
RENAME_GAIN = 2.0


def align_bin_labels(labels, bins, pixels, shape, present=0.05):
    """(labels (N,) 0..K-1, number of theta_h bins renamed): each theta_h bin's material names
    permuted to agree with the pixels adjacent to it in the neighbouring bins, outward from the
    bin with the most samples. bins (N,) the samples' theta_h bins, pixels (N,) flat indices into
    an (H, W) image, one sample per pixel.

    Why: the k-slice assignment decides bin by bin, so nothing ties material 1 in one bin to
    material 1 in the next. Where the mixture's first labels swap two materials over a range of
    bins (a dark glossy paint brighter than a white paper in the highlight), the slices learn
    the swap and keep it: whole rings of pixels, each ring split right, carry each other's names
    (white paper beside a glossy dark paint in blobs: 84.1% of pixels right; 98.8% renamed).
    Regions cross the rings, so the pixels adjacent across a bin's edge say which names belong
    together. Only materials holding at least `present` of both bins are renamed: a material
    boundary that follows a ring (a cap round the highlight) leaves one material per side and
    nothing to rename. A ring where one name holds both materials breaks the chain: the bins
    beyond it are then named against it, right or wrong (a phone-JPEG nickel beside a
    colour-changing paint: 77% -> 57% of pixels right)."""
    k = int(labels.max()) + 1 if len(labels) else 1
    if k < 2:
        return labels, 0
    # bins and labels as small-integer images (no sample: a bin far from every other), so the
    # pairs across a bin's edge come from whole-image differences, not 12-MP index gathers
    bin_image = np.full(shape[0] * shape[1], -1000, np.int16)
    bin_image[pixels] = bins
    bin_image = bin_image.reshape(shape)
    label_image = np.zeros(shape[0] * shape[1], np.int16)
    label_image[pixels] = labels
    label_image = label_image.reshape(shape)
    codes, same, pairs_in_bin = [], 0, 0
    for here, there in ((np.s_[:, :-1], np.s_[:, 1:]), (np.s_[:-1, :], np.s_[1:, :])):
        step = bin_image[there] - bin_image[here]
        inside = step == 0
        inside &= bin_image[here] >= 0
        same += int(np.count_nonzero(label_image[here][inside] == label_image[there][inside]))
        pairs_in_bin += int(np.count_nonzero(inside))
        for sign, low, high in ((1, here, there), (-1, there, here)):
            edge = step == sign
            codes.append((bin_image[low][edge].astype(np.int64) * k + label_image[low][edge]) * k
                         + label_image[high][edge])
    codes = np.concatenate(codes)
    shares = np.bincount(labels, minlength=k) / len(labels)
    if same <= (shares ** 2).sum() * pairs_in_bin:
        # neighbours share their material no more often than chance (a 1-px pattern, or noise):
        # adjacency says nothing about names
        return labels, 0
    n_bins = N_THETA_H
    # pairs[b, i, j]: adjacent pixels, the one in bin b labelled i, the one in bin b + 1 labelled j
    pairs = np.bincount(codes, minlength=n_bins * k * k).reshape(n_bins, k, k).astype(float)
    counts = np.bincount(bins * k + labels, minlength=n_bins * k).reshape(n_bins, k)
    names = np.tile(np.arange(k), (n_bins, 1))  # names[b, i]: what label i of bin b becomes
    reference = int(np.argmax(counts.sum(axis=1)))

    def rename(here, fixed, agree):
        """names for bin `here` given the already named bin `fixed`; agree[i, j]: pairs between
        label i here and label j there (original labels)."""
        named = np.zeros((k, k))
        np.add.at(named.T, names[fixed], agree.T)  # columns under bin `fixed`'s new names
        there = np.bincount(names[fixed], weights=counts[fixed], minlength=k)
        shared = [j for j in range(k) if counts[here, j] >= present * counts[here].sum() > 0
                  and there[j] >= present * there.sum() > 0]
        out = np.arange(k)
        if len(shared) < 2:
            return out
        sub = named[np.ix_(shared, shared)]
        rows, cols = linear_sum_assignment(-sub)
        moved = rows != cols
        # every renamed material must itself agree RENAME_GAIN x better under its new name (a
        # region that merely changes label across one ring edge is a mislabel, not a swap), and
        # 3 sigma better than a coin toss would (a few pairs at a grazing ring are noise)
        new, old = sub[rows, cols][moved], sub[rows, rows][moved]
        if moved.any() and np.all((new > RENAME_GAIN * old)
                                  & (new - old >= 3 * np.sqrt(new + old))):
            out[np.array(shared)[rows]] = np.array(shared)[cols]
        return out

    for here in range(reference + 1, n_bins):
        names[here] = rename(here, here - 1, pairs[here - 1].T)
    for here in range(reference - 1, -1, -1):
        names[here] = rename(here, here + 1, pairs[here])
    renamed = int(np.count_nonzero((names != np.arange(k)).any(axis=1)))
    return names[bins, labels], renamed


# a patch of a material under this many pixels is speckle whatever the material's shape: the
# clean-up's floor (clean_label_image)
MIN_PATCH_PX = 4


def clean_label_image(labels, object_mask, min_area_fraction):
    """Spatial clean-up of a label image (H, W) int (0 = no sample) over object_mask (H, W).

    Connected patches smaller than min_area_fraction of the object (at least MIN_PATCH_PX
    pixels) are cleared, unless they touch the photo's frame: such a patch continues outside the
    photo, so its visible area does not say it is noise (an object larger than the frame: the
    planar cards' scales cut by the frame). A material none of whose patches is larger is a
    pattern (dots, print), not speckle round a region of it, so only its patches under
    MIN_PATCH_PX go. Then every object pixel takes the label of the nearest labelled pixel.
    Labels are renumbered 1..K by decreasing area. Returns (H, W) uint16.
    Works on the object's bounding box only (the rest stays 0): the same result, less image.
    """
    object_mask = np.asarray(object_mask, bool)
    out = np.zeros(object_mask.shape, np.uint16)
    rows, cols = np.flatnonzero(object_mask.any(axis=1)), np.flatnonzero(object_mask.any(axis=0))
    if not len(rows):
        return out
    box = (slice(rows[0], rows[-1] + 1), slice(cols[0], cols[-1] + 1))
    frame = np.zeros(object_mask.shape, bool)
    frame[[0, -1], :] = frame[:, [0, -1]] = True
    out[box] = _clean_labels(np.asarray(labels)[box], object_mask[box], min_area_fraction,
                             int(object_mask.sum()), frame[box])
    return out


def _clean_labels(labels, object_mask, min_area_fraction, object_pixels, frame):
    """clean_label_image on a crop holding the whole object; frame (crop) bool: the photo's
    outermost pixels."""
    labels = labels.astype(np.int32)
    min_area = max(MIN_PATCH_PX, int(min_area_fraction * max(object_pixels, 1)))
    for k in range(1, int(labels.max()) + 1):
        count, comp, stats, _ = cv2.connectedComponentsWithStats(
            (labels == k).view(np.uint8), connectivity=8)
        if count <= 2:  # absent, or one patch: nothing to clear
            continue
        area = stats[:, cv2.CC_STAT_AREA]
        clear = area < min_area
        clear[0] = False                      # the background of this label's mask
        clear[np.unique(comp[frame])] = False  # cut by the frame: its size is unknown
        if clear[1:].all():                   # no patch is a region: a pattern (dots, print)
            clear &= area < MIN_PATCH_PX
        if clear[1:].all():                   # all tiny: keep the largest
            clear[1 + int(np.argmax(area[1:]))] = False
        if clear.any():
            labels[clear[comp]] = 0           # a lookup table: no per-patch pass
    if not np.any(labels > 0):
        return np.where(object_mask, 1, 0).astype(np.uint16)
    # nearest labelled pixel of every pixel: OpenCV's labelled distance transform numbers the
    # labelled (zero) pixels in row-major order; 4x faster than scipy's exact one at 12 MP
    unlabelled = (labels == 0).view(np.uint8)
    _, nearest = cv2.distanceTransformWithLabels(unlabelled, cv2.DIST_L2, 5,
                                                 labelType=cv2.DIST_LABEL_PIXEL)
    filled = labels[labels > 0].take(nearest - 1)
    filled[~object_mask] = 0
    area = np.bincount(filled.ravel(), minlength=int(filled.max()) + 1)
    order = [k for k in np.argsort(-area, kind="stable") if k > 0 and area[k] > 0]
    renumber = np.zeros(len(area), np.uint16)
    renumber[order] = np.arange(1, len(order) + 1)
    return renumber[filled]


# Width of the band along a border between two materials whose samples a material's slice is
# not extracted from, as a share of the object's size (the square root of its pixel count), at
# least one pixel. Why: labels are least sure at a border (mixed pixels from lens blur,
# demosaicing and resampling; a k-slice assignment that flips on noise), and a wrong pixel
# costs more in a slice (it moves its material's per-bin estimate, most in a bin with few of
# that material's pixels) than at render. A share of the object, not pixels, so a 12-MP photo
# and a 0.3-MP photo of one object drop the same part of it: 0.3% is 3 px on the 1-MP planar
# cards and 1 px (the floor, like extraction's silhouette_px) on DiLiGenT's ~190-px pot2.
BORDER_FRACTION = 0.003


# a theta_h bin keeps its border samples when the interior leaves it fewer than this many: 1,
# so dropping the border never costs a material a bin, and a bin the interior does observe is
# measured from the interior alone, however few its pixels. (20, the n of a trusted bin
# elsewhere, kept the border in the small-theta_h bins, where a material's few pixels are the
# ones a wrong label moves most: planar cards 11.39 against 10.92 with 1, flat tables.)
BORDER_MIN_BIN = 1


def border_width_px(object_pixels, fraction=BORDER_FRACTION):
    """Width (int pixels, >= 1) of the border band for an object of object_pixels pixels."""
    return max(1, int(round(fraction * np.sqrt(max(object_pixels, 0)))))


def material_interior(labels, width):
    """(H, W) bool: object pixels (labels > 0) farther than `width` pixels (Euclidean) from any
    pixel of another material. The object's outline (label 0) is no border here: extraction's
    silhouette_px handles it. Labels (H, W) int, 0 = not the object."""
    labels = np.asarray(labels)
    inside = labels > 0
    out = np.zeros(labels.shape, bool)
    if not inside.any():
        return out
    for k in np.unique(labels[inside]):
        other = inside & (labels != k)
        if not other.any():
            out |= labels == k
            continue
        # distance of every pixel to the nearest pixel of another material (zeros of the input)
        distance = cv2.distanceTransform((~other).view(np.uint8), cv2.DIST_L2, 5)
        out |= (labels == k) & (distance > width)
    return out


def check_labels(labels, shape, where, count=None):
    """K = labels.max() of a label image (H, W) int. InputError (naming `where`) when it is not
    `shape`, when a label in 1..K has no pixel, or when K != count (the number of tables)."""
    if labels.shape != tuple(shape):
        raise InputError(where, f"is {labels.shape[1]}x{labels.shape[0]} but the flash photo is "
                                f"{shape[1]}x{shape[0]}")
    if labels.size and labels.min() < 0:
        raise InputError(where, f"holds a negative label ({int(labels.min())}); labels are 0 "
                                "(not the object) or 1..K")
    k = int(labels.max()) if labels.size else 0
    # the labels used: a count per value only when K is no more than the pixels (one pixel of
    # 2^31 - 1 in an int32 TIFF asked np.bincount for 16 GiB; past that some label is missing
    # anyway), else np.unique, which sorts (0.34 s against 0.02 s on 12 MP)
    used = (np.flatnonzero(np.bincount(labels.ravel().astype(np.int64), minlength=k + 1)[1:]) + 1
            if k <= labels.size else np.unique(labels[labels > 0]))
    missing = k - len(used)
    if k == 0 or missing:
        # the first missing labels lie within 1..len(used) + 5
        empty = np.setdiff1d(np.arange(1, min(k, len(used) + 5) + 1), used)[:5].tolist()
        shown = ", ".join(map(str, empty or [1])) + (", ..." if missing > 5 else "")
        raise InputError(where, f"label(s) {shown} have no pixel ({missing or 1} in all): "
                                "labels must be 1..K, each used")
    if count is not None and count != k:
        raise InputError(where, f"has {k} material label(s) but {count} BRDF table(s) were "
                                "given")
    return k


def face_label_agreement(labels, face_image, faces):
    """The share (0..1) of the labelled pixels of labels (H, W) that hit a face (face_image
    (H, W), -1 none) whose label in faces (F,) is theirs; None when none hits a face. Any
    matching shapes do: a sample of pixels (N,) and the faces they hit. A face
    takes its pixels' majority label, so a mesh coarser than the materials' patches (a card
    of several inks as two triangles) leaves most pixels of the minority materials off."""
    seen = (face_image >= 0) & (labels > 0)
    count = int(np.count_nonzero(seen))
    if not count:
        return None
    return int(np.count_nonzero(np.asarray(faces)[face_image[seen]] == labels[seen])) / count


def face_parts(vertices, faces):
    """(F,) int: the connected part of the mesh each face belongs to (faces sharing a vertex
    position are connected; positions, not indices, since meshes are read unprocessed and a
    flat-shaded file repeats its vertices per face)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    vertices = np.ascontiguousarray(vertices, dtype=np.float64) + 0.0   # -0.0 is 0.0's position
    _, position = np.unique(vertices.view(np.dtype((np.void, 24))).ravel(), return_inverse=True)
    n_faces, n_positions = len(faces), int(position.max()) + 1
    corners = position[np.asarray(faces)].ravel()
    graph = coo_matrix((np.ones(len(corners), np.int8),
                        (np.repeat(np.arange(n_faces), 3), n_faces + corners)),
                       shape=(n_faces + n_positions,) * 2)
    return connected_components(graph, directed=False)[1][:n_faces]


def face_labels(labels, face_image, faces_centroids, parts=None):
    """Label per mesh face (F,) int32 from a label image (H, W) and the face each pixel hits
    (H, W) int (-1 none); faces_centroids (F, 3). A seen face takes its pixels' majority label;
    an unseen face the label of the nearest seen face (by centroid) of its own connected part
    (parts (F,) int, face_parts) when that part has one, else of any part: a part hidden
    behind another (a sphere inside a torus) is not given the label of what hides it."""
    n_faces = len(faces_centroids)
    k = int(labels.max())
    if k <= 1:  # one material: every face is it (the nearest-face search cost 20 s at 600k)
        return np.ones(n_faces, np.int32)
    seen = (face_image >= 0) & (labels > 0)
    # votes per (face, label) by one bincount (np.add.at is many times slower)
    votes = np.bincount(face_image[seen].astype(np.int64) * (k + 1) + labels[seen],
                        minlength=n_faces * (k + 1)).reshape(n_faces, k + 1)
    out = votes.argmax(axis=1).astype(np.int32)
    has = votes[:, 1:].sum(axis=1) > 0
    if not has.any():
        return np.ones(n_faces, np.int32)
    if not has.all():
        centroids = np.asarray(faces_centroids, np.float64)
        unseen = np.flatnonzero(~has)
        if parts is not None:
            parts = np.asarray(parts)
            in_seen_part = np.isin(parts[unseen], parts[has])
            # one search for all parts: a 4th coordinate part x (more than the mesh's size)
            # puts every other part farther than any face of the same part
            apart = 2 * float(np.ptp(centroids, axis=0).max()) + 1
            lifted = np.column_stack([centroids, parts * apart])
            own = unseen[in_seen_part]
            if len(own):
                _, nearest = cKDTree(lifted[has]).query(lifted[own], workers=thread_budget(2))
                out[own] = out[has][nearest]
            unseen = unseen[~in_seen_part]
        if len(unseen):
            tree = cKDTree(centroids[has])
            _, nearest = tree.query(centroids[unseen], workers=thread_budget(2))
            out[unseen] = out[has][nearest]
    return out
