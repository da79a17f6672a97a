"""Expression gain: parsing, per key-model values, clipping."""

from __future__ import annotations

import numpy as np
import pytest

from facepuppet.pipeline.gain import GainConfig, apply_gain, parse_gain

NAMES = ("jawOpen", "eyeBlink_L", "mouthSmile_L")


def test_unit_gain_only_clips():
    w = np.array([[0.5, -0.2, 1.3]])
    np.testing.assert_allclose(apply_gain(w, GainConfig(), NAMES), [[0.5, 0.0, 1.0]])


def test_global_and_per_key_gain():
    cfg = parse_gain(["0.5", "jawOpen=1.5"])
    assert cfg.gain == 0.5 and cfg.per_key == {"jawOpen": 1.5}
    w = np.array([0.8, 0.6, 0.4])
    np.testing.assert_allclose(apply_gain(w, cfg, NAMES), [1.2, 0.3, 0.2])


def test_gain_above_one_raises_the_upper_bound_in_proportion():
    cfg = parse_gain(["jawOpen=1.5"])
    np.testing.assert_allclose(apply_gain(np.array([1.2, 1.2, 0.0]), cfg, NAMES), [1.5, 1.0, 0.0])


def test_no_clipping():
    cfg = GainConfig(gain=2.0, low=None, high=None)
    np.testing.assert_allclose(apply_gain(np.array([-0.5, 0.7, 2.0]), cfg, NAMES), [-1.0, 1.4, 4.0])


def test_comma_list_and_nan_kept():
    cfg = parse_gain(["1.1,eyeBlink_L=0"])
    out = apply_gain(np.array([[np.nan, 1.0, 0.5]]), cfg, NAMES)
    assert np.isnan(out[0, 0])
    np.testing.assert_allclose(out[0, 1:], [0.0, 0.55])


@pytest.mark.parametrize("spec, match", [(["big"], "NUMBER"), (["=2"], "empty"), (["jaw=inf"], "finite")])
def test_bad_specs(spec, match):
    with pytest.raises(ValueError, match=match):
        parse_gain(spec)


def test_unknown_key_model_named():
    with pytest.raises(ValueError, match="browDown"):
        apply_gain(np.zeros(3), parse_gain(["browDown=2"]), NAMES)
