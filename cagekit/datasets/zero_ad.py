"""Real game-art furniture: the tables and benches of Debian's ``0ad-data``.

Debian's package ``0ad-data`` (``apt-get install 0ad-data``, 1.4 GB) ships the art of the
game 0 A.D. by Wildfire Games (CC BY-SA 3.0) in one archive,
``/usr/share/games/0ad/mods/public/public.zip``: about 4,000 PMD meshes
(:mod:`cagekit.io.pmd`). Among its props are a few pieces of furniture, low-poly (42-44
triangles for a table: a top and four legs, each an open box) and unlike the
``sweethome3d-furniture`` models the learned mode trains on (thousands of triangles, closed
parts). :data:`FURNITURE` names the ones that are furniture and nothing else (the game's
tables laden with weapons or food, and its building parts, are left out);
:func:`furniture` unpacks them into a cache folder as the ``.pmd`` files they are
(:func:`cagekit.io.load_mesh` reads them). They are a second set of unseen real test shapes
for ``benchmarks/bench_learn_real.py`` (``--test-set 0ad``), never trained on. Nothing is
downloaded: without the package :func:`furniture` raises an
:class:`~cagekit.errors.InputError` that says how to install it.

Examples
--------
>>> tables = furniture(["table"])  # doctest: +SKIP
>>> [m.name for _, m in tables]  # doctest: +SKIP
['Rectangular table', 'Square table', 'Long table', 'Short table']
"""

from __future__ import annotations

import os
import zipfile
from collections.abc import Iterable

from cagekit.datasets.sweethome3d import Model
from cagekit.errors import InputError
from cagekit.io.files import atomic_output

__all__ = ["PUBLIC_ZIP", "LICENSE", "CREATOR", "FURNITURE", "furniture", "meshes"]

#: where Debian puts the game's art
PUBLIC_ZIP = "/usr/share/games/0ad/mods/public/public.zip"
#: the licence of the game's art, and whom to credit
LICENSE = "CC BY-SA 3.0"
CREATOR = "Wildfire Games"

#: kind -> (name, member of the archive) of each piece of furniture used, in this order
FURNITURE = {
    "table": (
        ("Rectangular table", "art/meshes/props/table_rect.dae.cached.pmd"),
        ("Square table", "art/meshes/props/table_square.dae.cached.pmd"),
        ("Long table", "art/meshes/props/wrld_table_long.dae.cached.pmd"),
        ("Short table", "art/meshes/props/wrld_table_short.dae.cached.pmd"),
    ),
    "stool or bench": (
        ("Bench", "art/meshes/props/bench.dae.cached.pmd"),
        ("Nuba camp bench", "art/meshes/props/kush_nuba_camp_bench.dae.cached.pmd"),
    ),
}


def furniture(kinds: Iterable[str] = tuple(FURNITURE), cache: str = "out/0ad",
              archive: str = PUBLIC_ZIP) -> list[tuple[str, Model]]:
    """The game's furniture of some kinds, unpacked into ``cache``.

    Parameters
    ----------
    kinds : iterable of str, default every kind of :data:`FURNITURE`
        ``"table"``, ``"stool or bench"``; a kind with no furniture here gives none.
    cache : str, default "out/0ad"
        Where the PMD files are written (once; again when the archive is newer).
    archive : str
        The game's ``public.zip``.

    Returns
    -------
    list of (kind, Model)
        Kind by kind, in :data:`FURNITURE`'s order; ``Model.catalog`` is ``"0ad-data"``,
        its creator :data:`CREATOR` and licence :data:`LICENSE`.

    Raises
    ------
    InputError
        The archive is missing (the package is not installed) or lacks a model.
    """
    _require(archive)
    wanted = [(kind, name, member) for kind in kinds for name, member in FURNITURE.get(kind, ())]
    out = []
    with zipfile.ZipFile(archive) as zf:
        for kind, name, member in wanted:
            path = os.path.join(cache, os.path.basename(member).replace(".dae.cached", ""))
            _unpack_member(zf, member, path, archive)
            out.append((kind, Model(path=path, catalog="0ad-data", name=name,
                                    category=kind, creator=CREATOR, license=LICENSE)))
    return out


def meshes(count: int | None = None, cache: str = "out/0ad/all",
           archive: str = PUBLIC_ZIP) -> list[Model]:
    """The game's PMD meshes (all 4,010, or ``count`` of them spread evenly), unpacked.

    Parameters
    ----------
    count : int, optional
        How many: every k-th mesh of the archive's sorted list, k = total // count, the
        first ``count`` of them (the same ones on every machine). None: all.
    cache : str, default "out/0ad/all"
        Where the PMD files are written, under their folders in the archive.
    archive : str
        The game's ``public.zip``.

    Returns
    -------
    list of Model
        In the archive's sorted order; ``catalog`` is the mesh's folder below
        ``art/meshes`` (``props``, ``gaia``, ``structural``, ``skeletal``...), ``name``
        its file's stem, creator :data:`CREATOR` and licence :data:`LICENSE`.

    Raises
    ------
    InputError
        The archive is missing (the package is not installed), or ``count`` < 1.
    """
    _require(archive)
    if count is not None and count < 1:
        raise InputError(f"count must be at least 1, got {count}")
    out = []
    with zipfile.ZipFile(archive) as zf:
        members = sorted(m for m in zf.namelist() if m.endswith(".pmd"))
        if count is not None:
            members = members[::max(1, len(members) // count)][:count]
        for member in members:
            path = os.path.join(cache, member.replace(".dae.cached", ""))
            _unpack_member(zf, member, path, archive)
            parts = member.split("/")
            folder = parts[2] if len(parts) > 3 else "."
            name = os.path.basename(path)[: -len(".pmd")]
            out.append(Model(path=path, catalog=folder, name=name,
                             category="/".join(parts[2:-1]), creator=CREATOR,
                             license=LICENSE))
    return out


def _require(archive: str) -> None:
    """An InputError that says how to install the package, when its archive is missing."""
    if not os.path.isfile(archive):
        raise InputError("missing: install Debian's 0ad-data (apt-get install 0ad-data)",
                         archive)


def _unpack_member(zf: zipfile.ZipFile, member: str, path: str, archive: str) -> None:
    """Write one member of the archive to ``path``, atomically, unless a copy at least as
    new as the archive is there."""
    if os.path.exists(path) and os.path.getmtime(path) >= os.path.getmtime(archive):
        return
    try:
        data = zf.read(member)
    except KeyError:
        raise InputError(f"has no {member}: not the 0ad-data this module knows",
                         archive) from None
    os.makedirs(os.path.dirname(path) or ".", exist_ok=True)
    with atomic_output(path) as tmp, open(tmp, "wb") as fh:
        fh.write(data)
