"""Models that ship with cagekit_learn, found by name.

A shipped model is two files in :data:`MODELS_DIR` (``cagekit_learn/models/``):

- ``NAME.pt``: a checkpoint (:mod:`cagekit_learn.checkpoint`) holding the weights, the
  model config and the training config, without the optimiser's state;
- ``NAME.json``: its recipe: what it is for, the command that trained it (``make
  models``, :mod:`cagekit_learn.make_shipped`), the training data (every shape with its
  catalog, name, creator and licence; the shapes held out for the benchmark), the
  training figures, and the fingerprint of its first steps (weights after two steps,
  for the test that a fresh run reproduces them).

``--model chairs`` on the command line and ``cagekit_learn.load_model("chairs")`` take a
name wherever they take a checkpoint path: a path that exists wins, then a shipped name
(:func:`shipped_checkpoint`). This module imports no torch.

Examples
--------
>>> "chairs" in names()
True
>>> recipe("chairs")["data"]["package"]
'sweethome3d-furniture'
"""

from __future__ import annotations

import json
import os
from pathlib import Path

from cagekit.errors import InputError

__all__ = ["MODELS_DIR", "names", "shipped_checkpoint", "recipe"]

#: where the shipped models are (inside the installed package)
MODELS_DIR = Path(__file__).resolve().parent / "models"


def names() -> list[str]:
    """The names of the shipped models (those with both files), sorted.

    Returns
    -------
    list of str
    """
    if not MODELS_DIR.is_dir():
        return []
    return sorted(p.stem for p in MODELS_DIR.glob("*.pt") if p.with_suffix(".json").is_file())


def _shipped() -> str:
    return f"shipped: {', '.join(names()) or 'none'}"


def _is_bare_name(path: str | os.PathLike) -> bool:
    text = os.fspath(path)
    return bool(text) and os.sep not in text and "/" not in text and "." not in text


def shipped_checkpoint(path: str | os.PathLike) -> Path | None:
    """The shipped checkpoint a model argument names, or None when it names a path.

    Parameters
    ----------
    path : str or os.PathLike
        What the user gave: a path (a file or run folder, which wins when it exists) or
        a shipped model's name (a bare word: no folder, no suffix).

    Returns
    -------
    Path or None
        ``MODELS_DIR / NAME.pt`` for a shipped name; None for a path (existing or not).

    Raises
    ------
    InputError
        A bare word that is neither an existing path nor a shipped model: says which
        models ship.
    """
    if os.path.exists(path) or not _is_bare_name(path):
        return None
    name = os.fspath(path)
    if name in names():
        return MODELS_DIR / f"{name}.pt"
    raise InputError(f"{name}: no such checkpoint file or run folder, nor a shipped model "
                     f"({_shipped()})")


def recipe(name: str) -> dict:
    """The recipe of a shipped model (its ``NAME.json``).

    Parameters
    ----------
    name : str

    Returns
    -------
    dict

    Raises
    ------
    InputError
        ``name`` is not a shipped model.
    """
    if name not in names():
        raise InputError(f"{name}: not a shipped model ({_shipped()})")
    with open(MODELS_DIR / f"{name}.json", encoding="utf-8") as handle:
        return json.load(handle)
