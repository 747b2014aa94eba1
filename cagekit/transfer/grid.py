"""The picture of a transfer (``cagekit transfer --grid``): rest poses first, then each pose.

The template above, the character below, in columns: the rest pose of each first, then the
poses, :data:`PER_LINE` columns to a line of the picture (pairs of rows), at most
:data:`MAX_POSES` poses; the poses left out are named under the last row and returned, so
that the command can say so too.
"""

from __future__ import annotations

import os
from collections.abc import Sequence

from numpy.typing import ArrayLike

from cagekit.errors import InputError

__all__ = ["MAX_POSES", "PER_LINE", "PANEL", "grid_columns", "transfer_grid"]

#: poses drawn at most (with the rest pose: two lines of :data:`PER_LINE` columns)
MAX_POSES = 11
#: columns to a line of the picture
PER_LINE = 6
#: width and height of one panel in pixels
PANEL = (320, 400)

_Mesh = tuple[ArrayLike, ArrayLike]


def grid_columns(names: Sequence[str], max_poses: int = MAX_POSES,
                 per_line: int = PER_LINE) -> tuple[list[list[int]], list[str]]:
    """Which poses the picture shows, line by line, and which it leaves out.

    Parameters
    ----------
    names : sequence of str
        The poses' names, in order.
    max_poses : int
        Poses shown at most (the first ones).
    per_line : int
        Columns to a line; the rest pose takes the first column of the first line.

    Returns
    -------
    lines : list of list of int
        Per line of the picture, the poses' indices in ``names``; -1 is the rest pose.
    left_out : list of str
        The names not shown.

    Examples
    --------
    >>> grid_columns(["a", "b", "c"], max_poses=2, per_line=2)
    ([[-1, 0], [1]], ['c'])
    """
    shown = [-1, *range(min(len(names), max_poses))]
    lines = [shown[i:i + per_line] for i in range(0, len(shown), per_line)]
    return lines, list(names[max_poses:])


def transfer_grid(path: str | os.PathLike[str], template_rest: _Mesh, character_rest: _Mesh,
                  template_poses: Sequence[_Mesh], character_poses: Sequence[_Mesh],
                  names: Sequence[str], *, max_poses: int = MAX_POSES,
                  per_line: int = PER_LINE,
                  panel: tuple[int, int] = PANEL) -> list[str]:
    """Draw the template's poses above the character's, rest poses first (PNG, atomic).

    Parameters
    ----------
    path : str or os.PathLike
        The PNG written; its folder must exist.
    template_rest, character_rest : ((n, 3) array_like of float, (m, 3) array_like of int)
        The two meshes in rest pose.
    template_poses, character_poses : sequences of (V, F)
        The template in each pose and the character carried to it, one per name.
    names : sequence of str
        The poses' names (the columns' titles).
    max_poses, per_line : int
        As :func:`grid_columns`.
    panel : (int, int)
        Width and height of one panel in pixels.

    Returns
    -------
    list of str
        The names of the poses left out (also written under the picture's last row).
    """
    from cagekit.render import render_grid

    if not len(template_poses) == len(character_poses) == len(names):
        raise InputError("one template pose and one character pose per name")
    lines, left_out = grid_columns(names, max_poses, per_line)
    rows, titles, captions = [], [], []
    for line in lines:
        rows.append([template_rest if i < 0 else template_poses[i] for i in line])
        rows.append([character_rest if i < 0 else character_poses[i] for i in line])
        titles += [["rest pose" if i < 0 else names[i] for i in line], None]
        captions += ["template", "transferred character"]
    if left_out:
        captions[-1] += (f"\n{len(left_out)} of {len(names)} poses not shown: "
                         f"{_listed(left_out)}")
    render_grid(path, rows, titles=titles, captions=captions, size=panel, same_scale=True,
                views=((10, -70),))
    return left_out


def _listed(names: Sequence[str], shown: int = 6) -> str:
    """A short list: all names, or the first ``shown`` ones and how many more.

    Examples
    --------
    >>> _listed(["a", "b"]), _listed(list("abcdefgh"), shown=3)
    ('a, b', 'a, b, c and 5 more')
    """
    if len(names) <= shown:
        return ", ".join(names)
    return f"{', '.join(names[:shown])} and {len(names) - shown} more"
