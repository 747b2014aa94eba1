"""numba's set-up (cagekit/_numba_setup.py): cagekit runs from a read-only install with a
read-only HOME (its kernels cached in a temporary folder, one warning line), and numba
never tries, nor warns about, an old TBB library (issue 29)."""

import os
import shutil
import subprocess
import sys

import pytest
from builders import ROOT, SHAPE

from cagekit.datasets import synthetic
from cagekit.io import save_mesh

#: numba's variables a test sets itself (a developer's own would change the outcome)
NUMBA_VARIABLES = ("NUMBA_CACHE_DIR", "NUMBA_THREADING_LAYER",
                   "NUMBA_THREADING_LAYER_PRIORITY", "XDG_CACHE_HOME", "CAGEKIT_DEBUG")


def clean_environment(**extra):
    env = {k: v for k, v in os.environ.items() if k not in NUMBA_VARIABLES}
    return {**env, "PYTHONPATH": ROOT, **extra}


def run(args, env, cwd):
    """Run Python in ``cwd`` (not the repository: its cagekit would come first)."""
    return subprocess.run([sys.executable, *args], capture_output=True, text=True, env=env,
                          cwd=cwd, timeout=300)


@pytest.fixture
def read_only_install(tmp_path, read_only):
    """A copy of the cagekit package in a read-only folder, a read-only HOME and a writable
    temporary folder; yields (environment, temporary folder)."""
    install, home, temp = tmp_path / "install", tmp_path / "home", tmp_path / "tmp"
    shutil.copytree(os.path.join(ROOT, "cagekit"), install / "cagekit",
                    ignore=shutil.ignore_patterns("__pycache__"))
    home.mkdir()
    temp.mkdir()
    env = clean_environment(PYTHONPATH=str(install), HOME=str(home), TMPDIR=str(temp))
    with read_only(install), read_only(home):
        yield env, temp


def cached_kernels(folder):
    return [name for _, _, names in os.walk(folder) for name in names
            if name.endswith(".nbi")]


def test_a_read_only_install_and_home_cache_the_kernels_in_a_temporary_folder(
        read_only_install, tmp_path):
    """Every command that compiled a kernel ended with "internal error: RuntimeError:
    cannot cache function ...": numba found no folder to write its cache to."""
    env, temp = read_only_install
    result = run(["-m", "cagekit.cli", "fit-cage", SHAPE, "-o", tmp_path / "cage.obj",
                  "--faces", "40"], env, tmp_path)
    assert result.returncode == 0, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("cagekit fit-cage: warning: "), lines
    assert "cache" in lines[0] and "NUMBA_CACHE_DIR" in lines[0] and str(temp) in lines[0]
    assert cached_kernels(temp)  # the kernel fit-cage compiled is cached there
    # as a library: one warning line (Python's own format), and the kernels are defined
    result = run(["-W", "default", "-c", "import cagekit.coords, cagekit.cage._cut_kernel"], env,
                 tmp_path)
    assert result.returncode == 0, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "CagekitWarning" in lines[0] and str(temp) in lines[0], lines


def test_the_users_numba_cache_folder_is_kept(read_only_install, tmp_path):
    env, temp = read_only_install
    mine = tmp_path / "mine"
    env["NUMBA_CACHE_DIR"] = str(mine)
    result = run(["-W", "default", "-c", "import cagekit.coords"], env, tmp_path)
    assert (result.returncode, result.stderr) == (0, "")
    assert os.path.isdir(mine) and not os.listdir(temp)


def test_a_writable_install_needs_no_warning(tmp_path):
    result = run(["-W", "default", "-c", "import cagekit.coords"], clean_environment(),
                 tmp_path)
    assert (result.returncode, result.stderr) == (0, "")


# ------------------------------------------------------------------------------ TBB

#: pymeshlab ships TBB 2021.5 (TBB_INTERFACE_VERSION 12050): loaded before numba starts its
#: threads, numba used to find it, warn in two raw lines and fall back to OpenMP
BIND_AFTER_PYMESHLAB = """
import warnings
with warnings.catch_warnings():  # as pytest runs a test: the filters set here are dropped
    import cagekit.coords
import numpy as np, pymeshlab, numba
from cagekit.cage.shapes import box_cage
v, f = box_cage()
b = cagekit.coords.bind(np.full((4, 3), 0.1), v, f)
print(numba.threading_layer())
"""


def test_numba_never_tries_an_old_tbb(tmp_path):
    result = run(["-W", "default", "-c", BIND_AFTER_PYMESHLAB], clean_environment(),
                 tmp_path)
    assert result.returncode == 0, result.stderr
    assert "TBB" not in result.stderr, result.stderr
    assert result.stdout.strip() in ("omp", "workqueue")


def test_amplify_workers_print_no_tbb_warning(tmp_path):
    """Each pool worker imports pymeshlab, then starts numba's threads."""
    folder = tmp_path / "shapes"
    folder.mkdir()
    for seed in (0, 1):
        save_mesh(folder / f"chair_{seed}.obj", *synthetic.chair(seed=seed, resolution=0.2))
    result = run(["-m", "cagekit.cli", "amplify", folder, "-o", tmp_path / "out",
                  "--variations", "2", "--workers", "2", "--method", "scale"],
                 clean_environment(PYTHONWARNINGS="default"), tmp_path)
    assert result.returncode == 0, result.stderr
    assert "TBB" not in result.stderr, result.stderr
