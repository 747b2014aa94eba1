"""The benchmark scripts start: each imports what it needs and prints its usage.

Benchmarks are run by hand (docs/benchmarks.md), not by the tests; this catches a script
left behind by a move of the code it imports (``mvc_precision.py`` once looked for a test
helper in its old folder). ``bench_blender.py`` needs Blender's ``bpy`` and is checked in
the Blender environment's tests instead.
"""

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPTS = sorted(p.name for p in (ROOT / "benchmarks").glob("*.py") if p.name != "bench_blender.py")


def test_every_benchmark_is_listed():
    assert "bench_deform.py" in SCRIPTS and "mvc_precision.py" in SCRIPTS


@pytest.mark.parametrize("script", SCRIPTS)
def test_the_benchmark_prints_its_usage(script):
    done = subprocess.run([sys.executable, str(ROOT / "benchmarks" / script), "--help"],
                          cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.startswith("usage:"), done.stdout[:500]
