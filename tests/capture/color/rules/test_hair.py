"""Facial hair left out of the mouth blob (rules/hair.py), on columns of known Cr."""

import numpy as np

from facepuppet.capture.color.eye_anchors import skin_reference
from facepuppet.capture.color.rules.hair import HAIR_CR, hair_trim, red_chroma

SKIN = 160.0
UNIT = 50.0                 # crop pixels per face unit: runs of 2 px and more count as lip (HAIR_LIP 0.04)


def _column(*runs):
    """A column of Cr from (value, length) runs."""
    return np.concatenate([np.full(n, v, np.float32) for v, n in runs])


def _trim(columns, top, bottom, line=30.0):
    cr = np.stack(columns, axis=1)
    w = cr.shape[1]
    return hair_trim(cr, np.ones(w, np.bool_), np.full(w, top, np.float32), np.full(w, bottom, np.float32), SKIN,
                     line, UNIT)


def test_moustache_and_beard_are_cut_at_the_lips():
    """Blob rows 10-50: a moustache (Cr 140) over the upper lip (175), the mouth's dark inside (150), the lower
    lip (172), a beard (142): the blob's top moves to the upper lip, its bottom to the lower lip's end."""
    col = _column((SKIN, 10), (140, 10), (175, 6), (150, 8), (172, 6), (142, 10), (SKIN, 10))
    top, bottom, above, below = _trim([col], 10, 50)
    assert (top[0], bottom[0], above[0], below[0]) == (20, 40, True, True)


def test_a_blob_without_red_lip_next_to_its_edges_is_kept():
    """No lip as red as the cheeks beside the dark runs: pale lips (Cr 158), an open mouth whose blob is its dark
    inside alone (Cr 140 all through), a short dark edge (1 px, the blob's blur) and grey footage (Cr 128 all
    through): the blob stays as it is."""
    pale = _column((SKIN, 10), (140, 10), (158, 20), (140, 10), (SKIN, 10))
    inside = _column((SKIN, 10), (140, 40), (SKIN, 10))
    blur = _column((SKIN, 10), (140, 1), (175, 38), (140, 1), (SKIN, 10))
    grey = np.full(60, 128.0, np.float32)
    top, bottom, above, below = _trim([pale, inside, blur, grey], 10, 50)
    np.testing.assert_array_equal(top, 10)
    np.testing.assert_array_equal(bottom, 50)
    assert not above.any() and not below.any()


def test_hair_must_be_clearly_less_red_than_the_cheeks():
    """A run just under HAIR_CR less red than the cheeks (shade on the skin) stays in the blob; one just over is
    cut off. An open mouth's pale upper lip over its dark inside, above a red lower lip, is no moustache: that lip
    lies well below the lips' line."""
    near = _column((SKIN, 10), (SKIN - HAIR_CR + 1, 10), (175, 20), (SKIN, 20))
    far = _column((SKIN, 10), (SKIN - HAIR_CR - 1, 10), (175, 20), (SKIN, 20))
    top, _, above, _ = _trim([near, far], 10, 40)
    assert (top[0], above[0]) == (10, False) and (top[1], above[1]) == (20, True)
    open_pale = _column((SKIN, 10), (SKIN - 9, 6), (140, 12), (172, 6), (SKIN, 10))
    top, bottom, above, below = _trim([open_pale], 10, 34, line=16.0)
    assert (top[0], bottom[0], above[0], below[0]) == (10, 34, False, False)


def test_red_chroma_is_opencv_cr():
    import cv2

    rng = np.random.default_rng(3)
    rgb = rng.integers(0, 256, (6, 7, 3)).astype(np.uint8)
    ref = cv2.cvtColor(rgb, cv2.COLOR_RGB2YCrCb)[..., 1].astype(np.float32)
    np.testing.assert_allclose(red_chroma(rgb, 0, 0, 7, 6), ref, atol=1.0)
    boxes = np.array([[0, 0, 3, 6], [4, 0, 7, 6]], dtype=np.int64)
    both = np.concatenate([ref[:, 0:3].ravel(), ref[:, 4:7].ravel()])
    assert abs(128.0 + skin_reference(rgb, boxes)[1] - np.median(both)) <= 1.0


def test_each_condition_keeps_what_is_not_hair():
    """Columns that only one condition keeps: a pale lip (a run at the cheeks' Cr less 4) between the hair and the
    red lip; specks a little less red than the cheeks throughout (mean above the hair's level); an open mouth's
    dark inside under a red upper lip, whose lip ends above the lips' line (no beard). Hair whose run is broken
    only next to the lip (the lip's blurred edge) is cut."""
    pale_between = _column((SKIN, 10), (140, 8), (SKIN - 4, 5), (175, 8), (SKIN, 9))
    specks = _column((SKIN, 10), *[(v, 1) for v in (150, 157) * 6], (175, 8), (SKIN, 10))
    open_mouth = _column((SKIN, 10), (175, 6), (140, 14), (SKIN, 10))
    blurred = _column((SKIN, 10), (140, 8), (SKIN - 5, 2), (175, 10), (SKIN, 10))
    top, bottom, above, below = _trim([pale_between, specks, open_mouth, blurred], 10, 30)
    np.testing.assert_array_equal(above, [False, False, False, True])
    np.testing.assert_array_equal(below, False)
    np.testing.assert_array_equal(top, [10, 10, 10, 20])
    np.testing.assert_array_equal(bottom, 30)
    # The opening under a red upper lip that ends just under the lips' line (a wide-open mouth, its lower lip
    # pale and dark): no beard.
    _, bottom, _, below = _trim([open_mouth], 10, 30, line=14.0)
    assert (bottom[0], below[0]) == (30, False)
