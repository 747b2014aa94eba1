"""Exceptions raised by cagekit.

Every problem caused by the user's input (a file, an array, a cage) raises a subclass of
:class:`InputError`. The message is one line that names the file (when there is one) and the
problem, so the command line can print it as is and exit with status 2. What is accepted but
worth knowing (faces dropped from a file, points outside their cage) is a
:class:`CagekitWarning`, issued with :func:`warnings.warn`; the command line prints each as
one line.
"""

from __future__ import annotations

import os
from collections.abc import Iterator

__all__ = ["InputError", "MeshFileError", "LandmarkFileError", "CageError", "CageFitError",
           "OutsideCageError", "CagekitWarning",
           "MeshFileWarning", "OutsideCageWarning"]  # and exception_chain, a helper of the
#  command line and the optimiser that `import cagekit` does not export


class InputError(ValueError):
    """Bad user input: a file that cannot be read, an array with NaN, an invalid cage.

    Parameters
    ----------
    message : str
        What is wrong, in one line.
    path : str or os.PathLike, optional
        The file the problem was found in; it is prefixed to the message.
    """

    def __init__(self, message: str, path: str | os.PathLike | None = None):
        self.path = None if path is None else os.fspath(path)
        self.problem = message
        text = message if self.path is None else f"{self.path}: {message}"
        super().__init__(text)


class MeshFileError(InputError):
    """A mesh or point-cloud file is missing, empty, unparsable or holds invalid data."""


class LandmarkFileError(InputError):
    """A landmark file is missing, empty, unparsable or holds invalid data."""


class CageError(InputError):
    """A cage is not a closed, 2-manifold, consistently oriented triangle mesh."""


class CageFitError(InputError):
    """No cage meeting every guarantee could be built (``cagekit.fit_cage``, the character
    cage of a transfer); the message says what failed.

    Attributes
    ----------
    cage : (cage_v, cage_f) or None
        The cage that failed, to look at, when there is one (the character cage).
    missed : list of str or None
        The labels of the landmarks the character cage missed by too much, the worst first.
    outside_near : dict of str to int or None
        For the points left outside, how many lie nearest each landmark.
    """

    cage: tuple | None = None
    missed: list[str] | None = None
    outside_near: dict[str, int] | None = None


class OutsideCageError(InputError):
    """Most of a shape lies outside the cage given for it: a cage in other units or placed
    elsewhere, most likely (the message says which, when the sizes or centres tell)."""


class CagekitWarning(UserWarning):
    """Something accepted that the user should know about (one line, like InputError)."""


class MeshFileWarning(CagekitWarning):
    """A file was read, but parts of it were dropped (faces with fewer than 3 vertices)."""


class OutsideCageWarning(CagekitWarning):
    """Some bound points lie outside their cage: their coordinates extrapolate."""


def exception_chain(exc: BaseException) -> Iterator[BaseException]:
    """``exc`` and every exception of its cause/context chain, each once.

    Examples
    --------
    >>> try:
    ...     try:
    ...         raise KeyError("inner")
    ...     except KeyError as inner:
    ...         raise ValueError("outer") from inner
    ... except ValueError as outer:
    ...     [type(e).__name__ for e in exception_chain(outer)]
    ['ValueError', 'KeyError']
    """
    todo, seen = [exc], set()
    while todo:
        exc = todo.pop()
        if exc is None or id(exc) in seen:
            continue
        seen.add(id(exc))
        yield exc
        todo += [e for e in (exc.__cause__, exc.__context__) if e is not None]  # context first
