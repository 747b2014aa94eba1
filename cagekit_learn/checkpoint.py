"""Checkpoints: written atomically, read without ever running code from the file.

A checkpoint is one ``torch.save`` file holding only tensors and plain Python values:

``{"format": 1, "model": state_dict, "optimizer": state_dict, "config": {...},
"model_config": {...}, "step": int, "epoch": int, "skipped": int, "rng": tensor}``

It is read with ``torch.load(..., weights_only=True)``, PyTorch's restricted unpickler,
which rebuilds tensors and containers and refuses anything else, so a malicious file
cannot execute code. It is written with :func:`cagekit.io.files.atomic_output` (a temporary file
in the same folder, fsynced, renamed over the old one), so a run killed while saving leaves
the previous checkpoint whole, and the next save removes what the killed one left.
"""

from __future__ import annotations

import os
from pathlib import Path

import torch

from cagekit.errors import InputError
from cagekit.io.files import atomic_output
from cagekit_learn.shipped import MODELS_DIR, names, shipped_checkpoint

__all__ = ["FORMAT", "CHECKPOINT_NAME", "save_checkpoint", "load_checkpoint", "resolve",
           "nonfinite_tensors"]

FORMAT = 1
CHECKPOINT_NAME = "checkpoint.pt"


def resolve(path: str | os.PathLike) -> Path:
    """A checkpoint file from a path that may name the run folder or a shipped model.

    An existing path wins; a bare word that is not one names a shipped model
    (:func:`cagekit_learn.shipped.shipped_checkpoint`, which refuses an unknown one).
    """
    shipped = shipped_checkpoint(path)
    if shipped is not None:
        return shipped
    path = Path(path)
    return path / CHECKPOINT_NAME if path.is_dir() else path


def _hidden_model(given: str | os.PathLike) -> str:
    """What to add when a folder named like a shipped model hides it (a ``chairs/`` of
    meshes in the working folder, as the README's amplify example makes)."""
    name = os.path.normpath(os.fspath(given))
    if os.path.exists(given) and name in names():
        kind = "folder" if os.path.isdir(given) else "file"
        return (f" (the {kind} {name} here hides the shipped model {name!r}; give its "
                f"file instead: {MODELS_DIR / (name + '.pt')})")
    return ""


def save_checkpoint(path: str | os.PathLike, payload: dict) -> None:
    """Write ``payload`` to ``path`` atomically (temporary file, fsync, rename).

    Parameters
    ----------
    path : str or Path
    payload : dict
        Tensors and plain Python values only.
    """

    with atomic_output(path) as tmp, open(tmp, "wb") as handle:
        torch.save({"format": FORMAT, **payload}, handle)


def nonfinite_tensors(state_dict: dict) -> list[str]:
    """Names of the floating-point tensors of a state dict that hold NaN or inf."""
    return [name for name, t in state_dict.items()
            if isinstance(t, torch.Tensor) and t.is_floating_point()
            and not bool(torch.isfinite(t).all())]


def load_checkpoint(path: str | os.PathLike,
                    map_location: str | torch.device = "cpu") -> dict:
    """Read a checkpoint with ``torch.load(weights_only=True)``.

    Parameters
    ----------
    path : str or Path
        The file, or a run folder holding ``checkpoint.pt``.
    map_location : str or torch.device, default "cpu"

    Returns
    -------
    dict

    Raises
    ------
    InputError
        Missing or unreadable file, a file that needs more than tensors and plain values
        (refused by the restricted unpickler), or not a cagekit checkpoint.
    """
    given, path = path, resolve(path)
    if not path.is_file():
        raise InputError(f"{path}: no such checkpoint file{_hidden_model(given)}")
    try:
        payload = torch.load(path, map_location=map_location, weights_only=True)
    except Exception as exc:  # noqa: BLE001 - any failure is the file's fault here
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
        # torch's advice is not for us; a bare key or an empty message says nothing
        if first.startswith("Weights only load failed") or isinstance(
                exc, (KeyError, EOFError)) or not first:
            first = ("torch's safe loader refused it: not a file torch saved, or one "
                     "holding more than tensors and plain values")
        raise InputError(f"{path}: not a readable checkpoint ({first})"
                         f"{_hidden_model(given)}") from None
    if not isinstance(payload, dict) or payload.get("format") != FORMAT or "model" not in payload:
        raise InputError(f"{path}: not a cagekit checkpoint (format {FORMAT})")
    return payload
