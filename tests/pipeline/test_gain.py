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


REGIONS = ("background", "jaw", "mouth_L", "mouth_R", "brow", "brow_2")


def test_region_names_match_by_stem_and_plural():
    from facepuppet.pipeline.gain import region_matches

    assert region_matches("mouth", "mouth_L") and region_matches("mouth", "mouth_R")
    assert region_matches("brows", "brow_2") and region_matches("brow", "brow")
    assert region_matches("mouth_L", "mouth_L") and not region_matches("mouth_L", "mouth_R")
    assert not region_matches("jaw", "mouth_L")


def test_per_region_gain_scales_only_that_region():
    cfg = parse_gain(["mouth=1.4", "brows=0.5"])
    w = np.full((len(REGIONS), len(NAMES)), 0.5)
    out = apply_gain(w, cfg, NAMES, REGIONS)
    want = np.array([0.5, 0.5, 0.7, 0.7, 0.25, 0.25])[:, None] * np.ones(len(NAMES))
    np.testing.assert_allclose(out, want)


def test_key_and_region_gains_multiply_where_both_apply():
    cfg = parse_gain(["2", "jawOpen=0.5", "mouth=1.2"])
    out = apply_gain(np.full((2, len(REGIONS), len(NAMES)), 0.25), cfg, NAMES, REGIONS)
    np.testing.assert_allclose(out[0, 0], [0.125, 0.5, 0.5])      # background: key gain, else global
    np.testing.assert_allclose(out[1, 2], [0.15, 0.3, 0.3])       # mouth_L: 0.5*1.2, then region 1.2


def test_unknown_region_is_one_error_listing_the_valid_names():
    with pytest.raises(ValueError, match=r"no key-model or region named nose .*regions background, jaw"):
        apply_gain(np.zeros((len(REGIONS), len(NAMES))), parse_gain(["nose=2"]), NAMES, REGIONS)
    with pytest.raises(ValueError, match="regional weights must have shape"):
        apply_gain(np.zeros(len(NAMES)), parse_gain(["mouth=2"]), NAMES, REGIONS)
