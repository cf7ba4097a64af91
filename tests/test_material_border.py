"""The border band a material's slice leaves out (slice_extract.segment.material_interior,
border_width_px; slice_extract.extract.interior_samples): known label images, exact answers."""

import numpy as np

from flashbrdf.slice_extract.extract import interior_samples
from flashbrdf.slice_extract.segment import border_width_px, material_interior


def test_interior_leaves_out_a_band_of_the_given_width_on_each_side_of_a_border():
    labels = np.zeros((40, 60), int)
    labels[5:35, 5:30] = 1          # columns 5..29
    labels[5:35, 30:55] = 2         # columns 30..54: the border runs between 29 and 30
    inside = material_interior(labels, 3)
    # material 1: a pixel in column c is 30 - c from the nearest material-2 pixel; kept if > 3
    assert inside[20, 26] and not inside[20, 27]
    # material 2: column c is c - 29 from material 1
    assert not inside[20, 32] and inside[20, 33]
    # the outline (label 0) is no border: the card's outer columns and rows stay
    assert inside[5, 5] and inside[34, 54]
    # so exactly 3 columns per side go, over the 30 rows
    assert (labels > 0).sum() - inside.sum() == 2 * 3 * 30
    assert not inside[labels == 0].any()


def test_one_material_keeps_every_pixel():
    labels = np.zeros((10, 10), int)
    labels[2:8, 2:8] = 1
    assert np.array_equal(material_interior(labels, 4), labels > 0)


def test_border_width_is_a_share_of_the_object_not_of_the_image():
    # 0.3% of sqrt(object pixels), at least 1: pot2-sized 1, 1-MP card 3, a 6.6-MP object 8
    assert border_width_px(35_205) == 1
    assert border_width_px(1_048_576) == 3
    assert border_width_px(6_600_000) == 8
    assert border_width_px(0) == 1


def test_a_bin_the_interior_leaves_empty_keeps_its_border_samples():
    mine = np.array([1, 1, 1, 1, 1, 0], bool)
    interior = np.array([1, 0, 0, 0, 1, 1], bool)
    bins = np.array([0, 0, 1, 1, 2, 2])
    # bin 0: the interior sample only; bin 1: no interior sample, so both border samples stay;
    # bin 2: the interior one; the last sample is another material's
    assert interior_samples(mine, interior, bins).tolist() == [1, 0, 1, 1, 1, 0]


def test_a_material_seen_only_inside_the_lobe_is_flagged_narrow_and_warned():
    from flashbrdf.slice_extract.slice_files import material_coverage
    from flashbrdf.slice_extract.extract import SliceResult

    def seen(bins, lo, hi):
        report = {"coverage": {"bins_filled": bins, "pixels_used": 1000,
                               "theta_h_deg_filled": [lo, hi]}}
        return SliceResult(None, None, None, report)

    # the planar cards' materials: ~40 bins, all within 0-19 deg; a sphere's: 0-80 deg
    labels = np.array([[1, 2, 3]])
    cover = material_coverage({1: seen(40, 0.0, 19.1), 2: seen(70, 0.5, 80.0),
                               3: seen(6, 0.0, 3.0)}, labels)
    flags = [(m["sparse"], m["narrow"]) for m in cover["materials"]]
    assert flags == [(False, True), (False, False), (True, True)]
    # one warning per material that needs one: the sparse one says sparse, not both
    assert len(cover["warnings"]) == 2
    assert "narrow slice, theta_h 0.0-19.1 deg" in cover["warnings"][0]
    assert "sparse slice" in cover["warnings"][1]
