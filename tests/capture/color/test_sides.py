"""Light from one side evened out on drawn face crops (known answers: the shading applied)."""

import cv2
import numpy as np
import pytest

from facepuppet.capture.color.sides import SIDES, evened_sides, side_gains

SIZE = (125, 134)                   # crop width, height (the tracker's)
SKIN = (196, 150, 130)
#: The cheek rectangles (x0, y0, x1, y1) as the tracker places them: the image's right one first.
CHEEKS = np.array([[82, 62, 98, 77], [26, 62, 43, 77]], dtype=np.int64)


def _face():
    """A crop of skin (with a little texture) holding two eyes, two brows, nostrils and a mouth; float32."""
    rng = np.random.default_rng(3)
    img = np.zeros((SIZE[1], SIZE[0], 3), np.float32) + SKIN + rng.normal(0.0, 3.0, (SIZE[1], SIZE[0], 1))
    for x in (38, 86):
        cv2.ellipse(img, (x, 41), (11, 5), 0, 0, 360, (235, 235, 235), -1, cv2.LINE_AA)
        cv2.circle(img, (x, 41), 5, (60, 40, 30), -1, cv2.LINE_AA)
        cv2.ellipse(img, (x, 25), (14, 4), 0, 200, 340, (90, 60, 45), 5, cv2.LINE_AA)
        cv2.circle(img, (x // 2 + 31, 76), 3, (70, 40, 35), -1, cv2.LINE_AA)
    cv2.ellipse(img, (62, 100), (20, 6), 0, 0, 360, (170, 80, 85), -1, cv2.LINE_AA)
    return img


def _u8(img):
    return np.clip(img + 0.5, 0, 255).astype(np.uint8)


def _lit(img, floor, centre, soft, dark_right=True):
    """``img`` with its columns' light falling from 1 to ``floor`` through a logistic step at column ``centre``
    ``soft`` columns wide, towards the right (or the left); returns the crop and the light (W,)."""
    x = np.arange(img.shape[1], dtype=np.float32)
    s = (x - centre) / soft * (1.0 if dark_right else -1.0)
    light = floor + (1.0 - floor) / (1.0 + np.exp(s))
    return _u8(img * light[None, :, None]), light


def _cheek_levels(crop):
    return [float(np.median(crop[y0:y1, x0:x1].max(axis=2))) for x0, y0, x1, y1 in CHEEKS]


def test_a_face_lit_alike_on_both_sides_is_left_as_it_is():
    crop = _u8(_face())
    assert side_gains(crop, CHEEKS) is None and evened_sides(crop, CHEEKS) is crop
    # a little unevenness, as a room's light gives (up to 1.28 on the shared clips' crops), is left too
    uneven, _ = _lit(_face(), 0.8, 62, 30)
    levels = _cheek_levels(uneven)
    assert 1.1 < max(levels) / min(levels) < SIDES["from"][0]
    assert evened_sides(uneven, CHEEKS) is uneven


@pytest.mark.parametrize("dark_right", [True, False], ids=["shade on the right", "shade on the left"])
def test_a_face_lit_from_one_side_is_evened_out(dark_right):
    """The light falling to about a third across the face (a window beside the performer): after evening, both cheeks
    are at the lit one's level, the lit side is untouched and the shaded eye's contrast to its skin is back."""
    face = _face()
    crop, _ = _lit(face, 0.35, 62, 8, dark_right)
    before = _cheek_levels(crop)
    assert max(before) / min(before) > 2.5
    out = evened_sides(crop, CHEEKS)
    after = _cheek_levels(out)
    assert max(after) / min(after) < 1.08, (before, after)
    lit_cols = slice(0, 30) if dark_right else slice(SIZE[0] - 30, SIZE[0])
    assert np.abs(out[:, lit_cols].astype(int) - crop[:, lit_cols]).max() <= 1
    # the shaded eye's iris against the skin beside it, as on the face before the light fell off
    x = 86 if dark_right else 38
    iris, skin = out[41, x].astype(float).mean(), out[41, x + 16].astype(float).mean()
    true_iris, true_skin = face[41, x].mean(), face[41, x + 16].mean()
    assert abs(iris / skin - true_iris / true_skin) < 0.1
    assert np.all(side_gains(crop, CHEEKS) <= SIDES["most"][0])


def test_a_sharp_shadow_edge_leaves_the_lit_side_as_it_is():
    """A shadow's sharp edge near the shaded cheek: the lit columns between it and the lit cheek keep their light
    (a gain running evenly from one cheek to the other would brighten them half way), the shaded ones come up."""
    crop, _ = _lit(_face(), 0.35, 80, 1.5)
    gains = side_gains(crop, CHEEKS)
    assert gains is not None
    assert np.all(gains[:74] < 1.05), gains[:74].max()
    assert np.all(gains[86:] > 2.5), gains[86:].min()


def test_the_gain_grows_from_nothing_as_the_sides_part():
    """No jump where the evening starts: just over the ratio it starts from, the gain is near 1; from the ratio at
    which it is full, the shaded cheek comes up to the lit one."""
    start, full = SIDES["from"][0], SIDES["full"][0]
    small = []
    for floor in np.linspace(0.6, 0.8, 21):
        crop, _ = _lit(_face(), float(floor), 62, 10)
        levels = _cheek_levels(crop)
        g = side_gains(crop, CHEEKS)
        ratio = max(levels) / min(levels)
        if g is None:
            assert ratio <= start + 0.02
        elif ratio < start + 0.03:
            small.append(float(g.max()))
    assert small and max(small) < 1.05, small
    crop, _ = _lit(_face(), 1.0 / (full + 0.3), 62, 10)
    after = _cheek_levels(evened_sides(crop, CHEEKS))
    assert abs(after[0] - after[1]) < 0.05 * max(after)
