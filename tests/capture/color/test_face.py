"""Face localisation by skin colour and the face frame (paper §3.2)."""

import cv2
import numpy as np
import pytest

from facepuppet.capture.color.face import (
    FaceFrame,
    find_face,
    light_balance,
    scaled_about,
    similarity_from_points,
    similarity_of_pairs,
    skin_probability,
)

SKIN = (225, 170, 140)
GREY = (128, 128, 128)


def _face_image(centre=(160, 130), iod=60.0, roll_deg=0.0, size=(320, 260)):
    """A skin-coloured oval on grey with two dark eyes, brows and a mouth; returns image and eye centres."""
    w, h = size
    img = np.full((h, w, 3), GREY, np.uint8)
    c = np.array(centre, float)
    r = np.radians(roll_deg)
    ax = np.array([np.cos(r), np.sin(r)])
    dn = np.array([-np.sin(r), np.cos(r)])
    face_c = c + 0.6 * iod * dn
    cv2.ellipse(img, tuple(np.round(face_c).astype(int)), (int(iod * 1.1), int(iod * 1.5)), roll_deg, 0, 360, SKIN, -1)
    eyes = [c - ax * iod / 2, c + ax * iod / 2]
    for e in eyes:
        cv2.ellipse(img, tuple(np.round(e).astype(int)), (int(iod * 0.2), int(iod * 0.08)), roll_deg, 0, 360,
                    (40, 30, 30), -1)
    mouth = c + 1.2 * iod * dn
    cv2.ellipse(img, tuple(np.round(mouth).astype(int)), (int(iod * 0.35), int(iod * 0.07)), roll_deg, 0, 360,
                (150, 60, 70), -1)
    return img, eyes


def test_skin_probability_tells_skin_from_grey_and_blue():
    img = np.array([[SKIN, GREY, (90, 110, 160), (200, 140, 110)]], np.uint8)
    m = skin_probability(img)
    assert m[0, 0] == 255 and m[0, 3] == 255
    assert m[0, 1] == 0 and m[0, 2] == 0


@pytest.mark.parametrize("roll", [0.0, 12.0, -15.0])
def test_find_face_locates_the_eyes_and_roll(roll):
    img, (right, left) = _face_image(roll_deg=roll)
    frame = find_face(img)
    assert frame is not None
    np.testing.assert_allclose(frame.origin, (right + left) / 2, atol=0.15 * 60)
    assert frame.unit == pytest.approx(60, rel=0.2)
    assert np.degrees(frame.roll) == pytest.approx(roll, abs=6)


def test_no_skin_no_face():
    assert find_face(np.full((120, 160, 3), GREY, np.uint8)) is None
    assert find_face(np.zeros((120, 160, 3), np.uint8)) is None


def test_light_balance_undoes_a_colour_cast_and_a_dim_light():
    img, _ = _face_image()
    cast = np.clip(img * np.array([0.3, 0.25, 0.15]), 0, 255).astype(np.uint8)   # dim and warm
    M = light_balance(cast)
    assert M.shape == (3, 4)
    out = cv2.transform(cast, M).astype(float)
    means = out.reshape(-1, 3).mean(axis=0)
    assert np.ptp(means) < 0.03 * means.mean()                 # grey world: equal channel means
    lo, hi = np.percentile(out, (1, 99))
    assert lo < 10 and hi > 240                                # level stretched over the whole range


def test_similarity_from_points_recovers_a_known_similarity(rng):
    src = rng.normal(size=(6, 2))
    a = np.radians(25)
    R = 1.7 * np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    dst = src @ R.T + [3.0, -2.0]
    S = similarity_from_points(src, dst)
    np.testing.assert_allclose(S[:, :2], R, atol=1e-9)
    np.testing.assert_allclose(S[:, 2], [3.0, -2.0], atol=1e-9)


def test_face_frame_crop_maps_eyes_to_fixed_crop_pixels():
    f = FaceFrame.from_eyes(np.array([100.0, 80.0]), np.array([150.0, 90.0]))
    A = f.crop_matrix(48.0)
    right = A[:, :2] @ [100.0, 80.0] + A[:, 2]
    left = A[:, :2] @ [150.0, 90.0] + A[:, 2]
    np.testing.assert_allclose(left - right, [48.0, 0.0], atol=1e-9)    # one face unit, level
    M = f.to_image()
    np.testing.assert_allclose(M[:, :2] @ [0.5, 0.0] + M[:, 2], [150.0, 90.0])
    assert f.unit == pytest.approx(np.hypot(50, 10))


def test_compose_and_blend():
    f = FaceFrame.from_eyes(np.array([0.0, 0.0]), np.array([10.0, 0.0]))
    g = f.compose(np.array([[2.0, 0.0, 0.0], [0.0, 2.0, 1.0]]))            # twice as large, one unit lower
    assert g.unit == pytest.approx(20.0)
    np.testing.assert_allclose(g.origin, [5.0, 10.0])
    h = f.blend(g, 0.5)
    assert h.unit == pytest.approx(np.sqrt(200.0))
    np.testing.assert_allclose(h.origin, [5.0, 5.0])


def test_scaled_about_keeps_the_point_and_the_turn(rng):
    """A similarity scaled about a point: that point maps where it did, the turn is kept, the scale multiplied."""
    src, dst = rng.normal(size=(2, 2)) * 50.0, rng.normal(size=(2, 2)) * 50.0
    S = similarity_of_pairs(src, dst)
    mid = src.mean(axis=0)
    out = scaled_about(S, mid, 0.8)
    assert np.allclose(out[:, :2] @ mid + out[:, 2], dst.mean(axis=0))
    assert np.isclose(np.hypot(out[0, 0], out[1, 0]), 0.8 * np.hypot(S[0, 0], S[1, 0]))
    assert np.isclose(np.arctan2(out[1, 0], out[0, 0]), np.arctan2(S[1, 0], S[0, 0]))
