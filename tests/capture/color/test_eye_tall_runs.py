"""The eye search leaves out C's tall runs down a column (the hair or background beside the face, lit against
it), which would draw it outward, and keeps the eye's own blob and a brow above it."""

import numpy as np

from facepuppet.capture.color.config import ColorTrackerConfig
from facepuppet.capture.color.eye_anchors import EYE_TALL, EYE_TALL_LEVEL, eye_centres, without_tall_runs
from facepuppet.capture.color.face import CROP_EXTENT
from facepuppet.capture.color.profile import GENERIC_ANCHORS
from facepuppet.capture.color.tracker import ColorTracker

PX = ColorTrackerConfig().measure.px
WINDOW = tuple(int(round(v * PX)) for v in ColorTrackerConfig().measure.eye_window)
ANCHORS = (GENERIC_ANCHORS - CROP_EXTENT[:2]) * PX
TALL = int(round(EYE_TALL * PX))


def test_tall_runs_down_a_column_are_left_out_and_short_ones_kept():
    C = np.zeros((60, 6), np.float32)
    C[2:40, 1] = 0.9                        # 38 px down: longer than tall = 30
    C[10:20, 3] = 0.8                       # an eye's blob's column, 10 px
    C[5:35, 4] = 1.0                        # exactly tall: kept
    C[0:60, 5] = 0.2                        # under the level: kept whatever its run
    out = without_tall_runs(C, 0.3, 30)
    assert not out[:, 1].any()
    np.testing.assert_array_equal(out[:, 3:], C[:, 3:])
    np.testing.assert_array_equal(C[2:40, 1], np.float32(0.9))      # the input is left as it was


def _crop_contrast(edge: bool) -> tuple[np.ndarray, np.ndarray]:
    """C of a crop (the tracker's size) with an eye blob 20 x 8 px at each eye, a brow 24 x 4 px parted from it
    by 6 px of skin above, and with ``edge`` a bright line 3 px wide from the crop's top to its middle just
    inside the eye window's outer edge (the hair beside a face found a little too large). Returns (C, the
    eyes' true centres (2, 2))."""
    w, h = ColorTracker().crop_size
    C = np.zeros((h, w), np.float32)
    eyes = ANCHORS[:2] + [[2.0, 1.0], [-2.0, 1.0]]
    for k, (cx, cy) in enumerate(np.round(eyes).astype(int)):
        C[cy - 4:cy + 4, cx - 10:cx + 10] = 0.8
        C[cy - 14:cy - 10, cx - 12:cx + 12] = 0.7
        if edge:
            x = cx - WINDOW[0] + 1 if k == 0 else cx + WINDOW[0] - 4
            C[:h // 2, x:x + 3] = 1.0
    return C, np.round(eyes) - [[0.5, 0.5], [0.5, 0.5]]


def test_the_face_s_edge_does_not_draw_the_eyes_outward():
    C, truth = _crop_contrast(edge=True)
    ok, kept = eye_centres(without_tall_runs(C, EYE_TALL_LEVEL, TALL), ANCHORS, *WINDOW)
    assert ok
    clear, _ = _crop_contrast(edge=False)
    ok, alone = eye_centres(clear, ANCHORS, *WINDOW)
    np.testing.assert_allclose(kept, alone, atol=1e-6)           # the eye and brow are kept whole
    assert np.abs(kept[:, 0] - truth[:, 0]).max() < 1.0
    # Without the cut the line pulls each eye outward.
    ok, pulled = eye_centres(C, ANCHORS, *WINDOW)
    assert pulled[0, 0] < truth[0, 0] - 2.0 and pulled[1, 0] > truth[1, 0] + 2.0


def test_the_generic_tracker_s_eye_search_leaves_the_edge_out():
    C, truth = _crop_contrast(edge=True)
    tracker = ColorTracker()
    tracker.intensity(np.full((*C.shape, 3), 128, np.uint8))     # a crop for the opening's test (flat: none)
    found = tracker.eye_centres(C)
    assert found is not None
    assert np.abs(found[:, 0] - truth[:, 0]).max() < 1.5


def test_the_eye_search_starts_where_the_last_correction_put_the_eyes(assets):
    """A followed face whose eyes have moved 0.35 face units down the crop, past the eye window's reach (the
    brows now sit in the window): the search started where the last correction put the eyes finds them; started
    at the anchors it takes the brows."""
    import cv2

    from facepuppet.capture.color.acquire import NO_CORRECTION

    cap = cv2.VideoCapture(str(assets / "video" / "performer_a.mp4"))
    ok, bgr = cap.read()
    cap.release()
    assert ok
    rgb = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
    first = ColorTracker()
    assert first.track(rgb, 0).valid
    frame = first._follow.frame
    down = np.array([-frame.axis[1], frame.axis[0]])        # the face's down, image pixels per face unit
    shift = 0.35 * down
    moved = cv2.warpAffine(rgb, np.array([[1.0, 0.0, shift[0]], [0.0, 1.0, shift[1]]]), rgb.shape[1::-1],
                           flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    still = ColorTracker().measure(rgb, frame, follow=True, gain=1.0, outline=False, correction=np.array(NO_CORRECTION))
    truth = still.frame.origin + shift
    off = {}
    for name, corr in (("seeded", np.array([1.0, 0.0, 0.0, 0.35 * PX])), ("anchors", np.array(NO_CORRECTION))):
        tracker = ColorTracker()                             # no reference crop: the frame is not re-aligned
        got = tracker.measure(moved, frame, follow=True, gain=1.0, outline=False, correction=corr)
        off[name] = float(np.linalg.norm(got.frame.origin - truth)) / frame.unit
    assert off["seeded"] < 0.05 and off["anchors"] > 0.2, off


def test_the_search_starts_from_the_correction_without_its_scale():
    from facepuppet.capture.color.face import turned_and_shifted

    anchors = np.array([[40.0, 50.0], [80.0, 50.0], [60.0, 90.0]])
    angle, scale, shift = np.radians(10.0), 1.2, np.array([3.0, -2.0])
    a, b = scale * np.cos(angle), scale * np.sin(angle)
    got = turned_and_shifted(anchors, np.array([a, b, *shift]))
    # The similarity's image of the eyes' midpoint, and the anchors turned about it at their own size.
    mid = anchors[:2].mean(axis=0)
    S = np.array([[a, -b], [b, a]])
    R = S / scale
    np.testing.assert_allclose(got, (anchors - mid) @ R.T + S @ mid + shift, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(got[1] - got[0]), 40.0, atol=1e-9)
