"""What a batch's parent process loads: the planning and the CLI's options, without numba (the workers compile
and load the kernels; the parent runs none of them)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

SRC = Path(__file__).resolve().parents[2] / "src"


def test_the_batch_parent_does_not_load_numba():
    code = ("import sys\n"
            "import facepuppet.batch.run, facepuppet.cli._batch\n"
            "from facepuppet.cli._animate import animate_config\n"
            "from facepuppet.pipeline.animate import AnimateConfig\n"
            "from facepuppet.filters import OneEuro\n"
            "assert 'numba' not in sys.modules, 'numba loaded'\n"
            "import numpy as np\n"
            "f = OneEuro()\n"
            "f(np.zeros((2, 2)), 0.1)\n"
            "out = f(np.ones((2, 2)), 0.1)\n"
            "assert 'numba' in sys.modules and 0 < out[0, 0] < 1, out\n")
    env = {**os.environ, "PYTHONPATH": str(SRC) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
