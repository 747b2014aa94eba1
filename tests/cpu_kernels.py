"""Which kernels the libraries that pick them by CPU use in this process, and how to choose them.

numba compiles for the CPU it runs on, numpy dispatches its loops to the best SIMD extension
present, OpenBLAS (numpy's and scipy's) picks a core type, torch picks an ATen capability and
its MKL and oneDNN their instruction sets. Each can be told to act as an older CPU by an
environment variable, which is how ``make test-emulated`` runs the suite as other CPUs would
(the Makefile's ``CPU_*`` variables). :func:`kernels` reports what was picked, for the test
log's header and for ``tests/test_cpu_kernels.py``, which checks that an emulation asked for
really took effect.
"""

import os
import platform

__all__ = ["EMULATION_VARIABLES", "kernels", "cpu_name"]

EMULATION_VARIABLES = ("NUMBA_CPU_NAME", "NPY_DISABLE_CPU_FEATURES", "OPENBLAS_CORETYPE",
                       "ATEN_CPU_CAPABILITY", "MKL_ENABLE_INSTRUCTIONS", "ONEDNN_MAX_CPU_ISA")
"""The variables that choose kernels, one library each (the last two: torch's MKL and oneDNN)."""


def cpu_name() -> str:
    """The processor's model name (``/proc/cpuinfo``), or the machine type elsewhere."""
    try:
        with open("/proc/cpuinfo") as info:
            for line in info:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.machine()


def numpy_simd() -> list[str]:
    """numpy's dispatch targets enabled in this process (its baseline is always on)."""
    from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__
    return [name for name in __cpu_dispatch__ if __cpu_features__.get(name)]


def openblas_cores() -> list[str]:
    """The core type of each OpenBLAS loaded so far (numpy's, scipy's), after loading both."""
    import scipy.linalg  # noqa: F401  (loads scipy's OpenBLAS beside numpy's)
    from threadpoolctl import threadpool_info
    return [str(lib.get("architecture")) for lib in threadpool_info()
            if lib.get("internal_api") == "openblas"]


def torch_capability() -> str | None:
    """torch's ATen CPU capability (``DEFAULT``, ``AVX2``, ``AVX512``), None without torch."""
    try:
        import torch
    except ImportError:
        return None
    return torch.backends.cpu.get_cpu_capability()


def kernels() -> dict[str, object]:
    """What each library picked here: numba's target, numpy's SIMD, OpenBLAS's cores, ATen's.

    Returns
    -------
    dict
        ``cpu`` (model name), ``numba`` (target CPU name), ``numpy`` (enabled dispatch
        targets), ``openblas`` (core type of each loaded OpenBLAS), ``torch`` (ATen
        capability or None), and ``emulation`` (the variables of
        :data:`EMULATION_VARIABLES` that are set, with their values).
    """
    import llvmlite.binding
    import numba
    return {
        "cpu": cpu_name(),
        "numba": numba.config.CPU_NAME or f"{llvmlite.binding.get_host_cpu_name()} (this CPU)",
        "numpy": numpy_simd(),
        "openblas": openblas_cores(),
        "torch": torch_capability(),
        "emulation": {name: os.environ[name] for name in EMULATION_VARIABLES if name in os.environ},
    }
