"""Memory of binding: beyond the (n, k) weights it is bounded by a chunk size, not by n."""

import json
import os
import subprocess
import sys

import pytest

SCRIPT = r"""
import json, sys
import numpy as np
import cagekit


def peak_rss():
    # VmHWM: this process's peak resident memory since exec (ru_maxrss would include the
    # parent's, inherited through fork)
    for line in open("/proc/self/status"):
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) * 1024

from cagekit.cage.shapes import box_cage
v, f = box_cage(4)                  # 192 faces, 98 vertices
n = int(sys.argv[1])
p = np.random.default_rng(0).uniform(-0.9, 0.9, (n, 3))
cagekit.bind(p[:100], v, f)         # compile / load the kernel first
before = peak_rss()
b = cagekit.bind(p, v, f)
after = peak_rss()
print(json.dumps({"before": before, "after": after, "weights": b.weights.nbytes,
                  "finite": bool(np.isfinite(b.weights).all())}))
"""


def _peak(n):
    # Two numba threads whatever the machine: each thread's scratch and allocator arena add
    # to the peak, so the bound would otherwise grow with the core count.
    env = {**os.environ, "NUMBA_NUM_THREADS": "2", "OMP_NUM_THREADS": "1"}
    out = subprocess.run([sys.executable, "-c", SCRIPT, str(n)], capture_output=True, text=True,
                         check=True, env=env)
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_bind_memory_is_weights_plus_a_constant():
    r = _peak(200_000)
    assert r["finite"]
    growth = r["after"] - r["before"]
    # weights (150 MiB) + input copies (2 x 4.6 MiB) + a margin for allocator slack
    assert growth <= r["weights"] + 40 * 2**20, growth


@pytest.mark.slow
def test_bind_one_million_points_under_1_5_gb():
    r = _peak(1_000_000)
    assert r["finite"]
    assert r["after"] <= 1.5e9, r
