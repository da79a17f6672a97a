"""Performer profile: save/load, the 11-10-4 colour network, and weights re-estimated as the light changes (§3.1)."""

import os
import zipfile

import cv2
import numpy as np
import pytest

from facepuppet.capture.color import train as cal
from facepuppet.capture.color.net import (
    N_INPUTS,
    WEIGHT_SCALE,
    ColourNet,
    constrain_weights,
    fisher_separation,
    separating_weights,
    subarea_means,
)
from facepuppet.capture.color.profile import (
    GENERIC_LAYOUT,
    GENERIC_MOUTH_REACH,
    PROFILE_VERSION,
    Profile,
    default_profile,
    load_profile,
    save_profile,
)
from facepuppet.capture.color.train import train_profile
from facepuppet.capture.color.transform import channels, lip_hue_table
from facepuppet.capture.curves import CURVE_NAMES
from facepuppet.errors import FacepuppetError


def _net(rng):
    x = rng.normal(size=(40, N_INPUTS))
    y = constrain_weights(np.column_stack([1 + x[:, 0] * 0.1, np.full(40, 0.3), -1 + x[:, 1] * 0.1, 0.5 + 0 * x[:, 2]]))
    return ColourNet.fit(x, y, seed=0)


def test_default_profile_round_trip(tmp_path):
    path = tmp_path / "p.npz"
    save_profile(path, default_profile())
    got = load_profile(path)
    assert got.name == "generic" and got.net == {} and got.lids == {}
    np.testing.assert_array_equal(got.layout, GENERIC_LAYOUT)
    assert got.skin == default_profile().skin and got.lip_hue == default_profile().lip_hue


def test_round_trip_with_network_predicts_the_same(tmp_path, rng):
    net = _net(rng)
    lids = {"coef": rng.normal(size=(2, 128)), "intercept": np.array([-0.1, 0.1])}
    prof = Profile(layout=GENERIC_LAYOUT + 0.01, weights=np.array([0.5, 0.5, -1.0, 0.4]), net=net.to_arrays(),
                   lids=lids, name="ann")
    path = tmp_path / "ann.npz"
    save_profile(path, prof)
    got = load_profile(path)
    assert got.name == "ann"
    np.testing.assert_allclose(got.layout, prof.layout)
    np.testing.assert_allclose(got.weights, prof.weights)
    x = rng.normal(size=(5, N_INPUTS))
    np.testing.assert_allclose(ColourNet.from_arrays(got.net).predict(x), net.predict(x), rtol=1e-6)
    assert set(got.lids) == {"coef", "intercept"}
    np.testing.assert_array_equal(got.lids["coef"], lids["coef"])
    with np.load(path, allow_pickle=False) as d:          # loads without pickle
        assert int(d["version"]) == PROFILE_VERSION


def test_the_networks_estimates_move_the_weights_of_a_followed_face_only(rng):
    """Eq. 1's weights start at the profile's; a followed crop's re-estimate moves them ``reestimate_gain`` of the
    way to the network's estimate, every ``reestimate_every`` followed crops; a search's candidate crops leave
    them as they are."""
    from facepuppet.capture.color.config import ColorTrackerConfig, MeasureConfig
    from facepuppet.capture.color.net import subarea_means
    from facepuppet.capture.color.tracker import ColorTracker

    net = _net(rng)
    start = np.array([0.5, 0.5, -1.0, 0.4])
    tracker = ColorTracker(Profile(weights=start, net=net.to_arrays()),
                           config=ColorTrackerConfig(measure=MeasureConfig(reestimate_every=3, reestimate_gain=0.25)))
    w, h = tracker.crop_size
    crops = [rng.integers(0, 256, (h, w, 3)).astype(np.uint8) for _ in range(5)]
    estimate = [net.predict(subarea_means(c, tracker.config.measure.px)) for c in crops]
    tracker.intensity(crops[0])                                             # a candidate: not moved
    np.testing.assert_allclose(tracker._intensity.weights, start, rtol=1e-6)
    expected = start.astype(np.float32)
    for k, crop in enumerate(crops):
        tracker.intensity(crop, followed=True)
        if k % 3 == 0:                                                      # the 1st and 4th followed crops
            expected = expected + 0.25 * (estimate[k] - expected)
        np.testing.assert_allclose(tracker._intensity.weights, expected, rtol=1e-5, err_msg=str(k))
    with pytest.raises(ValueError, match="reestimate_gain"):
        MeasureConfig(reestimate_gain=0.0)


def test_mouth_reach_round_trip_and_older_files(tmp_path):
    path = tmp_path / "p.npz"
    save_profile(path, Profile(mouth_reach=0.21))
    assert load_profile(path).mouth_reach == pytest.approx(0.21)
    with np.load(path) as d:
        arrays = {k: d[k] for k in d.files if k != "mouth_reach"}
    older = tmp_path / "older.npz"
    np.savez(older, **arrays)
    assert load_profile(older).mouth_reach == GENERIC_MOUTH_REACH


def test_mouth_reach_learned_from_the_corners_offsets():
    """Corners 0.16 face units in from the mean in one frame: reach 0.16 + 0.03; never below the generic one."""
    layouts = np.repeat(GENERIC_LAYOUT[None], 5, axis=0)
    c = CURVE_NAMES.index("lip_upper_outer")
    layouts[2, c, 0, 0] += 0.16
    layouts[2, c, 3, 0] -= 0.16
    assert cal.mouth_reach_of(layouts, GENERIC_LAYOUT, GENERIC_MOUTH_REACH) == pytest.approx(0.19)
    assert cal.mouth_reach_of(layouts[:2], GENERIC_LAYOUT, GENERIC_MOUTH_REACH) == GENERIC_MOUTH_REACH
    layouts[2, c, 0, 1] += 1.0
    assert cal.mouth_reach_of(layouts, GENERIC_LAYOUT, GENERIC_MOUTH_REACH) == pytest.approx(0.35)


def test_corrupt_truncated_future_and_incomplete_files(tmp_path):
    good = tmp_path / "good.npz"
    save_profile(good, default_profile())
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"this is not a profile")
    with pytest.raises(FacepuppetError, match="bad.npz"):
        load_profile(bad)
    cut = tmp_path / "cut.npz"
    cut.write_bytes(good.read_bytes()[:200])
    with pytest.raises(FacepuppetError, match="cut.npz"):
        load_profile(cut)
    with pytest.raises(FacepuppetError, match="no such profile"):
        load_profile(tmp_path / "missing.npz")
    with np.load(good) as d:
        arrays = {k: d[k] for k in d.files}
    future = tmp_path / "future.npz"
    np.savez(future, **{**arrays, "version": np.int64(PROFILE_VERSION + 1)})
    with pytest.raises(FacepuppetError, match="newer"):
        load_profile(future)
    partial = tmp_path / "partial.npz"
    np.savez(partial, **{k: v for k, v in arrays.items() if k != "layout"})
    with pytest.raises(FacepuppetError, match="layout"):
        load_profile(partial)
    assert zipfile.is_zipfile(good)


def test_network_arrays_are_checked():
    with pytest.raises(ValueError, match="w0"):
        ColourNet.from_arrays({})
    bad = {"w0": np.zeros((3, 10)), "b0": np.zeros(10), "w1": np.zeros((10, 4)), "b1": np.zeros(4),
           "x_mean": np.zeros(N_INPUTS), "x_std": np.ones(N_INPUTS)}
    with pytest.raises(ValueError, match="w0"):
        ColourNet.from_arrays(bad)


def test_constrained_weights_have_the_papers_signs_and_fixed_scale():
    w = constrain_weights(np.array([[-1.0, 2.0, 0.5, -0.2], [1.0, 1.0, -1.0, 1.0]]))
    assert np.all(w[:, [0, 1, 3]] >= 0) and np.all(w[:, 2] < 0)
    np.testing.assert_allclose(np.abs(w).sum(axis=1), WEIGHT_SCALE, rtol=1e-6)


def test_separating_weights_on_pixels_that_differ_only_in_value(rng):
    """Features darker than skin and otherwise alike: only K and V matter, with w2 = -w3 > 0."""
    skin_v = rng.uniform(0.7, 0.8, 500)
    feat_v = rng.uniform(0.2, 0.3, 500)
    other = rng.uniform(0.2, 0.3, (1000, 2))
    skin = np.column_stack([other[:500, 0], 1 - skin_v, skin_v, other[:500, 1]])
    feat = np.column_stack([other[500:, 0], 1 - feat_v, feat_v, other[500:, 1]])
    w = separating_weights(feat, skin)
    assert w[1] > 0 and w[2] < 0 and w[1] == pytest.approx(-w[2], rel=1e-3)
    assert abs(w[0]) < 0.05 * WEIGHT_SCALE and abs(w[3]) < 0.05 * WEIGHT_SCALE


def test_subarea_means_of_a_uniform_crop():
    crop = np.zeros((134, 125, 3), np.uint8)
    crop[:] = (200, 100, 50)
    x = subarea_means(crop, 48.0)
    assert x.shape == (N_INPUTS,)
    np.testing.assert_allclose(x[:9], (0.299 * 200 + 0.587 * 100 + 0.114 * 50) / 255, atol=1e-5)
    np.testing.assert_allclose(x[9:], [200 / 350, 50 / 350], atol=1e-5)


def test_calibration_rejects_mismatched_input():
    with pytest.raises(ValueError, match="curves"):
        train_profile([np.zeros((8, 8, 3), np.uint8)], np.zeros((1, 3, 4, 2)))
    with pytest.raises(ValueError, match="same length"):
        train_profile([], np.zeros((1, 12, 4, 2)))
    with pytest.raises(FacepuppetError, match="no labelled frame"):
        train_profile([np.zeros((8, 8, 3), np.uint8)], np.full((1, 12, 4, 2), np.nan))


@pytest.fixture(scope="module")
def labelled_clip(assets, face_landmarker):
    """200 frames of performer_c and MediaPipe's curves on them."""
    from facepuppet.capture.tracking import make_tracker

    cap = cv2.VideoCapture(str(assets / "video" / "performer_c.mp4"))
    frames = []
    for _ in range(200):
        ok, bgr = cap.read()
        assert ok
        frames.append(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB))
    cap.release()
    wanted = list(range(0, 60, 3)) + list(range(100, 200, 10))
    tracker = make_tracker("mediapipe", model_path=face_landmarker, running_mode="image")
    try:
        curves = {i: tracker.track(frames[i], 33 * i).curves for i in wanted}
    finally:
        tracker.close()
    return frames, curves


def _separation(frames, curves, idx, light, weights_of):
    out = []
    for i in idx:
        rgb = cal.relight(frames[i], *light)
        fr = cal.label_frame(curves[i])
        crop, A, size = cal.face_crop(rgb, fr)
        feat, skin = cal.feature_and_skin_masks(curves[i] @ A[:, :2].T + A[:, 2], size)
        ch = channels(crop, weights_of.table)
        image = np.tensordot(weights_of(crop), ch, 1)
        out.append(fisher_separation(image[feat], image[skin]))
    return float(np.mean(out))


def test_reestimated_weights_keep_features_separable_when_the_light_changes(labelled_clip):
    frames, curves = labelled_clip
    train, test = list(range(0, 60, 3)), list(range(100, 200, 10))
    prof = train_profile([frames[i] for i in train], np.stack([curves[i] for i in train]), augment=6)
    net = ColourNet.from_arrays(prof.net)
    table = lip_hue_table(prof.lip_hue)

    def reestimated(crop):
        return net.predict(subarea_means(crop, 48.0))

    def fixed(crop):
        return prof.weights

    reestimated.table = fixed.table = table
    same = (1.0, 0.0, 1.0)
    n0 = _separation(frames, curves, test, same, reestimated)
    f0 = _separation(frames, curves, test, same, fixed)
    for light in ((0.5, 0.25, 1.0), (0.6, -0.2, 1.0)):            # darker and warmer, darker and cooler
        n1 = _separation(frames, curves, test, light, reestimated)
        f1 = _separation(frames, curves, test, light, fixed)
        assert n1 > f1, (light, n1, f1)
        assert n1 > 0.85 * n0, (light, n1, n0)
    cooler = _separation(frames, curves, test, (0.6, -0.2, 1.0), fixed)
    assert cooler < 0.8 * f0                                     # fixed weights degrade there


def test_head_turn_model_round_trip_and_damage(tmp_path, rng):
    from facepuppet.capture.color.head_turn import MODEL_KIND, N_FEATURES, apply_turn_model, fit_turn_model

    x = rng.normal(size=(60, N_FEATURES))
    yaw_pitch = np.column_stack([0.01 * x[:, 0], 0.01 * x[:, -1]])
    head = fit_turn_model(x, yaw_pitch)
    assert head["coef"].shape == (2, N_FEATURES)
    assert int(head["kind"]) == MODEL_KIND
    path = tmp_path / "p.npz"
    save_profile(path, Profile(head=head))
    got = load_profile(path)
    np.testing.assert_array_equal(got.head["coef"], head["coef"])
    assert default_profile().head == {}
    crop = rng.integers(0, 255, size=(134, 125, 3), dtype=np.uint8)
    S = np.eye(2, 3)
    np.testing.assert_allclose(apply_turn_model(got.head, crop, S, 48.0), apply_turn_model(head, crop, S, 48.0))
    with np.load(path) as d:
        arrays = {k: d[k] for k in d.files}
    bad = dict(arrays, head_coef=arrays["head_coef"][:, :10])
    np.savez(tmp_path / "bad.npz", **bad)
    with pytest.raises(FacepuppetError, match="head-turn model"):
        load_profile(tmp_path / "bad.npz")
    # A profile of an older head-turn model (RGB patches, no kind) still loads, without that model.
    old = {k: v for k, v in arrays.items() if k != "head_kind"}
    old["head_coef"] = np.zeros((2, 1572))
    np.savez(tmp_path / "old.npz", **old)
    assert load_profile(tmp_path / "old.npz").head == {}


def _known_set(rng, n=300):
    """Inputs (n, 11) and the Eq. 1 weights a smooth known function of them gives (n, 4)."""
    x = rng.normal(size=(n, N_INPUTS))
    raw = np.column_stack([1 + 0.3 * np.tanh(x[:, 0]), 0.5 + 0.2 * x[:, 1] * x[:, 2] / (1 + x[:, 1] ** 2),
                           -1 - 0.2 * np.tanh(x[:, 3] + x[:, 4]), 0.6 + 0.2 * np.sin(x[:, 9])])
    return x, constrain_weights(raw)


def test_colour_network_fit_is_deterministic_and_learns_a_known_function(rng):
    x, y = _known_set(rng)
    a, b = ColourNet.fit(x, y, seed=0), ColourNet.fit(x, y, seed=0)
    for k, v in a.to_arrays().items():
        np.testing.assert_array_equal(v, b.to_arrays()[k], err_msg=k)
    x_new, y_new = _known_set(np.random.default_rng(7), 200)
    mean_only = np.abs(constrain_weights(y.mean(axis=0)) - y_new).mean()
    assert np.abs(a.predict(x_new) - y_new).mean() < 0.5 * mean_only


def test_colour_network_inputs_perturbed_by_1e_6_give_the_same_weights(rng):
    x, y = _known_set(rng)
    a = ColourNet.fit(x, y)
    b = ColourNet.fit(x + 1e-6 * np.random.default_rng(3).standard_normal(x.shape), y)
    for k, v in a.to_arrays().items():
        np.testing.assert_allclose(b.to_arrays()[k], v, atol=1e-3, err_msg=k)
    x_new = _known_set(np.random.default_rng(8), 200)[0]
    np.testing.assert_allclose(b.predict(x_new), a.predict(x_new), atol=1e-3)


def test_hidden_units_permuted_and_flipped_have_one_canonical_form_and_the_same_outputs(rng):
    from facepuppet.capture.color.net import N_HIDDEN, canonical_units

    w0, b0 = rng.normal(size=(N_INPUTS, N_HIDDEN)), rng.normal(size=N_HIDDEN)
    w1, b1 = rng.normal(size=(N_HIDDEN, 4)), rng.normal(size=4)
    # A copy with its units in another order and three of them turned (σ(−a) = 1 − σ(a)).
    order, turned = rng.permutation(N_HIDDEN), np.array([1, 4, 7])
    v0, c0, v1, c1 = w0[:, order].copy(), b0[order].copy(), w1[order].copy(), b1.copy()
    c1 += v1[turned].sum(axis=0)
    v0[:, turned], c0[turned], v1[turned] = -v0[:, turned], -c0[turned], -v1[turned]
    z = rng.normal(size=(50, N_INPUTS))
    out = lambda w0, b0, w1, b1: (1.0 / (1.0 + np.exp(-(z @ w0 + b0)))) @ w1 + b1  # noqa: E731
    np.testing.assert_allclose(out(v0, c0, v1, c1), out(w0, b0, w1, b1), atol=1e-12)   # the same network
    for p, q in zip(canonical_units(w0, b0, w1, b1), canonical_units(v0, c0, v1, c1), strict=True):
        np.testing.assert_allclose(p, q, atol=1e-12)
    canon = canonical_units(w0, b0, w1, b1)
    np.testing.assert_allclose(out(*canon), out(w0, b0, w1, b1), atol=1e-12)
    assert np.all(canon[0][np.argmax(np.abs(canon[0]), axis=0), np.arange(N_HIDDEN)] > 0)
    assert np.all(np.diff(np.hypot(np.linalg.norm(canon[0], axis=0), canon[1])) <= 0)


def test_colour_network_on_a_real_clip_is_stable_under_1e_6(labelled_clip, monkeypatch):
    """train_profile's own training set (performer_c's frames, MediaPipe's curves, relit copies), fitted once
    as collected and once with every input moved by up to 1e-6: the same Eq. 1 weights within 1e-3."""
    frames, curves = labelled_clip
    train = list(range(0, 60, 3))
    fits = []

    class Collected(Exception):
        pass

    class Capture(ColourNet):
        @classmethod
        def fit(cls, x, y, *, seed=0):
            fits.append((np.array(x), np.array(y), ColourNet.fit(x, y, seed=seed)))
            raise Collected

    monkeypatch.setattr(cal, "ColourNet", Capture)
    with pytest.raises(Collected):
        train_profile([frames[i] for i in train], np.stack([curves[i] for i in train]), augment=6)
    x, y, net = fits[0]
    x_moved = x + 1e-6 * np.random.default_rng(5).uniform(-1, 1, x.shape)
    moved = ColourNet.fit(x_moved, y)
    np.testing.assert_allclose(moved.predict(x), net.predict(x), atol=1e-3)
    assert np.abs(net.predict(x) - y).mean() < 0.5 * np.abs(constrain_weights(y.mean(axis=0)) - y).mean()
    # The same fit whatever threads BLAS is allowed (on the machine's cores its sums differ in their last bits,
    # 7e-6 in the input weights, from one thread's).
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1):
        one = ColourNet.fit(x, y)
    with threadpool_limits(limits=max(os.cpu_count() or 1, 2)):
        many = ColourNet.fit(x, y)
    for k, v in one.to_arrays().items():
        np.testing.assert_array_equal(many.to_arrays()[k], v, err_msg=k)
