"""Light from one side, and two lights of different colours, evened out on drawn face crops (known answers: the
shading and the lights' colours applied)."""

import cv2
import numpy as np
import pytest

from facepuppet.capture.color.sides import COLOURS, SIDES, colour_gains, evened_colours, evened_sides, side_gains

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


#: A warm lamp's and a cool window's light, per channel (R, G, B): the second also dimmer.
WARM, COOL = (1.15, 1.0, 0.75), (0.6, 0.7, 0.85)


def _two_lights(img, centre, soft, warm=WARM, cool=COOL):
    """``img`` lit by ``warm`` on the left and ``cool`` on the right, a logistic step at column ``centre`` ``soft``
    columns wide."""
    x = np.arange(img.shape[1], dtype=np.float32)
    s = (1.0 / (1.0 + np.exp((x - centre) / soft)))[:, None]
    light = s * np.asarray(warm, np.float32) + (1.0 - s) * np.asarray(cool, np.float32)
    return _u8(img * light[None])


def _cheek_shares(crop):
    means = [crop[y0:y1, x0:x1].reshape(-1, 3).mean(axis=0) for x0, y0, x1, y1 in CHEEKS]
    return [m / m.sum() for m in means]


def test_one_light_s_colour_is_left_as_it_is():
    """Both cheeks of one colour (one light, however warm, or shade alone): the crop itself."""
    for crop in (_u8(_face()), _two_lights(_face(), 62, 8, WARM, WARM), _lit(_face(), 0.35, 62, 8)[0]):
        assert colour_gains(crop, CHEEKS) is None and evened_colours(crop, CHEEKS) is crop


def test_two_lights_colours_are_evened_to_the_lit_side_s():
    """A warm lamp on the left, a cool, dimmer light on the right: after evening, the cool cheek has the warm
    cheek's chromaticity, the warm side is untouched and each pixel of the step keeps about its R + G + B (the
    levels are the side evening's)."""
    crop = _two_lights(_face(), 62, 8)
    before = _cheek_shares(crop)
    gap = float(np.abs(before[0][:2] - before[1][:2]).sum())
    assert COLOURS["full"][0] < gap <= COLOURS["most"][0], gap
    out = evened_colours(crop, CHEEKS)
    after = _cheek_shares(out)
    assert np.abs(after[0] - after[1]).max() < 0.01, (before, after)
    assert np.abs(after[1] - before[1]).max() < 0.01                  # about the warm (brighter) cheek's colour
    assert np.abs(out[:, :30].astype(int) - crop[:, :30]).max() <= 1
    total_in, total_out = crop.astype(int).sum(axis=2), out.astype(int).sum(axis=2)
    assert np.abs(total_out - total_in)[60:80].max() <= 0.06 * total_in[60:80].max()


def test_colours_too_far_apart_for_one_skin_are_left():
    """One cheek on the skin, the other on a blue scene (a crop off the face): not two lights on one skin."""
    crop = _u8(_face())
    x0, y0, x1, y1 = CHEEKS[0]
    crop[:, x0 - 10:] = (60, 90, 170)
    assert colour_gains(crop, CHEEKS) is None and evened_colours(crop, CHEEKS) is crop


def test_the_colour_gain_grows_from_nothing_as_the_colours_part():
    """No jump where the colour evening starts: just over the difference it starts from, the gains are near 1."""
    start = COLOURS["from"][0]
    small = []
    for t in np.linspace(0.0, 1.0, 201):
        cool = tuple(1.0 + t * (c - 1.0) for c in COOL)
        warm = tuple(1.0 + t * (w - 1.0) for w in WARM)
        crop = _two_lights(_face(), 62, 8, warm, cool)
        shares = _cheek_shares(crop)
        gap = float(np.abs(shares[0][:2] - shares[1][:2]).sum())
        g = colour_gains(crop, CHEEKS)
        if g is None:
            assert gap <= start + 0.002 or gap > COLOURS["most"][0]
        elif gap < start + 0.002:
            small.append(float(np.abs(np.log(g)).max()))
    assert small and max(small) < 0.05, small
