"""LatencyStats: percentiles, maximum and fps of known inputs."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from facepuppet.live.stats import BINS_PER_DECADE, LatencyStats


def test_known_percentiles_and_fps(tmp_path):
    stats = LatencyStats()
    latencies = np.arange(1, 101) * 1e-3  # 1..100 ms, shuffled
    for k, i in enumerate(np.random.default_rng(0).permutation(100)):
        stats.add(latencies[i], k / 30)
    half_bin = 10 ** (0.5 / BINS_PER_DECADE) - 1
    for q, expected in ((50, 0.050), (95, 0.095), (99, 0.099), (100, 0.100), (0, 0.001)):
        assert stats.percentile(q) == pytest.approx(expected, rel=half_bin * 1.01)
    assert stats.max == 0.1
    assert stats.fps == pytest.approx(30.0)
    stats.drop(3)
    path = tmp_path / "stats.json"
    stats.write(path)
    summary = json.loads(path.read_text())
    assert summary["frames"] == 100 and summary["dropped"] == 3 and summary["fps"] == pytest.approx(30.0)
    assert summary["latency_ms"]["p95"] == pytest.approx(95.0, rel=1e-3)
    assert summary["latency_ms"]["max"] == 100.0


def test_empty_and_out_of_range():
    stats = LatencyStats()
    assert math.isnan(stats.percentile(50)) and math.isnan(stats.fps)
    assert stats.summary()["latency_ms"] == {"p50": None, "p95": None, "p99": None, "max": None}
    stats.add(0.0, 0.0)
    stats.add(1e4, 1.0)  # beyond the last bin: counted there; the maximum stays exact
    assert stats.max == 1e4 and stats.percentile(100) <= 1e4
    with pytest.raises(ValueError, match="finite"):
        stats.add(float("nan"), 2.0)
    with pytest.raises(ValueError, match="q must be"):
        stats.percentile(101)


def test_matches_nearest_rank_percentiles_of_the_samples():
    x = np.random.default_rng(1).exponential(0.004, 20000) + 1e-4
    stats = LatencyStats()
    for k, v in enumerate(x):
        stats.add(v, k / 60)
    half_bin = 10 ** (0.5 / BINS_PER_DECADE) - 1
    for q in (50, 95, 99):
        assert stats.percentile(q) == pytest.approx(np.percentile(x, q, method="inverted_cdf"),
                                                    rel=half_bin * 1.01)
    assert stats.fps == pytest.approx(60.0)
