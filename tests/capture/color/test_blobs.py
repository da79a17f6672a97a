"""Blob growing on synthetic masks (paper §3.2)."""

import numpy as np

from facepuppet.capture.color.blobs import BlobConfig, column_profile, grow_blob

PLAIN = BlobConfig(seed_level=0.7, grow_level=0.4, radius=0, close=0, open=0)


def _img(h=40, w=60):
    return np.zeros((h, w), dtype=np.float32)


def test_largest_seeded_region_wins_and_its_box_area_centroid_are_exact():
    img = _img()
    img[5:15, 5:25] = 0.5          # 200 px, seeded by one bright pixel
    img[8, 10] = 0.9
    img[20:30, 30:40] = 0.9        # 100 px, all seeds
    blob = grow_blob(img, PLAIN)
    assert blob.area == 200
    np.testing.assert_array_equal(blob.box, [5, 5, 25, 15])
    np.testing.assert_allclose(blob.centroid, [14.5, 9.5])
    assert blob.mask.sum() == 200 and blob.mask[10, 20] and not blob.mask[25, 35]


def test_unseeded_region_is_not_a_blob_however_large():
    img = _img()
    img[2:38, 2:30] = 0.6          # large but never above the seed level
    img[10:14, 40:44] = 0.9        # small seeded
    blob = grow_blob(img, PLAIN)
    assert blob.area == 16
    np.testing.assert_array_equal(blob.box, [40, 10, 44, 14])


def test_no_seed_gives_none():
    img = _img()
    img[10:20, 10:20] = 0.6
    assert grow_blob(img, PLAIN) is None
    assert grow_blob(_img(), PLAIN) is None


def test_growing_stops_below_the_grow_level():
    img = _img()
    img[10:20, 10:20] = 0.9
    img[10:20, 20:30] = 0.3        # below grow level: not joined
    blob = grow_blob(img, PLAIN)
    assert blob.area == 100


def test_radius_crosses_a_one_pixel_gap_that_plain_growing_does_not():
    img = _img()
    img[10:20, 10:20] = 0.9
    img[10:20, 21:31] = 0.5        # one empty column between
    assert grow_blob(img, PLAIN).area == 100
    joined = grow_blob(img, BlobConfig(seed_level=0.7, grow_level=0.4, radius=1, close=0, open=0))
    assert joined.box[0] == 10 and joined.box[2] == 31
    assert joined.area >= 200


def test_closing_fills_holes_and_opening_removes_a_thin_spur():
    img = _img()
    img[10:22, 10:30] = 0.9
    img[15, 18] = 0.0              # pinhole
    img[15, 30:45] = 0.9           # one-pixel-thin spur
    cfg = BlobConfig(seed_level=0.7, grow_level=0.4, radius=0, close=3, open=3)
    blob = grow_blob(img, cfg)
    assert blob.mask[15, 18]
    assert blob.box[2] <= 33          # the spur reached column 45


def test_min_area():
    img = _img()
    img[5, 5] = 0.9
    assert grow_blob(img, PLAIN, min_area=3) is None
    assert grow_blob(img, PLAIN, min_area=1).area == 1


def test_column_profile_of_a_triangle():
    mask = np.zeros((10, 6), dtype=bool)
    for c in range(4):
        mask[2 + c:8, c] = True
    cols, top, bottom = column_profile(mask)
    np.testing.assert_array_equal(cols, [True, True, True, True, False, False])
    np.testing.assert_array_equal(top[:4], [2, 3, 4, 5])
    np.testing.assert_array_equal(bottom[:4], [8, 8, 8, 8])


def test_near_prefers_the_region_where_the_feature_is_expected():
    img = np.zeros((40, 60), np.float32)
    img[5:10, 20:40] = 1.0          # the feature: 100 pixels near (30, 7)
    img[25:40, 0:20] = 1.0          # a larger shadow in a corner: 300 pixels
    assert grow_blob(img).area == 300
    blob = grow_blob(img, near=(30.0, 7.0, 8.0))
    assert blob.area == 100
    np.testing.assert_allclose(blob.centroid, (29.5, 7.0))
