"""The colour tracker's small parts on known answers: the face likeness (Pearson's over its box), the filters'
switch, the job registry, the grouped configuration."""

import numpy as np
import pytest

from facepuppet.capture.color import jobs
from facepuppet.capture.color.config import ColorTrackerConfig, FilterConfig, MeasureConfig
from facepuppet.capture.color.face import FaceFrame
from facepuppet.capture.color.likeness import FaceTemplate, box_correlation
from facepuppet.capture.color.profile import GENERIC_LAYOUT
from facepuppet.capture.color.smoothing import CurveSmoother
from facepuppet.capture.curves import CURVE_NAMES


def _template(px=32.0):
    from facepuppet.capture.color.face import CROP_EXTENT

    size = (int(round((CROP_EXTENT[2] - CROP_EXTENT[0]) * px)), int(round((CROP_EXTENT[3] - CROP_EXTENT[1]) * px)))
    return FaceTemplate((GENERIC_LAYOUT - CROP_EXTENT[:2]) * px, size, px)


def test_the_template_is_fully_like_itself_and_unlike_its_negative():
    t = _template()
    same = np.eye(2, 3)
    assert t.score(t.image, same) == pytest.approx(1.0, abs=1e-6)
    assert t.score(-t.image, same) == pytest.approx(-1.0, abs=1e-6)
    shifted = np.array([[1.0, 0.0, 6.0], [0.0, 1.0, 0.0]])        # the layout placed 6 pixels to the right
    assert t.score(t.image, shifted) < 0.9


def test_the_box_correlation_is_pearsons_over_the_box():
    rng = np.random.default_rng(1)
    C, T = rng.random((40, 30)).astype(np.float32), rng.random((40, 30)).astype(np.float32)
    T[5:30, 4:20] += 0.5 * C[5:30, 4:20]
    want = np.corrcoef(C[5:30, 4:20].ravel(), T[5:30, 4:20].ravel())[0, 1]
    assert box_correlation(C, T, 4, 5, 20, 30) == pytest.approx(want, abs=1e-7)
    # A rectangle reaching past the images is clipped to them; an empty one scores 0.
    assert box_correlation(C, T, -3, -2, 20, 30) == pytest.approx(np.corrcoef(C[:30, :20].ravel(),
                                                                               T[:30, :20].ravel())[0, 1], abs=1e-7)
    assert box_correlation(C, T, 10, 10, 10, 20) == 0.0
    assert box_correlation(C, np.ones_like(T), 4, 5, 20, 30) == 0.0          # a flat image: no correlation


def test_the_score_is_the_correlation_with_the_moved_template():
    import cv2

    t = _template()
    rng = np.random.default_rng(2)
    C = cv2.GaussianBlur(rng.random(t.image.shape).astype(np.float32), (0, 0), 2.0)
    C += cv2.warpAffine(t.image, np.float32([[1, 0, 2], [0, 1, -1]]), t.size)
    for S in (np.eye(2, 3), np.array([[1.05, -0.04, 1.7], [0.04, 1.05, -2.2]])):
        T = cv2.warpAffine(t.image, S.astype(np.float32), t.size, flags=cv2.INTER_LINEAR)
        x0, y0, x1, y1 = t.box
        want = np.corrcoef(C[y0:y1, x0:x1].ravel(), T[y0:y1, x0:x1].ravel())[0, 1]
        assert t.score(C, S) == pytest.approx(want, abs=1e-7)


def test_a_disabled_smoother_passes_the_curves_through():
    curves = np.random.default_rng(0).normal(size=(len(CURVE_NAMES), 4, 2)) * 10 + 100
    frame = FaceFrame(np.array([100.0, 100.0]), np.array([40.0, 0.0]))
    off = CurveSmoother(FilterConfig(enabled=False), lids=True, shaped=np.zeros(0, int))
    for k in range(3):
        assert off(curves, frame, 33 * k) is curves


def test_wait_pending_waits_for_every_job_once():
    waited = []

    class Job:
        def wait(self):
            waited.append(self)

    a, b = Job(), Job()
    jobs.add(a)
    jobs.add(b)
    assert jobs.pending()[-2:] == (a, b)
    jobs.wait_pending()
    assert waited == [b, a] and jobs.pending() == ()


def test_configs_are_grouped_keyword_only_and_checked():
    cfg = ColorTrackerConfig()
    assert cfg.measure.px == 48.0 and cfg.filters.enabled and cfg.landmarks.enabled
    with pytest.raises(TypeError):
        MeasureConfig(48.0)                         # keyword-only
    with pytest.raises(ValueError, match=r"outline_parts: unknown \['nose'\]"):
        MeasureConfig(outline_parts=("nose",))


def test_the_lips_follow_a_jump_by_their_own_filter_and_the_rest_by_the_curves():
    from facepuppet.filters import OneEuro, OneEuroConfig

    # A face frame of unit 1 at the origin: face units are image pixels, so each filter's answer is known.
    frame = FaceFrame(np.zeros(2), np.array([1.0, 0.0]))
    cfg = FilterConfig(curve=OneEuroConfig(min_cutoff=0.3, beta=0.0), lip=OneEuroConfig(min_cutoff=3.0, beta=0.0),
                       frame=OneEuroConfig(min_cutoff=1.0, beta=0.0))
    lips = np.array([i for i, n in enumerate(CURVE_NAMES) if n.startswith("lip_")])
    still = np.zeros((len(CURVE_NAMES), 4, 2))
    moved = still + 1.0                                   # every curve jumps by one face unit
    expect = {}
    for name, c in (("curve", cfg.curve), ("lip", cfg.lip)):
        f = OneEuro(c)
        f(still, 0.033)
        expect[name] = f(moved, 0.033)[0, 0, 0]
    smoother = CurveSmoother(cfg, lids=False, shaped=np.zeros(0, int))
    smoother(still, frame, 0)
    out = smoother(moved, frame, 33)
    others = np.setdiff1d(np.arange(len(CURVE_NAMES)), lips)
    assert np.allclose(out[lips], expect["lip"]) and np.allclose(out[others], expect["curve"])
    assert expect["curve"] < expect["lip"] < 1.0          # the lips' filter is the quicker one here
    # Lips that a shape model reads go through the shape filter instead (None: unfiltered).
    shaped = CurveSmoother(FilterConfig(curve=cfg.curve, lip=cfg.lip, frame=cfg.frame, shape=None), lids=False,
                           shaped=lips[:2])
    shaped(still, frame, 0)
    out = shaped(moved, frame, 33)
    assert np.allclose(out[lips[:2]], 1.0) and np.allclose(out[lips[2:]], expect["lip"])
