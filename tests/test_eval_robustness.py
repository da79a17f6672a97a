"""The robustness benchmark's copies of a clip: chains of conditions (``benchmarks/eval_robustness.py``)."""

import argparse
import importlib.util
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from facepuppet.io.frames import open_media

_PATH = Path(__file__).resolve().parents[1] / "benchmarks" / "eval_robustness.py"
_spec = importlib.util.spec_from_file_location("eval_robustness", _PATH)
robustness = importlib.util.module_from_spec(_spec)
sys.modules.setdefault("eval_robustness", robustness)
_spec.loader.exec_module(robustness)


def test_a_chain_names_any_copy_first_and_per_frame_ones_after():
    for chain in ("wood+warm", "dim+noisy", "warm+noisy+lowres", "glasses+deep", "stage_hand", "turned",
                  "turned+dim") + robustness.COMPOUNDS:
        assert robustness.variant_name(chain) == chain
    for bad in ("noisy+wood", "warm+glasses", "dim+turned", "foo", "dim+", "dim++noisy"):
        with pytest.raises(argparse.ArgumentTypeError):
            robustness.variant_name(bad)


def test_a_chains_copies_are_applied_in_order(tmp_path):
    """A grey clip copied as ``dim+warm``: every frame 0.35 times as bright, then each channel times the warm
    light's gains (to the MPEG-4 coding's error: its dark, saturated blue 10 % off)."""
    src = tmp_path / "grey.mp4"
    writer = cv2.VideoWriter(str(src), cv2.VideoWriter_fourcc(*"mp4v"), 30.0, (64, 48))
    for _ in range(5):
        writer.write(np.full((48, 64, 3), 160, np.uint8))
    writer.release()
    out = tmp_path / "copy.mp4"
    robustness.write_copy(src, "dim+warm", out)
    shown, copied = _frames(src), _frames(out)
    assert len(copied) == 5
    expected = np.mean([f.reshape(-1, 3).mean(axis=0) for f in shown], axis=0) * 0.35 * np.array([1.3, 0.95, 0.65])
    got = np.mean([f.reshape(-1, 3).mean(axis=0) for f in copied], axis=0)
    assert np.abs(got / expected - 1.0).max() < 0.12, (got, expected)      # measured: within 0.1 (blue, the darkest)



def _frames(path):
    with open_media(path) as frames:
        return list(frames)
