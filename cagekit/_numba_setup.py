"""numba's process-wide settings for cagekit's kernels, in one place.

:func:`configure` runs before any of cagekit's kernels is defined (``cagekit.coords``
calls it first, the command line when a command starts); it is cheap (it imports numba
only when the folders numba would cache in are not writable) and acts once a process.
Both settings go through numba's environment variables, so that processes started from
this one (``cagekit amplify``'s workers) inherit them, and both are left to the user when
the variable is set already.

- **Threading layer.** numba tries a TBB library first and, when the one it finds is too
  old, prints a two-line warning and falls back to OpenMP. pymeshlab ships TBB 2021.5 (too
  old), so every process that imported pymeshlab before numba started its threads warned
  (each worker of ``cagekit amplify``). cagekit asks for OpenMP, else numba's own work
  queue (``NUMBA_THREADING_LAYER_PRIORITY``); TBB comes last and is never tried, since the
  work queue always loads.
- **Cache folder.** The kernels are compiled with ``cache=True``. numba caches a kernel
  beside its source (``__pycache__``) or in the user's cache folder (``~/.cache/numba``)
  and, when it can write to neither (a read-only installation and HOME), refuses to define
  the kernel ("cannot cache function"). Then cagekit sets ``NUMBA_CACHE_DIR`` to a private
  folder in the temporary folder and says so in one warning line.
"""

from __future__ import annotations

import os
import stat
import sys
import tempfile
import warnings

from cagekit.errors import CagekitWarning

__all__ = ["configure"]

#: numba's threading layers in cagekit's order (numba wants all three named)
THREADING_LAYER_PRIORITY = "omp workqueue tbb"

#: the package's folder (numba caches a kernel beside the file that defines it)
_PACKAGE = os.path.dirname(os.path.abspath(__file__))

_CONFIGURED: list[bool] = []


def configure() -> None:
    """Choose numba's threading layer and, when needed, its cache folder (once a process).

    Call it before numba starts its threads and before any ``@numba.njit(cache=True)``
    function of cagekit is defined. Sets ``NUMBA_THREADING_LAYER_PRIORITY`` unless the
    user chose a layer, and ``NUMBA_CACHE_DIR`` (with a :class:`~cagekit.errors.
    CagekitWarning`) when numba could not write its cache where it looks by default.

    Examples
    --------
    >>> configure()
    >>> os.environ.get("NUMBA_THREADING_LAYER_PRIORITY") is not None or bool(
    ...     os.environ.get("NUMBA_THREADING_LAYER"))
    True
    """
    if _CONFIGURED:
        return
    _CONFIGURED.append(True)
    if not (os.environ.get("NUMBA_THREADING_LAYER")
            or os.environ.get("NUMBA_THREADING_LAYER_PRIORITY")):
        _set("NUMBA_THREADING_LAYER_PRIORITY", THREADING_LAYER_PRIORITY,
             THREADING_LAYER_PRIORITY.split())
    if not os.environ.get("NUMBA_CACHE_DIR") and not _default_cache_writable():
        folder = _private_temporary_folder()
        _set("NUMBA_CACHE_DIR", folder, folder)
        _warn(f"numba cannot write its cache beside cagekit ({_PACKAGE}) nor in your "
              f"cache folder ({_user_cache_folder()}); compiled kernels are cached in "
              f"{folder} (set NUMBA_CACHE_DIR to choose another folder)")


def _set(variable: str, text: str, value) -> None:
    """Set numba's environment variable, and its configuration when numba is imported
    (numba reads the variables when it is imported; its compiler reloads them when they
    change)."""
    os.environ[variable] = text
    config = sys.modules.get("numba.core.config")
    if config is not None:
        setattr(config, variable.removeprefix("NUMBA_"), value)


def _kernel_folders() -> list[str]:
    """The package's folders that hold Python files (kernels may be defined in any)."""
    return [folder for folder, _, names in os.walk(_PACKAGE)
            if os.path.basename(folder) != "__pycache__"
            and any(name.endswith(".py") for name in names)]


def _default_cache_writable() -> bool:
    """True if numba can cache every kernel where it looks by default: beside its file,
    else in the user's cache folder (numba's ``InTreeCacheLocator`` and
    ``UserWideCacheLocator``)."""
    missing = [folder for folder in _kernel_folders()
               if not _writable(os.path.join(folder, "__pycache__"))]
    if not missing:
        return True  # the usual case: numba is not imported
    return all(_writable(_user_cache_folder(folder)) for folder in missing)


def _user_cache_folder(folder: str | None = None) -> str:
    """numba's user-wide cache folder (``~/.cache/numba`` on Linux), or the one where it
    caches the kernels of ``folder``."""
    from numba.core.caching import UserWideCacheLocator
    from numba.misc.appdirs import AppDirs

    root = AppDirs(appname="numba", appauthor=False).user_cache_dir
    if folder is None:
        return root
    source = os.path.join(folder, "__init__.py")  # any file of the folder: same subfolder
    return os.path.join(root, UserWideCacheLocator.get_suitable_cache_subpath(source))


def _writable(folder: str) -> bool:
    """True if ``folder`` exists or can be made, and a file can be written in it (the test
    numba makes)."""
    try:
        os.makedirs(folder, exist_ok=True)
        tempfile.TemporaryFile(dir=folder).close()
    except OSError:
        return False
    return True


def _private_temporary_folder() -> str:
    """``<temporary folder>/cagekit-numba-cache-<user id>``, made private (0o700) so that
    no other user can plant compiled code there; when it exists and is not this user's
    alone, a new folder of ``tempfile.mkdtemp``."""
    uid = os.getuid() if hasattr(os, "getuid") else None
    name = f"cagekit-numba-cache-{'user' if uid is None else uid}"
    folder = os.path.join(tempfile.gettempdir(), name)
    try:
        os.makedirs(folder, mode=0o700, exist_ok=True)
        info = os.lstat(folder)
        private = (stat.S_ISDIR(info.st_mode) and not info.st_mode & 0o077
                   and (uid is None or info.st_uid == uid))
        if private and _writable(folder):
            return folder
    except OSError:
        pass
    return tempfile.mkdtemp(prefix="cagekit-numba-cache-")


def _warn(text: str) -> None:
    """One warning line, also in Python's own format (no source line is shown)."""

    warnings.warn_explicit(CagekitWarning(text), CagekitWarning, filename=__file__,
                           lineno=0, module=__name__)
