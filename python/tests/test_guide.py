"""The guide's examples (docs/guide/python.md) run as written."""

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

GUIDE = Path(__file__).resolve().parents[2] / "docs" / "guide" / "python.md"


def blocks():
    return re.findall(r"```python\n(.*?)```", GUIDE.read_text(), re.S)


def run(code, cwd):
    env = dict(os.environ, MPLBACKEND="Agg")
    return subprocess.run([sys.executable, "-c", code], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=900)


def test_the_guide_has_its_examples():
    assert len(blocks()) == 2


def test_worked_example_shows_honest_sigma(tmp_path):
    out = run(blocks()[0], tmp_path)
    assert out.returncode == 0, out.stderr
    assert out.stdout.count("trust good") == 3, out.stdout
    m = re.search(r"z over (\d+) estimates: rms ([0-9.]+), largest \|z\| ([0-9.]+)", out.stdout)
    assert m, out.stdout
    n, rms, worst = int(m[1]), float(m[2]), float(m[3])
    # 3 sessions × the estimated parameters; an honest σ gives rms z ≈ 1
    assert n > 100 and 0.7 < rms < 1.3 and worst < 4.5, out.stdout
    png = (tmp_path / "z_scores.png").read_bytes()
    assert png.startswith(b"\x89PNG") and len(png) > 10_000


def test_files_example(tmp_path):
    out = run(blocks()[1], tmp_path)
    assert out.returncode == 0, out.stderr
    assert "wrote " in out.stdout and "ur5e_calibrated.urdf" in out.stdout
