"""Shared pytest configuration: hypothesis profiles and common fixtures."""

import contextlib
import os
import subprocess

import pytest
from hypothesis import HealthCheck, settings

settings.register_profile(
    "default", deadline=None, max_examples=60, suppress_health_check=[HealthCheck.too_slow]
)
settings.register_profile(
    "thorough", deadline=None, max_examples=1000, suppress_health_check=[HealthCheck.too_slow]
)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "default"))


@contextlib.contextmanager
def _read_only(folder):
    """Make ``folder`` read-only for the block, even for root (a read-only bind mount)."""
    if os.geteuid() != 0:
        folder.chmod(0o555)
        try:
            yield folder
        finally:
            folder.chmod(0o755)
        return
    mounted = subprocess.run(["mount", "--bind", "-o", "ro", str(folder), str(folder)],
                             capture_output=True)
    if mounted.returncode != 0:
        pytest.skip("root, and a read-only bind mount is not permitted here")
    try:
        yield folder
    finally:
        subprocess.run(["umount", str(folder)], check=False)


@pytest.fixture
def read_only():
    """``with read_only(folder):`` makes a folder read-only, for root too."""
    return _read_only


def pytest_terminal_summary(terminalreporter):
    """The CPU and the kernels this run used (numba, numpy, OpenBLAS, torch), also under -q."""
    from cpu_kernels import kernels

    terminalreporter.write_sep("-", "cpu and kernels")
    try:
        found = kernels()
    except Exception as exc:  # a report, never a reason for the run to fail
        terminalreporter.write_line(f"kernels: not known ({type(exc).__name__}: {exc})")
        return
    terminalreporter.write_line(f"cpu: {found['cpu']}")
    terminalreporter.write_line(
        f"kernels: numba {found['numba']}; numpy {' '.join(found['numpy']) or 'baseline only'}; "
        f"openblas {', '.join(found['openblas'])}; torch {found['torch']}")
    terminalreporter.write_line(f"emulation: {found['emulation'] or 'none (this CPU)'}")
