"""The contact sheet of a batch: a grid of variations readable at a glance.

Each :class:`Tile` shows one item: its variation large, the source and the target small
beside it, and under them three lines: the pair (short names, ``source -> target``), the
figures the filter decided on (CD x1e2, worst part's non-affinity, crossing parts), and
the status in its colour (ok green; rejected red when parts cross, orange otherwise) with
the reason, and what made the variation when a model's result was handed on (``ok (by box
scaling)``). Tiles stand :data:`SHEET_COLUMNS` to a line (fewer when there are fewer), as
many lines as needed. :func:`cagekit.batch.amplify.contact_sheet` builds the tiles of a
batch.
"""

from __future__ import annotations

import math
import os
import tempfile
import textwrap
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from cagekit.errors import InputError
from cagekit.io.files import atomic_output
from cagekit.render import render_meshes

__all__ = ["SHEET_COLUMNS", "STATUS_COLOURS", "TILE_SIZE", "Tile", "cut_middle",
           "draw_contact_sheet", "sheet_size", "status_colour", "tile_verdict"]

#: tiles side by side on a line of the sheet, at most
SHEET_COLUMNS = 5
#: a tile's width and height in pixels: the pictures (``TILE_SIZE[0]`` by two thirds of
#: it) above the text
TILE_SIZE = (300, 270)
#: a status's colour: ok, rejected (parts cross), rejected (other reasons)
STATUS_COLOURS = {"ok": "#2e7d32", "crossing": "#c62828", "rejected": "#e65100"}
_DPI = 100
#: characters across a tile: a 10-point bold title, a 9-point line, a 9-point bold line
_TITLE_CHARS, _LINE_CHARS, _BOLD_CHARS = 40, 50, 38


@dataclass(frozen=True)
class Tile:
    """One item of a contact sheet.

    Attributes
    ----------
    source, target, variation : ((n, 3) float array, (m, 3) int array)
        The meshes shown.
    title : str
        The pair, as ``"antiqueChair -> chair2"``.
    figures : str
        The figures the filter decided on, one line.
    status : str
        ``"ok"`` or ``"rejected"``.
    reason : str
        Why it was rejected (``""`` when ok).
    handed_on : str
        What made the variation instead of the batch's method, when something did (a
        model's result handed on as ``"box scaling"`` or ``"a fitted cage"``); ``""``
        otherwise.
    """

    source: tuple[np.ndarray, np.ndarray]
    target: tuple[np.ndarray, np.ndarray]
    variation: tuple[np.ndarray, np.ndarray]
    title: str
    figures: str
    status: str
    reason: str = ""
    handed_on: str = ""


def tile_verdict(tile: Tile) -> str:
    """The verdict a tile shows: ``ok`` or ``REJECTED: reason``, and what made the
    variation when the batch's method did not.

    Examples
    --------
    >>> empty = (np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64))
    >>> tile_verdict(Tile(empty, empty, empty, "a -> b", "", "ok", "", "box scaling"))
    'ok (by box scaling)'
    """
    by = f" (by {tile.handed_on})" if tile.handed_on else ""
    return f"ok{by}" if tile.status == "ok" else f"REJECTED{by}: {tile.reason}"


def status_colour(status: str, reason: str = "") -> str:
    """The colour a status is shown in (:data:`STATUS_COLOURS`).

    Parameters
    ----------
    status : str
        ``"ok"`` or ``"rejected"``.
    reason : str, default ""
        A rejection's reason: one that names crossing parts is red, any other orange.

    Returns
    -------
    str
        A matplotlib colour.

    Examples
    --------
    >>> status_colour("ok"), status_colour("rejected", "parts cross: 2 and 3")
    ('#2e7d32', '#c62828')
    """
    if status == "ok":
        return STATUS_COLOURS["ok"]
    return STATUS_COLOURS["crossing" if "parts cross" in reason else "rejected"]


def sheet_size(count: int, columns: int = SHEET_COLUMNS) -> tuple[int, int]:
    """The size in pixels, ``(width, height)``, of a sheet of ``count`` tiles.

    Parameters
    ----------
    count : int
        Tiles, at least 1.
    columns : int, default :data:`SHEET_COLUMNS`
        Tiles to a line, at most.

    Returns
    -------
    (int, int)

    Examples
    --------
    >>> sheet_size(3), sheet_size(12)
    ((900, 270), (1500, 810))
    """
    across = max(1, min(int(columns), int(count)))
    lines = math.ceil(count / across)
    return across * TILE_SIZE[0], lines * TILE_SIZE[1]


def draw_contact_sheet(tiles: Sequence[Tile], path: str | os.PathLike,
                       columns: int = SHEET_COLUMNS) -> str:
    """Write the tiles as one PNG (atomically), :func:`sheet_size` pixels.

    Parameters
    ----------
    tiles : sequence of Tile
        At least one.
    path : str or os.PathLike
        The PNG to write; its folder must exist.
    columns : int, default :data:`SHEET_COLUMNS`

    Returns
    -------
    str
        ``path``, as a string.

    Raises
    ------
    InputError
        No tiles.
    """
    from matplotlib.figure import Figure

    if not tiles:
        raise InputError("a contact sheet needs at least one tile")
    width, height = sheet_size(len(tiles), columns)
    across = width // TILE_SIZE[0]
    fig = Figure(figsize=(width / _DPI, height / _DPI), dpi=_DPI)
    fig.patch.set_facecolor("white")
    with tempfile.TemporaryDirectory() as tmp:
        for k, tile in enumerate(tiles):
            line, column = divmod(k, across)
            origin = (column * TILE_SIZE[0], height - (line + 1) * TILE_SIZE[1])
            _draw_tile(fig, tile, origin, (width, height), os.path.join(tmp, f"{k}-"))
    with atomic_output(path) as out:
        fig.savefig(out, format="png", dpi=_DPI, facecolor="white")
    return os.fspath(path)


def _draw_tile(fig, tile: Tile, origin, sheet, scratch: str) -> None:
    """Draw ``tile`` with its lower-left corner at ``origin`` (pixels) on a sheet of
    ``sheet`` (width, height) pixels."""
    from matplotlib.patches import Rectangle

    x0, y0 = origin
    w, h = TILE_SIZE
    big = 2 * w // 3
    small = w - big
    text_h = h - big
    colour = status_colour(tile.status, tile.reason)
    _picture(fig, tile.source, (x0, y0 + text_h + small), small, sheet, scratch + "s.png",
             "source")
    _picture(fig, tile.target, (x0, y0 + text_h), small, sheet, scratch + "t.png", "target")
    _picture(fig, tile.variation, (x0 + small, y0 + text_h), big, sheet, scratch + "v.png",
             None)
    inset = 3  # pixels: the frame stays inside its own tile
    fig.patches.append(Rectangle(((x0 + inset) / sheet[0], (y0 + inset) / sheet[1]),
                                 (w - 2 * inset) / sheet[0], (h - 2 * inset) / sheet[1],
                                 transform=fig.transFigure, fill=False, edgecolor=colour,
                                 linewidth=1.5))
    lines = [(cut_middle(tile.title, _TITLE_CHARS), 10, "bold", "black"),
             (cut_middle(tile.figures, _LINE_CHARS), 9, "normal", "0.25")]
    lines += [(cut_middle(text, _BOLD_CHARS), 9, "bold", colour)
              for text in textwrap.wrap(tile_verdict(tile), _BOLD_CHARS)[:2]]
    top = y0 + text_h - 4
    for text, size, weight, ink in lines:
        fig.text((x0 + 6) / sheet[0], top / sheet[1], _fit_pixels(text, size, weight, w - 12),
                 ha="left", va="top", fontsize=size, fontweight=weight, color=ink,
                 parse_math=False)
        top -= size + 6


def _picture(fig, mesh, corner, side: int, sheet, scratch: str, label: str | None) -> None:
    """One mesh drawn ``side`` pixels square with its lower-left corner at ``corner``."""
    from matplotlib.image import imread

    render_meshes([mesh], scratch, size=(side, side))
    ax = fig.add_axes((corner[0] / sheet[0], corner[1] / sheet[1], side / sheet[0],
                       side / sheet[1]))
    ax.imshow(imread(scratch)[..., :3], interpolation="antialiased")
    ax.axis("off")
    if label:
        ax.text(0.08, 0.95, label, transform=ax.transAxes, ha="left", va="top", fontsize=8,
                color="0.4", parse_math=False)


def _fit_pixels(text: str, size: float, weight: str, pixels: float) -> str:
    """``text`` cut in the middle (:func:`cut_middle`) until it is at most ``pixels`` wide, drawn
    at ``size`` points and ``weight`` on the sheet: a count of characters does not bound
    a width (``stool → kush_nuba_camp_bench`` ran into the next tile). A pair title
    (``source → target``) keeps its arrow: the longer name is cut first."""
    from matplotlib.font_manager import FontProperties
    from matplotlib.textpath import TextPath

    font = FontProperties(size=size, weight=weight)

    def fits(candidate: str) -> bool:  # `$` escaped: TextPath would read $...$ as maths
        path = TextPath((0, 0), candidate.replace("$", r"\$"), prop=font)
        return path.get_extents().x1 * _DPI / 72 <= pixels

    names = text.split(" → ")
    if len(names) == 2:
        widths = [len(name) for name in names]
        while not fits(" → ".join(map(cut_middle, names, widths))) and max(widths) > 4:
            widths[0 if widths[0] >= widths[1] else 1] -= 1
        text = " → ".join(map(cut_middle, names, widths))
    cuts = (cut_middle(text, width) for width in range(len(text), 3, -1))
    return next((cut for cut in cuts if fits(cut)), cut_middle(text, 4))


def cut_middle(text: str, width: int) -> str:
    """``text`` cut in the middle to ``width`` characters (both ends stay readable).

    Examples
    --------
    >>> cut_middle("antiqueChair", 9)
    'ant...air'
    """
    if len(text) <= width:
        return text
    keep = width - 3
    return text[: (keep + 1) // 2] + "..." + text[len(text) - keep // 2:]
