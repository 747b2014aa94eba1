"""Real artist-made models: Debian's ``sweethome3d-furniture`` catalogs.

Debian's package ``sweethome3d-furniture`` (``apt-get install sweethome3d-furniture``) ships
five Sweet Home 3D furniture libraries, 820 OBJ models by real artists (furniture,
characters, animals, plants, vehicles), as zip archives
``/usr/share/sweethome3d/furniture/<Catalog>.sh3f``; each one's
``PluginFurnitureCatalog.properties`` (Java properties, ISO 8859-1) names every model, its
category, its creator and the library's licence: Blend Swap CC-0 (public domain), Blend Swap
CC-BY, Kator Legaz, Reallusion and Scopia (CC BY 3.0: credit the creator of any model shown
or shipped). :func:`models` unpacks the archives once into a cache folder and lists the
models for ``benchmarks/bench_assets.py`` and the furniture benchmarks. Nothing is
downloaded: without the package it raises an :class:`~cagekit.errors.InputError` that says
how to install it.

Examples
--------
>>> chairs = [m for m in models() if "chair" in m.name.lower()]  # doctest: +SKIP
>>> chairs[0].path, chairs[0].creator, chairs[0].license  # doctest: +SKIP
"""

from __future__ import annotations

import os
import re
import zipfile
from collections.abc import Iterable
from dataclasses import dataclass

from cagekit.errors import InputError

__all__ = ["FURNITURE_DIR", "CATALOGS", "FURNITURE_CATALOGS", "KIND_WORDS", "SEAT_KINDS",
           "Model", "models", "read_properties", "furniture_kind", "held_out_split"]

#: where Debian puts the archives
FURNITURE_DIR = "/usr/share/sweethome3d/furniture"

#: the package's five catalogs (archive stems)
CATALOGS = ("BlendSwap-CC-0", "BlendSwap-CC-BY", "KatorLegaz", "Reallusion", "Scopia")

#: the catalogs of furniture (the benchmarks' real assets)
FURNITURE_CATALOGS = ("BlendSwap-CC-0", "BlendSwap-CC-BY", "KatorLegaz")

_PROPERTIES = "PluginFurnitureCatalog.properties"

#: name words of each furniture kind, first match wins (an "armchair" is not a "chair")
KIND_WORDS = (("armchair", ("armchair",)), ("sofa", ("sofa", "couch")),
              ("stool or bench", ("stool", "bench")), ("chair", ("chair",)),
              ("table", ("table",)))
#: words that put a name out of every kind ("pool table", "ceiling fan", "workbench")
NOT_FURNITURE = ("fan", "tennis", "pool", "football", "bedside", "wheel", "workbench",
                 "abdominal", "bat", "ottoman")
#: the kinds that make the seats (the shipped model ``chairs``, the learned benchmark)
SEAT_KINDS = ("chair", "armchair", "sofa", "stool or bench")


@dataclass(frozen=True)
class Model:
    """One model of a catalog.

    Attributes
    ----------
    path : str
        The unpacked OBJ file.
    catalog : str
        The archive's stem (one of :data:`CATALOGS`).
    name, category, creator : str
        As the catalog names them (``creator`` may be empty).
    license : str
        The model's licence, else the catalog's.
    """

    path: str
    catalog: str
    name: str
    category: str
    creator: str
    license: str

    @property
    def credit(self) -> str:
        """``"<name> by <creator> (<licence>)"``, for captions."""
        by = f" by {self.creator}" if self.creator else ""
        return f"{self.name}{by} ({self.license})"


def read_properties(text: str) -> dict[str, str]:
    """Parse Java ``.properties`` text: ``key=value`` (or ``:``), comments, continuations.

    Parameters
    ----------
    text : str
        Already decoded (the catalogs are ISO 8859-1); ``\\uXXXX`` escapes are decoded here.

    Returns
    -------
    dict of str to str

    Examples
    --------
    >>> read_properties("# c\\nname#1=Chair\\\\\\n  s\\ncategory#1 : Office\\n")
    {'name#1': 'Chairs', 'category#1': 'Office'}
    """
    out = {}
    lines = iter(text.splitlines())
    for line in lines:
        line = line.lstrip()
        if not line or line[0] in "#!":
            continue
        while line.endswith("\\") and not line.endswith("\\\\"):
            line = line[:-1] + next(lines, "").lstrip()
        match = re.match(r"((?:\\.|[^=:\s\\])+)\s*[=:]?\s*(.*)$", line)
        if match:
            out[_unescape(match.group(1))] = _unescape(match.group(2))
    return out


def _unescape(value: str) -> str:
    def one(m):
        code = m.group(1)
        if code.startswith("u"):
            return chr(int(code[1:], 16))
        return {"t": "\t", "n": "\n", "r": "\r", "f": "\f"}.get(code, code)

    return re.sub(r"\\(u[0-9a-fA-F]{4}|.)", one, value)


def _unpack(archive: str, folder: str) -> None:
    """Unpack ``archive`` into ``folder`` once (a marker file records it)."""
    marker = os.path.join(folder, ".unpacked")
    if os.path.exists(marker) and os.path.getmtime(marker) >= os.path.getmtime(archive):
        return
    os.makedirs(folder, exist_ok=True)
    with zipfile.ZipFile(archive) as zf:
        for member in zf.infolist():
            target = os.path.realpath(os.path.join(folder, member.filename))
            if not target.startswith(os.path.realpath(folder) + os.sep):
                raise InputError(f"unsafe path {member.filename!r} in the archive", archive)
        zf.extractall(folder)
    with open(marker, "w") as fh:
        fh.write(archive + "\n")


def models(catalogs: Iterable[str] = CATALOGS, cache: str = "out/sweethome3d",
           furniture_dir: str = FURNITURE_DIR) -> list[Model]:
    """The models of the installed catalogs, unpacked into ``cache``.

    Parameters
    ----------
    catalogs : sequence of str, default all five
        Archive stems (:data:`CATALOGS`); :data:`FURNITURE_CATALOGS` for furniture.
    cache : str, default "out/sweethome3d"
        Where the archives are unpacked (once; again when an archive is newer).
    furniture_dir : str
        Where the ``.sh3f`` archives are.

    Returns
    -------
    list of Model
        In catalog order, then in the order the catalog lists them.

    Raises
    ------
    InputError
        An archive is missing (the package is not installed) or is not a catalog.
    """
    out = []
    for catalog in catalogs:
        archive = os.path.join(furniture_dir, f"{catalog}.sh3f")
        if not os.path.isfile(archive):
            raise InputError("missing: install Debian's sweethome3d-furniture "
                             "(apt-get install sweethome3d-furniture)", archive)
        folder = os.path.join(cache, catalog)
        _unpack(archive, folder)
        try:
            with open(os.path.join(folder, _PROPERTIES), encoding="latin-1") as fh:
                props = read_properties(fh.read())
        except OSError:
            raise InputError(f"has no {_PROPERTIES}: not a furniture catalog",
                             archive) from None
        licence = props.get("license", "")
        numbers = sorted(int(k.split("#", 1)[1]) for k in props if k.startswith("model#"))
        for i in numbers:
            rel = props[f"model#{i}"].lstrip("/")
            out.append(Model(path=os.path.join(folder, rel), catalog=catalog,
                             name=props.get(f"name#{i}", rel),
                             category=props.get(f"category#{i}", ""),
                             creator=props.get(f"creator#{i}", ""),
                             license=props.get(f"license#{i}", licence)))
    return out


def furniture_kind(name: str) -> str | None:
    """The kind of a furniture model from its catalog name, or None.

    Parameters
    ----------
    name : str
        As the catalog names the model (:attr:`Model.name`).

    Returns
    -------
    str or None
        One of the kinds of :data:`KIND_WORDS`, or None for anything else (and for the
        names :data:`NOT_FURNITURE` excludes).

    Examples
    --------
    >>> furniture_kind("Antique armchair"), furniture_kind("Pool table")
    ('armchair', None)
    """
    low = name.lower()
    if any(word in low for word in NOT_FURNITURE):
        return None
    return next((kind for kind, words in KIND_WORDS if any(w in low for w in words)), None)


def held_out_split(found: Iterable[Model], kinds: Iterable[str] = SEAT_KINDS,
                   every: int = 4) -> tuple[list[tuple[str, Model]], list[tuple[str, Model]]]:
    """Split models of some kinds into training and held-out (test) models, by name only.

    Within each kind, in the order given (:func:`models`' catalog order), the models at
    positions ``1, 1 + every, 1 + 2 every, ...`` are held out and the rest train, so the
    split depends only on the installed catalogs, never on a random draw or on loading
    a mesh.

    Parameters
    ----------
    found : iterable of Model
    kinds : iterable of str, default :data:`SEAT_KINDS`
    every : int, default 4
        One model in ``every`` is held out.

    Returns
    -------
    train, held_out : list of (kind, Model)
        Kind by kind, in the order of ``kinds``.

    Examples
    --------
    >>> m = [Model(f"{i}.obj", "c", f"Chair {i}", "", "", "") for i in range(6)]
    >>> train, test = held_out_split(m, every=4)
    >>> [x.name for _, x in test], len(train)
    (['Chair 1', 'Chair 5'], 4)
    """
    kinds_of = [(furniture_kind(m.name), m) for m in found]  # named once, not per kind
    train: list[tuple[str, Model]] = []
    held_out: list[tuple[str, Model]] = []
    for kind in kinds:
        of_kind = [m for k, m in kinds_of if k == kind]
        for i, model in enumerate(of_kind):
            (held_out if i % every == 1 else train).append((kind, model))
    return train, held_out
