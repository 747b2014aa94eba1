"""Files: checked reading, atomic writing, output folders that vanish when a run fails.

Every reader and writer of cagekit goes through here, so that every file problem is one
:class:`~cagekit.errors.InputError` line naming the file, and no output is ever left half
written: :func:`atomic_output` writes to a locked temporary file and renames it, and
removes what writers killed mid-write left behind.
"""

from __future__ import annotations

import contextlib
import os
import re
import secrets
import stat
from collections.abc import Iterator, Sequence

from cagekit.errors import InputError

__all__ = ["all_or_nothing", "atomic_output", "check_file", "distinct_tails", "extension",
           "keep_outputs_as_written", "missing_folders", "one_line", "output_folder",
           "read_bytes", "read_text", "remove_empty_folders"]


def extension(path: str | os.PathLike) -> str:
    """The lower-case extension of ``path`` with its dot (``".obj"``), or ``""``."""
    return os.path.splitext(os.fspath(path))[1].lower()


def distinct_tails(paths: Sequence[Sequence[str]]) -> list[str]:
    """Each path's shortest trailing run of parts that no other path ends with, ``/``-joined.

    The whole path where no shorter tail tells it apart; an identical path does not count
    as another (it gets the same name).

    Parameters
    ----------
    paths : sequence of sequence of str
        Paths split into their parts (folders, then the file).

    Returns
    -------
    list of str
        One name per path, in order.

    Examples
    --------
    >>> distinct_tails([["out", "girl", "a.obj"], ["out", "suit", "a.obj"], ["b.obj"]])
    ['girl/a.obj', 'suit/a.obj', 'b.obj']
    """
    names = []
    for i, own in enumerate(paths):
        others = [p for j, p in enumerate(paths) if j != i and list(p) != list(own)]
        k = 1
        while k < len(own) and any(list(p[-k:]) == list(own[-k:]) for p in others):
            k += 1
        names.append("/".join(own[-k:]))
    return names


def one_line(exc: BaseException) -> str:
    """An exception as one line of at most 200 characters (for file errors)."""
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if len(text) <= 200 else text[:197] + "..."


def check_file(path: str | os.PathLike, error: type[InputError] = InputError) -> None:
    """Raise ``error(problem, path)`` unless ``path`` is a non-empty readable file."""
    if os.path.isdir(path):
        raise error("is a directory, not a file", path)
    try:
        size = os.stat(path).st_size
    except FileNotFoundError:
        raise error("no such file", path) from None
    except OSError as exc:
        raise error(f"cannot be read: {exc.strerror or exc}", path) from None
    if size == 0:
        raise error("is empty", path)


def read_bytes(path: str | os.PathLike, error: type[InputError] = InputError) -> bytes:
    """The bytes of a checked, non-blank file; problems raise ``error(problem, path)``."""
    check_file(path, error)
    try:
        with open(path, "rb") as fh:
            data = fh.read()
    except OSError as exc:
        raise error(f"cannot be read: {exc.strerror or exc}", path) from None
    if not data.strip():
        raise error("is empty", path)
    return data


def read_text(path: str | os.PathLike, error: type[InputError] = InputError) -> str:
    """:func:`read_bytes` decoded as UTF-8 (a BOM dropped, bad bytes replaced)."""
    return read_bytes(path, error).decode("utf-8-sig", errors="replace")


def missing_folders(path: str | os.PathLike) -> list[str]:
    """The folders that making ``path`` would create: it and its missing parents, as
    absolute paths with links resolved (``link/../out`` as the system reads it), deepest
    first; empty when ``path`` exists.

    Examples
    --------
    >>> missing_folders("/")
    []
    """
    missing, probe = [], os.path.realpath(os.fspath(path))
    while not os.path.lexists(probe):
        missing.append(probe)
        probe = os.path.dirname(probe)
    return missing


def remove_empty_folders(folders: Sequence[str]) -> None:
    """Remove each folder, in the order given (deepest first), that is empty by then; a
    folder that holds anything, or cannot be removed, stays.

    Examples
    --------
    >>> remove_empty_folders([])
    """
    for folder in folders:
        with contextlib.suppress(OSError):
            os.rmdir(folder)


@contextlib.contextmanager
def output_folder(path: str | os.PathLike) -> Iterator[str]:
    """Make a folder for a command's outputs; if the block fails, remove what it made.

    The folder and its missing parents are created; when the block raises (an error, an
    interrupt), each folder this call created is removed again if it is still empty, so a
    failed run leaves no empty folder behind. A folder that existed before is left alone.

    Parameters
    ----------
    path : str or os.PathLike

    Yields
    ------
    str
        The folder's absolute path.

    Raises
    ------
    InputError
        The path (or a parent) is a regular file, or the folder cannot be created
        (read-only file system, no permission).

    Examples
    --------
    >>> with output_folder("out/shapes") as folder:  # doctest: +SKIP
    ...     save_mesh(os.path.join(folder, "a.obj"), V, F)
    """
    target = os.path.realpath(os.fspath(path))  # "link/../out" as the system reads it
    missing = missing_folders(target)
    probe = os.path.dirname(missing[-1]) if missing else target
    if not os.path.isdir(probe):
        raise InputError(f"cannot make the folder: {probe} is not a folder", path)
    try:
        os.makedirs(target, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot make the folder: {exc.strerror or exc}", path) from None
    if _JOURNAL is not None:  # removed again (when empty) if all_or_nothing's block fails
        _JOURNAL.extend(reversed(missing))
    try:
        yield target
    except BaseException:
        remove_empty_folders(missing)
        raise


#: folders whose stale temporaries this process has removed (once per folder and process)
_SWEPT: set[str] = set()

#: temporary names: ``.<name>.tmp-<8 hex><ext>`` (being written, locked) and
#: ``.<name>.new-<8 hex><ext>`` (just created, about to be locked and renamed)
_TEMPORARY = re.compile(r"^\..*\.(tmp|new)-[0-9a-f]{8}(\.[^.]*)?$")

#: the files :func:`atomic_output` created (where there was none) and the folders
#: :func:`output_folder` made inside :func:`all_or_nothing`, in order
_JOURNAL: list[str] | None = None


@contextlib.contextmanager
def all_or_nothing() -> Iterator[None]:
    """Remove the outputs a block created when it fails.

    Every file :func:`atomic_output` creates in the block (where no file was) and every
    folder :func:`output_folder` makes is recorded; when the block raises an exception or
    is interrupted (Ctrl-C), they are removed again, the last first (a folder only when
    it is empty), so a command stopped half-way leaves no output it made. A file the block
    replaced keeps its new content: its earlier one is not kept (keeping it would hold a
    copy of every replaced file until the end). ``SystemExit`` counts as completion (click
    exits so when the reader of a finished command's output goes away).

    Examples
    --------
    >>> with all_or_nothing():  # doctest: +SKIP
    ...     save_mesh("out/result.obj", V, F)
    ...     render_meshes([...], "out/preview.png")  # Ctrl-C here removes result.obj too
    """
    global _JOURNAL
    outer, _JOURNAL = _JOURNAL, []
    try:
        yield
    except BaseException as exc:
        made, _JOURNAL = _JOURNAL, outer
        if isinstance(exc, (SystemExit, GeneratorExit)):
            raise
        for path in reversed(made or ()):
            with contextlib.suppress(OSError):
                if os.path.isdir(path) and not os.path.islink(path):
                    os.rmdir(path)  # only if nothing else is in it
                else:
                    os.remove(path)
        raise
    else:  # an enclosing block takes over what this one made
        made, _JOURNAL = _JOURNAL, outer
        if outer is not None and made is not None:
            outer.extend(made)


def keep_outputs_as_written() -> None:
    """Inside :func:`all_or_nothing`: keep every output, those written so far and those to
    come (a resumable batch, whose finished items are its progress)."""
    global _JOURNAL
    _JOURNAL = None


@contextlib.contextmanager
def atomic_output(path: str | os.PathLike) -> Iterator[str]:
    """Write a file atomically: yield a temporary path, then rename it to ``path``.

    The temporary file ``.<name>.tmp-<8 hex digits><ext>`` is created (empty) in the
    destination's folder with the same extension, so writers that pick a format from the
    extension work. When the block succeeds the file is fsynced and renamed over ``path``
    with ``os.replace`` (keeping the mode of a file it replaces); when the block raises, it
    is removed and ``path`` is left untouched.

    A process killed while writing (SIGKILL, a power cut) cannot remove its temporary file.
    So the temporary file is locked (``flock``) for as long as it exists under that name (it
    is created as ``.<name>.new-...``, locked, then renamed, which keeps the lock), and the
    first write into a folder in a process removes the folder's unlocked temporary files:
    what dead writers left behind (``.new-`` ones only when older than a minute). A live
    writer's file is locked and stays. On file systems whose ``flock`` is emulated or absent
    (some NFS set-ups) nothing is ever taken for stale.

    Parameters
    ----------
    path : str or os.PathLike
        The final destination. Its folder must exist.

    Yields
    ------
    str
        The temporary path to write to.

    Raises
    ------
    InputError
        ``path`` is a directory, its folder does not exist or cannot be written.

    Examples
    --------
    >>> with atomic_output("out/preview.png") as tmp:  # doctest: +SKIP
    ...     figure.savefig(tmp)
    """
    target = os.path.abspath(os.fspath(path))
    folder, name = os.path.split(target)
    if os.path.isdir(target):
        raise InputError("is a directory; cannot write a file there", path)
    if not os.path.isdir(folder):
        raise InputError(f"cannot write: folder {folder} does not exist", path)
    if folder not in _SWEPT:
        _remove_stale_temporaries(folder)
        _SWEPT.add(folder)
    root, ext = os.path.splitext(name)
    while True:
        token = secrets.token_hex(4)
        fresh = os.path.join(folder, f".{root}.new-{token}{ext}")
        tmp = os.path.join(folder, f".{root}.tmp-{token}{ext}")
        try:
            lock = os.open(fresh, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
        except FileExistsError:
            continue
        except OSError as exc:
            raise InputError(f"cannot write: {exc.strerror or exc}", path) from None
        if os.path.lexists(tmp):  # a name clash: try another token
            os.close(lock)
            os.remove(fresh)
            continue
        break
    try:
        _lock(lock, blocking=True)
        os.rename(fresh, tmp)  # the same inode, still locked: never unlocked under .tmp-
        try:
            yield tmp
            _fsync_written(tmp, lock)
            with contextlib.suppress(OSError):
                os.chmod(tmp, stat.S_IMODE(os.stat(target).st_mode))
            created = not os.path.lexists(target)
            os.replace(tmp, target)
            if created and _JOURNAL is not None:
                _JOURNAL.append(target)
        except BaseException:
            with contextlib.suppress(OSError):
                os.remove(tmp)
            raise
    finally:
        with contextlib.suppress(OSError):
            os.remove(fresh)  # only there if the rename failed
        os.close(lock)
    with contextlib.suppress(OSError):  # make the rename itself durable (POSIX)
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def _fsync_written(tmp: str, lock: int) -> None:
    """fsync what was written to ``tmp``: through the lock's descriptor when it is still
    the same file (opening and closing another descriptor would drop an emulated lock)."""
    if os.fstat(lock).st_ino == os.stat(tmp).st_ino:
        os.fsync(lock)
        return
    fd = os.open(tmp, os.O_RDONLY)  # the writer replaced the file
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _lock(fd: int, blocking: bool) -> bool:
    """An exclusive ``flock`` on ``fd``; False if another process holds one (non-blocking).

    Where ``fcntl`` is missing (not POSIX) or the file system has no locks, nothing is
    locked and False is returned, so that no temporary file is ever taken for stale there.
    """
    try:
        import fcntl
    except ImportError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | (0 if blocking else fcntl.LOCK_NB))
    except OSError:  # held by another process, or no locks on this file system
        return False
    return True


def _remove_stale_temporaries(folder: str) -> None:
    """Remove the unlocked temporary files in ``folder`` (what dead writers left)."""
    import time

    try:
        names = [n for n in os.listdir(folder) if n.startswith(".") and _TEMPORARY.match(n)]
    except OSError:
        return
    for stale in names:
        candidate = os.path.join(folder, stale)
        try:
            info = os.lstat(candidate)
        except OSError:
            continue
        if not stat.S_ISREG(info.st_mode):  # a link, a FIFO, a folder: not ours
            continue
        if ".new-" in stale and time.time() - info.st_mtime < 60:
            continue  # being created right now, about to be locked
        try:
            fd = os.open(candidate, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_NOFOLLOW", 0))
        except OSError:
            continue
        try:
            opened = os.fstat(fd)
            same = (opened.st_ino, opened.st_dev) == (info.st_ino, info.st_dev)
            if same and stat.S_ISREG(opened.st_mode) and _lock(fd, blocking=False):
                with contextlib.suppress(OSError):
                    os.remove(candidate)
        finally:
            os.close(fd)
