"""An emulated CPU asked for (make test-emulated) is the one the libraries really use.

Each variable of ``cpu_kernels.EMULATION_VARIABLES`` that is set must have taken effect, or a
run meant to be "as another CPU" would quietly run on this one's kernels. Natively (nothing
set) the checks have nothing to compare and pass on what the libraries picked.
"""

import os

import pytest
from cpu_kernels import kernels, numpy_simd, openblas_cores, torch_capability

# OpenBLAS names a few core types differently from how they are asked for
OPENBLAS_ALIASES = {"prescott": "katmai"}


def test_the_kernels_are_reported():
    found = kernels()
    assert found["cpu"] and found["numba"]
    assert found["openblas"], "numpy and scipy each load an OpenBLAS"


@pytest.mark.skipif("NUMBA_CPU_NAME" not in os.environ, reason="numba compiles for this CPU")
def test_numba_compiles_for_the_cpu_asked_for():
    import numba
    assert numba.config.CPU_NAME == os.environ["NUMBA_CPU_NAME"]


@pytest.mark.skipif("NPY_DISABLE_CPU_FEATURES" not in os.environ,
                    reason="numpy uses every SIMD extension here")
def test_numpy_leaves_the_disabled_extensions_alone():
    disabled = set(os.environ["NPY_DISABLE_CPU_FEATURES"].replace(",", " ").split())
    assert not disabled & set(numpy_simd())


@pytest.mark.skipif("OPENBLAS_CORETYPE" not in os.environ, reason="OpenBLAS picks its own core")
def test_openblas_uses_the_core_asked_for():
    asked = os.environ["OPENBLAS_CORETYPE"].lower()
    assert {core.lower() for core in openblas_cores()} == {OPENBLAS_ALIASES.get(asked, asked)}


@pytest.mark.skipif("ATEN_CPU_CAPABILITY" not in os.environ, reason="torch picks its own")
def test_torch_uses_the_capability_asked_for():
    capability = torch_capability()
    if capability is None:
        pytest.skip("torch is not installed")
    assert capability.lower() == os.environ["ATEN_CPU_CAPABILITY"].lower()
