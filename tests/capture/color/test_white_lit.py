"""The colours a face would have in a white light: a patch of skin's light undone (``white_lit.skin_light``), and
the crops of a window tried in that light, whose cheeks' skin is doubted."""

import cv2
import numpy as np

from facepuppet.capture.color.white_lit import LIGHT_SPREAD, WHITE_LIT_SKIN, skin_light


def _chroma(rgb):
    m = np.median(rgb.reshape(-1, 3), axis=0).astype(float)
    return m / m.sum(), m.sum()


def test_a_skin_patch_in_a_coloured_light_gets_an_average_skins_colour_back():
    rng = np.random.default_rng(2)
    skin = 600.0 * WHITE_LIT_SKIN                       # an average skin in a white light, R + G + B = 600
    for gains in ((1.3, 0.95, 0.65), (0.8, 1.0, 1.25), (0.6, 0.7, 0.85)):
        lit = skin * gains
        patch = np.clip(lit + rng.normal(0.0, 4.0, (40, 30, 3)), 0, 255).astype(np.uint8)
        M = skin_light(patch)
        assert M.shape == (3, 4) and np.all(M[:, 3] == 0) and np.count_nonzero(M[:, :3] - np.diag(np.diag(M))) == 0
        chroma, total = _chroma(cv2.transform(patch, M))
        assert np.abs(chroma - WHITE_LIT_SKIN).max() < 0.005, (gains, chroma)
        assert abs(total - _chroma(patch)[1]) < 4.0, (gains, total)       # the brightness kept, to rounding


def test_a_patch_no_light_turns_skin_has_none():
    blue = np.zeros((10, 10, 3), np.uint8)
    blue[..., 2] = 200
    assert skin_light(blue) is None                                     # a channel at 0
    assert skin_light(np.zeros((0, 5, 3), np.uint8)) is None            # no pixels
    # A deep blue (R 20, G 60, B 200): gains 8.5, 2.2 and 0.6, over LIGHT_SPREAD apart.
    assert skin_light(np.broadcast_to(np.uint8([20, 60, 200]), (8, 8, 3))) is None
    # A patch just inside it (R 60, B 159: its R and B gains 3.96 apart) and one just outside (B 164: 4.08).
    for b, inside in ((159, True), (164, False)):
        M = skin_light(np.broadcast_to(np.uint8([60, 110, b]), (8, 8, 3)))
        assert (M is not None) == inside, b
        if inside:
            assert np.diag(M[:, :3]).max() / np.diag(M[:, :3]).min() <= LIGHT_SPREAD


def test_a_crop_whose_skin_is_doubted_needs_a_faces_likeness():
    """A skin-coloured frame (a little noise on it): its crops' cheeks are skin, so a search's crop of it is measured
    whatever its likeness to a face; with the skin doubted (a window tried in the light made to give it skin's
    colour) a crop without a face's likeness is none."""
    from facepuppet.capture.color.face import FaceFrame
    from facepuppet.capture.color.tracker import ColorTracker

    noise = np.random.default_rng(4).normal(0.0, 6.0, (240, 320, 3))
    rgb = np.clip(np.float64([200, 150, 130]) + noise, 0, 255).astype(np.uint8)
    tracker = ColorTracker()
    frame = FaceFrame.from_eyes(np.array([130.0, 100.0]), np.array([190.0, 100.0]))
    assert tracker.measure(rgb, frame, follow=False, gain=1.0) is not None
    tracker._place.skin_doubted = True
    assert tracker.measure(rgb, frame, follow=False, gain=1.0) is None
