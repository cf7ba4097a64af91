"""Which material a pixel gets (slice_extract.segment): a flash highlight's added white does not
move a pixel to another material, and a patch cut by the photo's frame is not cleared as noise."""

import numpy as np
import pytest

from flashbrdf.brdf.merl import N_THETA_H
from flashbrdf.slice_extract.segment import align_bin_labels, clean_label_image
from flashbrdf.slice_extract.segment.slices import residuals

TEAL = np.array([0.01, 0.06, 0.058])      # a coloured material's slice value (1/sr)
SILVER = np.array([0.045, 0.083, 0.094])  # a pale lavender one
BIN = np.array([10])


def _slice(rho):
    return np.broadcast_to(np.log(rho), (N_THETA_H, 3))


def _plain(sample):
    return residuals(np.log(sample)[None], BIN, [_slice(TEAL), _slice(SILVER)])[0]


def _white(sample):
    return residuals(np.log(sample)[None], BIN, [_slice(TEAL), _slice(SILVER)], 0.0)[0]


def test_a_highlight_with_the_flash_colour_added_keeps_its_material():
    # twice the teal slice plus 0.04 of white (the flash's colour) in every channel. Plainly it
    # is nearer the pale silver: ln(rho / slice) = (0.29, 0.66, 0.51) from silver, colour 0.130
    # + 0.25 * 0.484 = 0.251, against (1.79, 0.98, 0.99) from teal, 0.359 + 0.313 = 0.672. The
    # least-squares fit rho = a teal + s gives a = 2, s = 0.04 exactly (s < 0.9 * 0.06, the cap),
    # so teal leaves only the brightness 0.25 ln 2 = 0.173; against silver s < 0: no white term
    sample = 2 * TEAL + 0.04
    np.testing.assert_allclose(_plain(sample), [0.672, 0.251], atol=2e-3)
    np.testing.assert_allclose(_white(sample), [0.25 * np.log(2), 0.251], atol=2e-3)
    assert _plain(sample).argmin() == 1 and _white(sample).argmin() == 0


def test_a_darker_pixel_is_not_given_a_white_term():
    # 0.67 x silver: against teal the fit's body a = 0.59 < 1 (the white would replace part of
    # the material, not add to it), so no term is taken: the residual is the plain one, and
    # silver's own, 0.25 |ln 0.67| = 0.100, wins
    sample = 0.67 * SILVER
    np.testing.assert_allclose(_white(sample), _plain(sample), rtol=1e-12)
    np.testing.assert_allclose(_white(sample)[1], 0.25 * abs(np.log(0.67)), atol=1e-9)


def test_a_grey_slice_takes_no_white_term():
    # against a grey slice (channels within GREY_SPREAD = 10% of their mean) white is only
    # brightness: the residual stays the plain one even for a pixel that is grey + white
    grey = np.array([0.1, 0.1, 0.1])
    sample = 2 * grey + 0.05 + np.array([0.0, 0.004, -0.004])
    slices = [_slice(grey)]
    plain = residuals(np.log(sample)[None], BIN, slices)
    np.testing.assert_allclose(residuals(np.log(sample)[None], BIN, slices, 0.0), plain,
                               rtol=1e-12)


def test_a_small_patch_cut_by_the_frame_is_kept():
    # a 100 x 100 object filling the photo; min_area 0.005 * 10,000 = 50 px. Material 2 has a
    # 10 x 10 patch (100 px, kept) and two 5 x 5 patches (25 px): the one in the corner is cut
    # by the frame and stays; the one inside is noise by the rule and takes its surroundings'
    labels = np.ones((100, 100), int)
    labels[80:90, 20:30] = 2
    labels[:5, :5] = 2
    labels[50:55, 50:55] = 2
    cleaned = clean_label_image(labels, np.ones((100, 100), bool), 0.005)
    assert np.all(cleaned[:5, :5] == 2)
    assert np.all(cleaned[50:55, 50:55] == 1)
    assert np.count_nonzero(cleaned == 2) == 100 + 25
    # the same object inside a larger photo does not touch the frame: both small patches go
    photo = np.zeros((120, 120), int)
    photo[10:110, 10:110] = labels
    cleaned = clean_label_image(photo, photo > 0, 0.005)
    assert np.count_nonzero(cleaned == 2) == 100


def _rings(size=120):
    """A disc of theta_h rings (bin = 0.7 x radius in px): (bins (N,), pixels (N,), shape,
    right half (N,) 0/1)."""
    rows, cols = np.mgrid[0:size, 0:size]
    radius = np.hypot(rows - size / 2, cols - size / 2)
    pixels = np.flatnonzero(radius.ravel() < size / 2)
    bins = np.clip((0.7 * radius).astype(int), 0, N_THETA_H - 1).ravel()[pixels]
    return bins, pixels, (size, size), (cols.ravel()[pixels] > size / 2).astype(int)


def test_align_bin_labels_puts_back_names_swapped_over_a_range_of_rings():
    """Two halves, their names exchanged in bins 10-19: every pixel right again (exact: the
    swap is clean), and the 10 bins counted."""
    bins, pixels, shape, truth = _rings()
    labels = np.where((bins >= 10) & (bins < 20), 1 - truth, truth)
    out, renamed = align_bin_labels(labels, bins, pixels, shape)
    assert renamed == 10 and np.array_equal(out, truth)


@pytest.mark.parametrize("layout", ["cap", "checkerboard", "one"])
def test_align_bin_labels_leaves_right_names_alone(layout):
    """A boundary that follows a ring (a cap round the highlight: one material per side, nothing
    to exchange), a 1-px checkerboard (neighbours share their material less than chance, so
    adjacency says nothing about names) and one material: unchanged."""
    bins, pixels, shape, _ = _rings()
    row, col = np.divmod(pixels, shape[1])
    labels = {"cap": (bins < 15).astype(int), "checkerboard": (row + col) % 2,
              "one": np.zeros(len(bins), int)}[layout]
    out, renamed = align_bin_labels(labels, bins, pixels, shape)
    assert renamed == 0 and np.array_equal(out, labels)


def test_clean_up_keeps_a_region_whole_and_clears_its_speckle():
    """A material with one region plus 1-px speckle (20% of the other material's pixels, more
    than the region holds) is not a pattern: the speckle goes (the pattern rule keeps small
    patches only for a material with no region). Measured 99.87% of pixels with their region's
    label (what is left: speckle touching the region or the frame); 89.6% under the rule that
    called a material a pattern when most of its pixels lay in small patches. 99.5%: between."""
    rng = np.random.default_rng(0)
    size = 400
    rows, cols = np.mgrid[0:size, 0:size]
    mask = np.hypot(rows - size / 2, cols - size / 2) < size / 2 - 1
    region = mask & (cols < 60)
    labels = np.where(mask, 1, 0)
    labels[region] = 2
    labels[mask & ~region & (rng.random(mask.shape) < 0.2)] = 2
    cleaned = clean_label_image(labels, mask, 0.002)
    truth = np.where(region, 2, 1)
    assert np.mean((cleaned == 2)[mask] == (truth == 2)[mask]) >= 0.995


def test_lossy_label_files_are_told_by_their_bytes(tmp_path):
    # A label image must be lossless: JPEG, JPEG 2000 (either wrapping) and lossy WebP, also in
    # its extended form where an alpha chunk precedes the image, are refused; PNG and lossless
    # WebP are not. The bytes decide, not the name (every file here is named .png).
    from flashbrdf.pipeline.label_files import lossy_format

    def riff(*chunks):
        body = b"WEBP" + b"".join(c + len(d).to_bytes(4, "little") + d + b"\0" * (len(d) & 1)
                                  for c, d in chunks)
        return b"RIFF" + len(body).to_bytes(4, "little") + body

    files = {"JPEG": b"\xff\xd8\xff\xe0" + bytes(20),
             "JPEG 2000": b"\x00\x00\x00\x0cjP  \r\n\x87\n" + bytes(20),
             "lossy WebP": riff((b"VP8X", bytes(10)), (b"ALPH", bytes(33)), (b"VP8 ", bytes(8))),
             None: riff((b"VP8X", bytes(10)), (b"VP8L", bytes(8)))}
    for kind, data in files.items():
        (tmp_path / "l.png").write_bytes(data)
        assert lossy_format(tmp_path / "l.png") == kind
    (tmp_path / "l.png").write_bytes(b"\xff\x4f\xff\x51" + bytes(20))  # a bare J2K codestream
    assert lossy_format(tmp_path / "l.png") == "JPEG 2000"
    (tmp_path / "l.png").write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(20))
    assert lossy_format(tmp_path / "l.png") is None

    # a TIFF is lossy when its first directory's Compression tag (259) names a lossy codec: in
    # either byte order, a SHORT left-justified in its entry; BigTIFF's entries are 20 bytes
    def tiff(order, compression, big=False):
        def n(value, size):
            return value.to_bytes(size, order)
        mark = b"II" if order == "little" else b"MM"
        if big:
            head = mark + n(43, 2) + n(8, 2) + n(0, 2) + n(16, 8) + n(2, 8)
            entry = n(256, 2) + n(3, 2) + n(1, 8) + n(4, 2) + bytes(6)
            return head + entry + n(259, 2) + n(3, 2) + n(1, 8) + n(compression, 2) + bytes(6)
        head = mark + n(42, 2) + n(8, 4) + n(2, 2)
        entry = n(256, 2) + n(3, 2) + n(1, 4) + n(4, 2) + bytes(2)
        return head + entry + n(259, 2) + n(3, 2) + n(1, 4) + n(compression, 2) + bytes(2)
    for order in ("little", "big"):
        for big in (False, True):
            for compression, kind in ((7, "TIFF compressed as JPEG"), (34712, "TIFF compressed as "
                                      "JPEG 2000"), (1, None), (5, None), (8, None)):
                (tmp_path / "l.png").write_bytes(tiff(order, compression, big))
                assert lossy_format(tmp_path / "l.png") == kind, (order, big, compression)
    (tmp_path / "l.png").write_bytes(b"II+\x00\x08\x00\x00\x00" + b"\xff" * 8)  # no directory
    assert lossy_format(tmp_path / "l.png") is None


def test_a_label_of_2_31_is_refused_without_counting_up_to_it(tmp_path):
    # An int32 TIFF of labels {0, 1, 2^31 - 1}: labels 2..2^31 - 2 have no pixel, so it is bad
    # input (exit 2, one line). Counting pixels per value up to K (np.bincount) asked for 16 GiB:
    # a MemoryError traceback, or the OOM killer. Run in a child limited to 4 GiB of address
    # space, so that the old code fails here instead of taking the machine's memory.
    import resource
    import subprocess
    import sys
    from pathlib import Path

    import cv2
    from synthetic import ggx_lambert, pinhole_camera, point_light, sphere_mesh, \
        write_synthetic_scene
    scene = write_synthetic_scene(tmp_path / "s", sphere_mesh(subdivisions=2), ggx_lambert(),
                                  pinhole_camera(16, 16, 40.0), [point_light([0.02, 0, 0])])
    labels = np.zeros((16, 16), np.int32)
    labels[4:12, 4:8], labels[4:12, 8:12] = 1, 2 ** 31 - 1
    assert cv2.imwrite(str(tmp_path / "l.tif"), labels)

    def limit():
        resource.setrlimit(resource.RLIMIT_AS, (4 << 30, resource.RLIM_INFINITY))
    root = Path(__file__).resolve().parents[1]
    done = subprocess.run(
        [sys.executable, "-m", "flashbrdf", "extract", str(scene), "--labels",
         str(tmp_path / "l.tif"), "--out", str(tmp_path / "out")], cwd=root,
        capture_output=True, text=True, preexec_fn=limit, timeout=300)
    assert done.returncode == 2, done.stderr
    assert len(done.stderr.strip().splitlines()) == 1, done.stderr
    assert "l.tif" in done.stderr and "(2147483645 in all)" in done.stderr
    assert not (tmp_path / "out").exists()


def test_face_labels_vote_per_face_and_unseen_faces_take_the_nearest_seen_ones():
    """The majority label of each face's pixels (a bincount of face x label), the nearest seen
    face's label for the others; with one material every face is 1 without a search."""
    from flashbrdf.slice_extract.segment.labels import face_labels
    rng = np.random.default_rng(2)
    faces = rng.integers(-1, 40, (50, 60))        # faces 0..39 seen, 40..59 never
    labels = rng.integers(0, 4, (50, 60)).astype(np.uint16)
    centroids = rng.normal(size=(60, 3))
    got = face_labels(labels, faces, centroids)
    for f in range(40):
        counts = np.bincount(labels[(faces == f) & (labels > 0)], minlength=4)
        assert got[f] == (np.argmax(counts) if counts[1:].any() else got[f])
    seen = np.array([np.bincount(labels[(faces == f) & (labels > 0)], minlength=4)[1:].any()
                     for f in range(60)])
    for f in np.flatnonzero(~seen):
        nearest = np.flatnonzero(seen)[np.argmin(np.linalg.norm(centroids[seen] - centroids[f],
                                                                axis=1))]
        assert got[f] == got[nearest]
    assert np.array_equal(face_labels(np.minimum(labels, 1), faces, centroids), np.ones(60))


def test_unseen_faces_take_the_label_of_their_own_part():
    """A sphere (material 2) inside an untilted torus (material 1), seen from +z: the torus's
    upper half and only the sphere's cap (z > 0.04) are seen. The sphere's hidden equator lies
    within 1 cm of the torus's inner ring and 4.7 cm of the cap, so the nearest seen face
    overall is the torus's: each unseen face must take its own part's label instead. A third
    part nobody sees (a small sphere beside the torus's +x side) keeps the rule of nearest seen
    face overall. Exact labels: a geometric rule, no tolerance. With flat-shaded files (every
    face its own three vertices) the parts are the same, found by vertex position."""
    import trimesh
    from flashbrdf.slice_extract.segment.labels import face_labels, face_parts
    from synthetic import combine, sphere_mesh, torus_mesh
    torus = torus_mesh(centre=(0, 0, 0), tilt_deg=0.0, sections=(64, 32))
    inner = sphere_mesh(radius=0.045, centre=(0, 0, 0), subdivisions=3)
    beside = sphere_mesh(radius=0.01, centre=(0.16, 0, 0), subdivisions=1)
    mesh = combine(torus, inner, beside)
    truth = np.repeat([1, 2, 2], [len(torus.faces), len(inner.faces), len(beside.faces)])
    centroids = mesh.triangles_center
    z = centroids[:, 2]
    part = np.repeat([0, 1, 2], [len(torus.faces), len(inner.faces), len(beside.faces)])
    seen = np.flatnonzero(((part == 0) & (z > 0)) | ((part == 1) & (z > 0.04)))
    labels, face_image = truth[seen].astype(np.uint16), seen  # one pixel per seen face
    parts = face_parts(mesh.vertices, mesh.faces)
    assert len(np.unique(parts)) == 3 and all(len(np.unique(parts[part == p])) == 1
                                             for p in range(3))
    got = face_labels(labels, face_image, centroids, parts)
    assert np.array_equal(got[part < 2], truth[part < 2]), np.bincount(got[part == 1])
    # the unseen part: the torus's outer ring is its nearest seen face
    assert (got[part == 2] == 1).all()
    # without parts, the old rule: the sphere's hidden equator takes the torus's label
    assert (face_labels(labels, face_image, centroids)[part == 1] == 1).any()
    flat = trimesh.Trimesh(mesh.vertices[mesh.faces].reshape(-1, 3),
                           np.arange(3 * len(mesh.faces)).reshape(-1, 3), process=False)
    assert np.array_equal(face_parts(flat.vertices, flat.faces), parts)


def test_a_vertex_at_minus_zero_joins_its_part():
    """face_parts matches vertex positions: a flat-shaded file repeating a vertex as -0.0 in
    one face and 0.0 in the next is one position, so two triangles sharing that vertex are one
    part (by bytes, -0.0 and 0.0 differ and split it)."""
    from flashbrdf.slice_extract.segment.labels import face_parts
    vertices = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0],       # triangle 1
                         [-0.0, 0, 0], [0, -1, 0], [-1, 0, 0]])   # triangle 2: the origin shared
    assert np.signbit(vertices[3, 0])
    assert face_parts(vertices, np.array([[0, 1, 2], [3, 4, 5]])).tolist() == [0, 0]
