"""The lips' and brows' shape models (capture.shape_models): geometry, learning curves from the look of synthetic
mouths, applying them, storing them in the profile and using them in the tracker."""

import cv2
import numpy as np
import pytest

from facepuppet.capture.color.profile import GENERIC_LAYOUT, Profile, load_profile, save_profile
from facepuppet.capture.color.shape_models import (
    FAMILIES,
    MARGINS,
    PATCH_SIZE,
    apply_shape_models,
    box_targets,
    family_box,
    family_patch,
    fit_shape_model,
    training_pairs,
)
from facepuppet.capture.curves import CURVE_NAMES, bezier_points
from facepuppet.errors import FacepuppetError

LIPS = FAMILIES["lips"]
UO, LO = CURVE_NAMES.index("lip_upper_outer"), CURVE_NAMES.index("lip_lower_outer")
UI, LI = CURVE_NAMES.index("lip_upper_inner"), CURVE_NAMES.index("lip_lower_inner")
CENTRE = np.array([60.0, 50.0])


def _layout() -> np.ndarray:
    """The generic layout placed on a 120 x 100 crop: 40 px per face unit, the mouth's middle at CENTRE."""
    mouth = GENERIC_LAYOUT[LIPS].reshape(-1, 2).mean(axis=0)
    return (GENERIC_LAYOUT - mouth) * 40.0 + CENTRE


def _lip_curves(half_width: float, upper: float, lower: float, dy: float) -> np.ndarray:
    """Lip curves (C, 4, 2): corners ``half_width`` px either side of the centre (moved down ``dy``), the outer
    lips' middles ``upper`` px above and ``lower`` px below the corners' line, the inner lips a third of that."""
    c = _layout().copy()
    y = CENTRE[1] + dy
    left, right = CENTRE[0] - half_width, CENTRE[0] + half_width
    for k, h in ((UO, -upper), (LO, lower), (UI, -upper / 3), (LI, lower / 3)):
        x1, x2 = CENTRE[0] - half_width / 2, CENTRE[0] + half_width / 2
        c[k] = [[left, y], [x1, y + 4 / 3 * h], [x2, y + 4 / 3 * h], [right, y]]
    return c


def _mouth_image(curves: np.ndarray, rng) -> np.ndarray:
    """A crop (100, 120, 3) uint8: skin, red lips between the outer curves, a dark line between the inner ones."""
    img = np.empty((100, 120, 3), np.float32)
    img[:] = (205, 160, 140)

    def poly(a, b):
        return np.round(np.concatenate([bezier_points(a, 24), bezier_points(b, 24)[::-1]]) * 4).astype(np.int32)

    cv2.fillPoly(img, [poly(curves[UO], curves[LO])], (170, 60, 70), cv2.LINE_AA, shift=2)
    cv2.fillPoly(img, [poly(curves[UI], curves[LI])], (60, 20, 25), cv2.LINE_AA, shift=2)
    img = cv2.GaussianBlur(img, (0, 0), 0.7) + rng.normal(0, 3, img.shape)
    return np.clip(img, 0, 255).astype(np.uint8)


def _random_mouth(rng) -> np.ndarray:
    return _lip_curves(rng.uniform(12, 20), rng.uniform(3, 7), rng.uniform(4, 12), rng.uniform(-3, 6))


def test_box_and_targets_geometry():
    layout = _layout()
    box = family_box(layout, "lips")
    pts = layout[LIPS].reshape(-1, 2)
    w = pts[:, 0].max() - pts[:, 0].min()
    side, up, down = MARGINS["lips"]
    np.testing.assert_allclose(box, [pts[:, 0].min() - side * w, pts[:, 1].min() - up * w,
                                     pts[:, 0].max() + side * w, pts[:, 1].max() + down * w])
    t = box_targets(layout, box, "lips")
    width = box[2] - box[0]
    np.testing.assert_allclose(t.reshape(-1, 4, 2) * width + box[:2], layout[LIPS])   # targets invert exactly
    brow = family_box(layout, "brow_left")
    ctrl = layout[FAMILIES["brow_left"]].reshape(-1, 2)
    assert brow[0] < ctrl[:, 0].min() and brow[2] > ctrl[:, 0].max() and brow[1] < ctrl[:, 1].min()
    lid = bezier_points(layout[CURVE_NAMES.index("eye_left_upper")], 32)
    assert brow[3] < lid[:, 1].min()                        # the brow's patch stops above the open eye


def test_patch_is_per_channel_normalised(rng):
    crop = rng.integers(0, 255, (100, 120, 3), dtype=np.uint8)
    p = family_patch(crop, np.array([10.0, 20.0, 70.0, 60.0])).reshape(-1, 3)
    assert p.shape == (PATCH_SIZE[0] * PATCH_SIZE[1], 3)
    np.testing.assert_allclose(p.mean(axis=0), 0.0, atol=1e-9)
    assert np.all(p.std(axis=0) < 1.0) and np.all(p.std(axis=0) > 0.9)
    flat = family_patch(np.full((100, 120, 3), 90, np.uint8), np.array([10.0, 20.0, 70.0, 60.0]))
    np.testing.assert_allclose(flat, 0.0, atol=1e-9)


def test_learnt_lips_are_read_back_from_unseen_mouths(rng):
    layout = _layout()
    xs, ys = [], []
    for _ in range(120):
        truth = _random_mouth(rng)
        x, y = training_pairs(_mouth_image(truth, rng), layout, truth, "lips", rng)
        xs += x
        ys += y
    model = fit_shape_model(np.array(xs), np.array(ys), alpha=1.0)
    errors, guesses = [], []
    for _ in range(10):
        truth = _random_mouth(rng)
        curves = layout.copy()                                  # the rules' guess: the neutral layout
        guesses.append(np.abs(curves[LIPS] - truth[LIPS]).max())
        apply_shape_models(curves, _mouth_image(truth, rng), layout, {"lips": model})
        errors.append(np.linalg.norm(curves[LIPS] - truth[LIPS], axis=-1).mean())
        others = np.setdiff1d(np.arange(len(CURVE_NAMES)), LIPS)
        np.testing.assert_array_equal(curves[others], layout[others])      # only the modelled family moves
    assert np.mean(errors) < 0.6 and np.mean(guesses) > 5, (np.round(errors, 2), np.round(guesses, 1))


def test_fit_checks_shapes():
    with pytest.raises(ValueError, match=r"patches \(N, P\) and targets \(N, T\)"):
        fit_shape_model(np.zeros((5, 3)), np.zeros((4, 2)))


def _constant_model(family: str, targets: np.ndarray) -> dict:
    n_in = PATCH_SIZE[0] * PATCH_SIZE[1] * 3
    return {"coef": np.zeros((len(targets), n_in)), "intercept": np.asarray(targets, dtype=float)}


def test_profile_round_trip_and_damaged_models(tmp_path, rng):
    shapes = {f: {"coef": rng.normal(size=(8 * len(idx), PATCH_SIZE[0] * PATCH_SIZE[1] * 3)),
                  "intercept": rng.normal(size=8 * len(idx))} for f, idx in FAMILIES.items()}
    save_profile(tmp_path / "p.npz", Profile(shapes=shapes))
    got = load_profile(tmp_path / "p.npz")
    assert set(got.shapes) == set(FAMILIES)
    for f in FAMILIES:
        np.testing.assert_array_equal(got.shapes[f]["coef"], shapes[f]["coef"])
        np.testing.assert_array_equal(got.shapes[f]["intercept"], shapes[f]["intercept"])
    assert load_profile(tmp_path / "p.npz").lids == {}
    bad = {"lips": {"coef": np.zeros((3, 5)), "intercept": np.zeros(3)}}
    save_profile(tmp_path / "bad.npz", Profile(shapes=bad))
    with pytest.raises(FacepuppetError, match="bad.npz: the profile's 'lips' shape model is damaged"):
        load_profile(tmp_path / "bad.npz")
    save_profile(tmp_path / "odd.npz", Profile(shapes={"nose": shapes["lips"]}))
    with pytest.raises(FacepuppetError, match="'nose' shape model"):
        load_profile(tmp_path / "odd.npz")


def test_the_tracker_reads_the_lips_with_the_profiles_model():
    """A lips model that always reads the same curves (no weights, an intercept): the tracker's lips are those
    curves in the box of the layout it placed, on every frame, whatever the rules would have found."""
    from facepuppet.capture.color.config import ColorTrackerConfig, FilterConfig
    from facepuppet.capture.color.tracker import ColorTracker
    from facepuppet.demo.performer import render_performer
    from facepuppet.demo.script import calibration_script

    script = calibration_script(hold=0.3, transition=0.1, head_motion=0.0)
    frames, _ = render_performer(script, size=(256, 256))
    fixed = np.linspace(0.1, 0.9, 32)
    tracker = ColorTracker(Profile(shapes={"lips": _constant_model("lips", fixed)}),
                           config=ColorTrackerConfig(filters=FilterConfig(enabled=False)))
    plain = ColorTracker(Profile(), config=ColorTrackerConfig(filters=FilterConfig(enabled=False)))
    differs = 0
    for k in range(0, len(frames), 7):
        got = tracker.track(frames[k], 33 * k)
        assert got.valid and tracker.seen is not None
        crop, A, placed = tracker.seen
        box = family_box(placed, "lips")
        expect = fixed.reshape(-1, 4, 2) * (box[2] - box[0]) + box[:2]       # crop pixels
        Ainv = cv2.invertAffineTransform(A)
        np.testing.assert_allclose(got.curves[LIPS], expect @ Ainv[:, :2].T + Ainv[:, 2], atol=1e-6)
        other = plain.track(frames[k], 33 * k)
        differs += not np.allclose(other.curves[LIPS], got.curves[LIPS], atol=0.5)
    assert differs > 0


def test_a_profile_with_shape_models_keeps_the_face_frame_filtered(monkeypatch):
    """The filters restart only when the face is (re)acquired or time does not move, not on every frame (with
    shape models too: their filter's restart must not restart the face frame's)."""
    from facepuppet.capture.color.tracker import ColorTracker
    from facepuppet.demo.performer import render_performer
    from facepuppet.demo.script import calibration_script
    from facepuppet.filters import OneEuro

    frames, _ = render_performer(calibration_script(hold=0.3, transition=0.1, head_motion=0.0), size=(256, 256))
    resets = []
    real = OneEuro.reset
    monkeypatch.setattr(OneEuro, "reset", lambda self: (resets.append(self), real(self))[1])
    tracker = ColorTracker(Profile(shapes={"lips": _constant_model("lips", np.linspace(0.1, 0.9, 32))}))
    for k in range(2):                                      # acquisition and the first filtered frame
        assert tracker.track(frames[k], 33 * k).valid
    resets.clear()
    for k in range(2, 14):
        assert tracker.track(frames[k], 33 * k).valid
    assert sum(r is tracker.smoother.frame for r in resets) <= 1, len(resets)


def test_the_rules_a_profiles_models_replace_are_not_run():
    """With models of every family the tracker runs none of §3.2's rules (no snakes, no eyelid model); its
    curves are those it gives when every rule runs, since the models replace them."""
    from facepuppet.capture.color.config import ColorTrackerConfig, MeasureConfig
    from facepuppet.capture.color.rules import OUTLINE_PARTS
    from facepuppet.capture.color.tracker import ColorTracker
    from facepuppet.demo.performer import render_performer
    from facepuppet.demo.script import calibration_script

    frames, _ = render_performer(calibration_script(hold=0.3, transition=0.1, head_motion=0.0), size=(256, 256))
    shapes = {f: _constant_model(f, np.linspace(0.1, 0.9, 8 * len(idx))) for f, idx in FAMILIES.items()}
    lips_only = ColorTracker(Profile(shapes={"lips": shapes["lips"]}))
    assert lips_only.parts == ("eyes", "brows")
    no_eyes = ColorTracker(Profile(shapes={f: m for f, m in shapes.items() if not f.startswith("eye_")}))
    assert no_eyes.parts == ("eyes",)
    lids = {"coef": np.zeros((2, 128)), "intercept": np.full(2, 0.3)}
    fast = ColorTracker(Profile(shapes=shapes, lids=lids))
    assert fast.parts == ()
    every = ColorTracker(Profile(shapes=shapes, lids=lids))
    every._parts = OUTLINE_PARTS
    for k in range(0, 40, 3):
        a, b = fast.track(frames[k], 33 * k), every.track(frames[k], 33 * k)
        assert a.valid and b.valid
        np.testing.assert_array_equal(a.curves, b.curves)
    with pytest.raises(ValueError, match=r"outline_parts: unknown \['nose'\]"):
        ColorTrackerConfig(measure=MeasureConfig(outline_parts=("eyes", "nose")))
