"""Checks of the key expressions: barely moving, too close to tell apart."""

from __future__ import annotations

import numpy as np

from facepuppet.pipeline.examples import check_examples
from synthetic_tracks import P


def test_check_examples_names_problems(rng):
    neutral = rng.normal(size=(P, 3))
    a, b, c = (rng.normal(size=(P, 3)) for _ in range(3))
    examples = np.stack([neutral + a, neutral + b, neutral + b + 0.01 * c, neutral + 1e-4 * c])
    out = check_examples(neutral, examples, ["jawOpen", "smile", "grin", "blank"])
    assert any("blank barely differs from neutral" in m for m in out)
    assert any("smile and grin are too close" in m for m in out)
    assert len(out) == 2
    assert check_examples(neutral, examples[:2], ["jawOpen", "smile"]) == []
