"""Side-by-side pictures of meshes, point clouds and their cages (matplotlib, no screen).

The pictures are for looking at results quickly (``cagekit render``, ``--preview``), not
for publication: every face is drawn flat-shaded by a Lambert-like term from a light fixed
relative to the camera, so surface detail reads clearly; cages are drawn as wireframes on
top of their shape; point clouds as dots. Matplotlib's painter's algorithm sorts faces by
depth, which is good enough for closed shapes seen from outside.

Nothing here touches :mod:`matplotlib.pyplot` or the global backend: figures are plain
:class:`matplotlib.figure.Figure` objects saved with the Agg renderer, so rendering works
without a display and does not disturb a caller's own plotting.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Sequence
from typing import TypeAlias

import numpy as np
from matplotlib.figure import Figure
from mpl_toolkits.mplot3d import Axes3D  # noqa: F401  (registers the "3d" projection)
from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection
from numpy.typing import ArrayLike

from cagekit.cage import unique_edges
from cagekit.geometry import as_shape
from cagekit.io.files import atomic_output, distinct_tails

__all__ = ["MAX_FACES", "MAX_POINTS", "render_meshes", "render_grid",
           "shortest_unique_names"]

#: At most this many faces of one mesh are drawn; larger meshes are subsampled
#: (deterministically) so that a picture takes seconds, not minutes.
MAX_FACES = 20_000
#: At most this many points of one point cloud are drawn.
MAX_POINTS = 20_000

_DPI = 100
_SURFACE_RGB = np.array([0.62, 0.72, 0.86])
_CLOUD_RGB = (0.25, 0.42, 0.70)
_CAGE_RGB = (0.85, 0.33, 0.10)
_AMBIENT = 0.22

#: a shape as the renderers take it: ``(V, F)``, ``F`` None or empty for a point cloud
_ShapeLike: TypeAlias = tuple[ArrayLike, ArrayLike | None]


def shortest_unique_names(paths: Sequence[str | os.PathLike]) -> list[str]:
    """The shortest trailing part of each path that no other path ends with (panel titles).

    A file name alone where it is unique, else as many of its folders as tell it apart
    (``/``-separated); a file given twice (the same normalised path) gets one name.

    Parameters
    ----------
    paths : sequence of str or os.PathLike

    Returns
    -------
    list of str
        One name per path, in order.

    Examples
    --------
    >>> shortest_unique_names(["out/girl/pose_003.obj", "out/suit/pose_003.obj", "rest.obj"])
    ['girl/pose_003.obj', 'suit/pose_003.obj', 'rest.obj']
    """
    return distinct_tails([os.path.normpath(os.fspath(p)).replace(os.sep, "/").split("/")
                           for p in paths])


def _to_display(V: np.ndarray, up: str) -> np.ndarray:
    """Rotate a shape so that its ``up`` axis becomes matplotlib's vertical z axis."""
    if up == "z":
        return V
    if up == "y":  # rotation by +90 degrees about x: (x, y, z) -> (x, -z, y)
        return np.stack([V[:, 0], -V[:, 2], V[:, 1]], axis=1)
    if up == "x":  # (x, y, z) -> (y, z, x), a cyclic permutation (a rotation)
        return np.stack([V[:, 1], V[:, 2], V[:, 0]], axis=1)
    raise ValueError(f"up must be 'x', 'y' or 'z', got {up!r}")


def _power_of_two_scale(arrays: Sequence[np.ndarray]) -> float:
    """The power of two at or just below the largest finite absolute coordinate (1.0 if none).

    Dividing by it is exact, so the picture does not change, but coordinates of any
    magnitude (1e200, 1e-200) come to [-2, 2] and their squares and cross products
    neither overflow nor underflow.
    """
    finite = [np.abs(a[np.isfinite(a)]) for a in arrays if a.size]
    largest = max((float(a.max()) for a in finite if a.size), default=0.0)
    return float(np.ldexp(1.0, int(np.frexp(largest)[1]) - 1)) if largest > 0 else 1.0


def _camera_frame(elev: float, azim: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit vectors (towards camera, screen right, screen up) of a matplotlib 3D view."""
    e, a = np.radians(elev), np.radians(azim)
    eye = np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])
    right = np.array([-np.sin(a), np.cos(a), 0.0])
    up = np.cross(eye, right)
    return eye, right, up


def _face_colors(V: np.ndarray, F: np.ndarray, light: np.ndarray) -> np.ndarray:
    """Flat, two-sided Lambert shading of each face: ``(m, 4)`` RGBA in [0, 1]."""
    tri = V[F[:, :3]]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.divide(n, norm, out=np.zeros_like(n), where=norm > 0)
    lambert = np.abs(n @ light)
    shade = _AMBIENT + (1.0 - _AMBIENT) * lambert
    rgb = np.clip(shade[:, None] * _SURFACE_RGB[None, :], 0.0, 1.0)
    return np.concatenate([rgb, np.ones((len(F), 1))], axis=1)


def _is_closed_oriented(F: np.ndarray) -> bool:
    """True if every directed edge occurs once and its reverse once (closed, oriented)."""
    if len(F) == 0 or F.shape[1] != 3:
        return False
    directed = np.stack([F, np.roll(F, -1, axis=1)], axis=-1).reshape(-1, 2)
    key = directed[:, 0] * (int(F.max()) + 1) + directed[:, 1]
    rkey = directed[:, 1] * (int(F.max()) + 1) + directed[:, 0]
    skey = np.sort(key)
    if np.any(skey[1:] == skey[:-1]):
        return False
    pos = np.searchsorted(skey, rkey).clip(0, len(skey) - 1)
    return bool(np.all(skey[pos] == rkey))


def _cluster_faces(V: np.ndarray, F: np.ndarray, cells: int) -> tuple[np.ndarray, np.ndarray]:
    """Vertex-clustering simplification on a ``cells``-per-axis grid.

    Vertices in one grid cell are merged at their mean; faces that collapse are dropped and
    duplicates removed. Deterministic, no holes, and cheap: a coarse stand-in for drawing.
    """
    lo = V.min(axis=0)
    step = max(float((V.max(axis=0) - lo).max()) / cells, 1e-300)
    ijk = np.floor((V - lo) / step).astype(np.int64)
    _, cluster = np.unique(ijk, axis=0, return_inverse=True)
    cluster = cluster.reshape(-1)
    counts = np.bincount(cluster)
    Vc = np.stack([np.bincount(cluster, V[:, d]) for d in range(3)], axis=1) / counts[:, None]
    Fc = cluster[F]
    ok = (Fc[:, 0] != Fc[:, 1]) & (Fc[:, 1] != Fc[:, 2]) & (Fc[:, 2] != Fc[:, 0])
    Fc = Fc[ok]
    _, first = np.unique(np.sort(Fc, axis=1), axis=0, return_index=True)
    return Vc, Fc[np.sort(first)]


def _visible_faces(
    V: np.ndarray, F: np.ndarray, eye: np.ndarray, limit: int
) -> tuple[np.ndarray, np.ndarray]:
    """At most ``limit`` faces to draw, chosen deterministically: ``(V', F')``.

    A closed, consistently oriented mesh first loses the faces turned away from the camera
    (they are hidden anyway); a mesh still over the limit is simplified by vertex clustering
    (so that it stays solid-looking), and as a last resort its faces are subsampled.
    """
    if len(F) <= limit:
        return V, F
    if _is_closed_oriented(F):
        tri = V[F]
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        facing = n @ eye
        volume = float(np.einsum("ij,ij->i", tri[:, 0], n).sum())
        F = F[facing >= 0] if volume >= 0 else F[facing <= 0]
    cells = max(int(np.sqrt(limit)), 4)
    for _ in range(6):
        if len(F) <= limit:
            break
        Vc, Fc = _cluster_faces(V, F, cells)
        if len(Fc) <= limit:
            V, F = Vc, Fc
            break
        cells = max(int(cells * 0.95 * np.sqrt(limit / len(Fc))), 2)
    return V, F[_subsample(len(F), limit)]


def _subsample(n: int, limit: int, seed: int = 0) -> np.ndarray:
    """Indices of at most ``limit`` of ``n`` items, chosen deterministically, sorted."""
    if n <= limit:
        return np.arange(n)
    rng = np.random.default_rng(seed)
    return np.sort(rng.choice(n, size=limit, replace=False))


def _draw_panel(ax, V, F, cage, elev, azim, limits, max_faces) -> None:
    """Draw one shape (and optionally its cage) into a 3D axes."""
    eye, right, up = _camera_frame(elev, azim)
    # a light above, left of and in front of the camera, fixed relative to the view
    light = eye + 0.8 * up - 0.6 * right
    light /= np.linalg.norm(light)

    ax.computed_zorder = False  # draw in the order added: surface first, then the cage
    if len(F):
        Vd, Fd = _visible_faces(V, F[:, :3], eye, max_faces)
        colors = _face_colors(Vd, Fd, light)
        poly = Poly3DCollection(
            Vd[Fd], facecolors=colors, edgecolors=colors, linewidths=0.15
        )
        poly.set_zorder(1)
        ax.add_collection3d(poly)
    elif len(V):
        P = V[_subsample(len(V), MAX_POINTS)]
        s = float(np.clip(30000.0 / max(len(P), 1), 1.5, 16.0))
        ax.scatter(P[:, 0], P[:, 1], P[:, 2], s=s, c=[_CLOUD_RGB], marker="o",
                   linewidths=0, depthshade=True, zorder=1)
    if cage is not None:
        CV, CF = cage
        edges = unique_edges(CF)
        if len(edges):
            lines = Line3DCollection(CV[edges], colors=[_CAGE_RGB], linewidths=0.8, alpha=0.75)
            lines.set_zorder(2)
            ax.add_collection3d(lines)
        ax.scatter(CV[:, 0], CV[:, 1], CV[:, 2], s=6, c=[_CAGE_RGB], depthshade=False,
                   linewidths=0, zorder=3)

    lo, hi = limits
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_zlim(lo[2], hi[2])
    ax.set_box_aspect((1.0, 1.0, 1.0), zoom=1.5)
    ax.set_proj_type("ortho")
    ax.view_init(elev=elev, azim=azim)
    ax.set_axis_off()


def _cube_limits(points: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """A cube (equal extents on all axes) around all given point sets."""
    finite = [p[np.isfinite(p).all(axis=1)] for p in points if len(p)]
    finite = [p for p in finite if len(p)]
    if not finite:
        return -np.ones(3), np.ones(3)
    allp = np.concatenate(finite, axis=0)
    centre = 0.5 * (allp.min(axis=0) + allp.max(axis=0))
    # the bounding sphere about the box centre: its projection fits any view
    half = float(np.sqrt(((allp - centre) ** 2).sum(axis=1).max()))
    if not half > 0:
        half = 1.0
    return centre - half, centre + half


def render_meshes(
    meshes: Iterable[_ShapeLike],
    path: str | os.PathLike,
    cages: Iterable[_ShapeLike | None] | None = None,
    titles: Iterable[str] | None = None,
    caption: str | None = None,
    views: Sequence[tuple[float, float]] = ((20, -60),),
    size: tuple[int, int] = (480, 480),
    up: str = "y",
    same_scale: bool = False,
    frame_cages: bool = True,
) -> str:
    """Draw shapes side by side and write the picture as a PNG file (atomically).

    Parameters
    ----------
    meshes : sequence of (V, F)
        One ``(n, 3)`` float vertex array and ``(m, 3)`` int face array per panel. A shape
        with no faces (``F`` empty or None) is a point cloud and is drawn as dots.
    path : str or os.PathLike
        Output PNG file. Written to a temporary file in the same folder, then renamed
        (:func:`cagekit.io.files.atomic_output`); its folder must exist.
    cages : sequence of (V, F) or None, optional
        Same length as ``meshes``; the cage of each shape (or None), drawn as a wireframe
        of its unique edges over the shape.
    titles : sequence of str, optional
        One title per shape, shown above its panel (first row of views only). Shown
        literally: ``$`` does not start matplotlib mathtext.
    caption : str, optional
        A line of text at the bottom of the picture, shown literally as the titles.
    views : sequence of (elev, azim)
        Camera angles in degrees, as :meth:`Axes3D.view_init`; one row of panels per view.
    size : (int, int)
        Width and height of one panel in pixels. The picture is
        ``len(meshes) * size[0]`` pixels wide and ``len(views) * size[1]`` pixels tall.
    up : {'y', 'z', 'x'}
        The shapes' vertical axis (OBJ/ShapeNet files are usually y-up).
    same_scale : bool
        If True, all panels share one frame (compare shapes in the same units); otherwise
        each panel is fitted to its own shape and cage.
    frame_cages : bool, default True
        Whether the cages count in the frames; False frames the shapes alone and cuts the
        cages at the panels' edges (a cage much larger than its shape, as a learned
        model's, would otherwise shrink the shape to a corner of its panel).

    Returns
    -------
    str
        ``path``, as a string.

    Raises
    ------
    ValueError
        If the arrays have the wrong shape, or ``cages``/``titles`` have the wrong length.
    cagekit.errors.InputError
        If ``path`` is a folder or its folder does not exist (raised by
        :func:`cagekit.io.files.atomic_output`; also a ``ValueError``).

    Examples
    --------
    >>> V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    >>> F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    >>> render_meshes([(V, F), (V, None)], "tetra.png", titles=["mesh", "points"])  # doctest: +SKIP
    'tetra.png'
    """
    meshes = list(meshes)
    if not meshes:
        raise ValueError("render_meshes needs at least one shape")
    shapes = [as_shape(m, name=f"shape {i}") for i, m in enumerate(meshes)]
    if cages is None:
        cages = [None] * len(shapes)
    cages = list(cages)
    if len(cages) != len(shapes):
        raise ValueError(f"got {len(cages)} cages for {len(shapes)} shapes")
    cage_arrays = [None if c is None else as_shape(c, name=f"cage {i}")
                   for i, c in enumerate(cages)]
    if titles is not None:
        titles = [str(t) for t in titles]
        if len(titles) != len(shapes):
            raise ValueError(f"got {len(titles)} titles for {len(shapes)} shapes")
    views = [(float(e), float(a)) for e, a in views]
    if not views:
        raise ValueError("render_meshes needs at least one view")
    width, height = int(size[0]), int(size[1])
    if width < 16 or height < 16:
        raise ValueError(f"panel size must be at least 16 x 16 pixels, got {size}")

    # an exact power-of-two rescale of each panel (of all with same_scale): the same
    # picture, without overflow or underflow for very large or small coordinates
    units = [_power_of_two_scale([V] + ([] if c is None else [c[0]]))
             for (V, _), c in zip(shapes, cage_arrays)]
    if same_scale:
        units = [max(units)] * len(units)
    shapes = [(_to_display(V / u, up), F) for (V, F), u in zip(shapes, units)]
    cage_arrays = [None if c is None else (_to_display(c[0] / u, up), c[1])
                   for c, u in zip(cage_arrays, units)]
    panel_points = [
        [V] + ([] if c is None or not frame_cages else [c[0]])
        for (V, _), c in zip(shapes, cage_arrays)
    ]
    if same_scale:
        common = _cube_limits([p for pts in panel_points for p in pts])
        limits = [common] * len(shapes)
    else:
        limits = [_cube_limits(pts) for pts in panel_points]

    ncols, nrows = len(shapes), len(views)
    total_w, total_h = ncols * width, nrows * height
    fig = Figure(figsize=(total_w / _DPI, total_h / _DPI), dpi=_DPI)
    fig.patch.set_facecolor("white")
    # room (in pixels) kept free for the titles above the first row and the caption below
    top_px = min(24, height // 4) if titles is not None else 0
    bottom_px = min(6 + 16 * (caption.count("\n") + 1), height // 3) if caption else 0
    for r, (elev, azim) in enumerate(views):
        y0_px = (nrows - 1 - r) * height + (bottom_px if r == nrows - 1 else 0)
        h_px = height - (top_px if r == 0 else 0) - (bottom_px if r == nrows - 1 else 0)
        for c, ((V, F), cage) in enumerate(zip(shapes, cage_arrays)):
            ax = fig.add_subplot(nrows, ncols, r * ncols + c + 1, projection="3d")
            ax.set_position([c / ncols, y0_px / total_h, 1.0 / ncols, h_px / total_h])
            _draw_panel(ax, V, F, cage, elev, azim, limits[c], MAX_FACES)
            if titles is not None and r == 0:
                fig.text((c + 0.5) / ncols, 1.0 - 4.0 / total_h, titles[c], ha="center",
                         va="top", fontsize=11, parse_math=False)
    if caption:
        fig.text(0.5, 3.0 / total_h, caption, ha="center", va="bottom", fontsize=10,
                 color="0.25", parse_math=False)

    with atomic_output(path) as tmp:
        fig.savefig(tmp, format="png", dpi=_DPI, facecolor="white")
    return os.fspath(path)


def render_grid(path: str | os.PathLike, rows: Iterable[Iterable[_ShapeLike]], *,
                cages: Sequence[Iterable[_ShapeLike | None] | None] | None = None,
                titles: Sequence[Iterable[str] | None] | None = None,
                captions: Sequence[str | None] | None = None,
                size: tuple[int, int] = (240, 300), same_scale: bool = False,
                views: Sequence[tuple[float, float]] = ((20, -60),), up: str = "y",
                columns: int = 1) -> str:
    """Rows of shapes in one PNG (atomically): each row a :func:`render_meshes` picture.

    Parameters
    ----------
    path : str or os.PathLike
        Output PNG file.
    rows : sequence of sequences of (V, F)
        The shapes of each row, left to right; rows may differ in length (shorter ones
        are padded with white on the right).
    cages, titles : sequences (one per row) of sequences (one per shape), optional
        As :func:`render_meshes` takes them for one row; None for a row without.
    captions : sequence of str, optional
        A caption under each row (None for none; may hold line breaks).
    size, same_scale, views, up
        As :func:`render_meshes`, for every row (``same_scale`` within a row).
    columns : int, default 1
        Rows placed side by side, this many to a line of the picture (a contact sheet of
        many short rows stays near square).

    Returns
    -------
    str
        ``path``, as a string.

    Examples
    --------
    >>> V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    >>> F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    >>> render_grid("grid.png", [[(V, F)] * 3, [(V, F)]])  # doctest: +SKIP
    'grid.png'
    """
    import tempfile

    from matplotlib.image import imread

    rows = [list(r) for r in rows]
    if not rows:
        raise ValueError("render_grid needs at least one row")
    for name, per_row in (("cages", cages), ("titles", titles), ("captions", captions)):
        if per_row is not None and len(per_row) != len(rows):
            raise ValueError(f"got {len(per_row)} {name} for {len(rows)} rows")
    images = []
    with tempfile.TemporaryDirectory() as tmp:
        for i, meshes in enumerate(rows):
            png = os.path.join(tmp, f"row{i}.png")
            render_meshes(meshes, png, cages=None if cages is None else cages[i],
                          titles=None if titles is None else titles[i],
                          caption=None if captions is None else captions[i], size=size,
                          same_scale=same_scale, views=views, up=up)
            images.append(imread(png)[..., :3])
    lines = [_side_by_side(images[i:i + columns], axis=1)
             for i in range(0, len(images), max(1, int(columns)))]
    grid = _side_by_side(lines, axis=0)
    fig = Figure(figsize=(grid.shape[1] / _DPI, grid.shape[0] / _DPI), dpi=_DPI)
    ax = fig.add_axes((0, 0, 1, 1))
    ax.imshow(grid, interpolation="nearest")
    ax.axis("off")
    with atomic_output(path) as tmp:
        fig.savefig(tmp, format="png", dpi=_DPI)
    return os.fspath(path)


def _side_by_side(images, axis: int) -> np.ndarray:
    """Images joined along ``axis`` (0: stacked, 1: in a line), padded with white."""
    other = 1 - axis
    extent = max(image.shape[other] for image in images)
    padded = []
    for image in images:
        pad = [(0, 0), (0, 0), (0, 0)]
        pad[other] = (0, extent - image.shape[other])
        padded.append(np.pad(image, pad, constant_values=1.0))
    return np.concatenate(padded, axis=axis)
