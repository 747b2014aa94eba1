"""Torch twin of :func:`cagekit.geometry.alignment.box_scale`, batched, for the networks."""

from __future__ import annotations

import torch

__all__ = ["box_scale", "FLAT"]

#: an axis below this share of the largest half-extent is flat (its factor stays 1); larger
#: than the NumPy twin's 1e-9 because training batches are float32
FLAT = 1e-6


def box_scale(source: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Per-axis factors mapping each source's bounding box onto its target's, no gradient.

    Parameters
    ----------
    source, target : (B, P, 3) and (B, Q, 3) tensors
        Point clouds, each centred on its bounding box.

    Returns
    -------
    (B, 3) tensor
        ``half_extent(target) / half_extent(source)`` per axis; 1 on an axis where either
        cloud is flat (below :data:`FLAT` of its largest half-extent).

    Examples
    --------
    >>> s = torch.tensor([[[-1.0, -0.5, 0.0], [1.0, 0.5, 0.0]]])
    >>> box_scale(s, s * torch.tensor([1.0, 2.0, 1.0])).tolist()
    [[1.0, 2.0, 1.0]]
    """
    with torch.no_grad():
        hs = 0.5 * (source.amax(dim=1) - source.amin(dim=1))
        ht = 0.5 * (target.amax(dim=1) - target.amin(dim=1))
        flat = (hs < FLAT * hs.amax(dim=1, keepdim=True)) | (
            ht < FLAT * ht.amax(dim=1, keepdim=True))
        return torch.where(flat, torch.ones_like(hs), ht / torch.where(flat, 1.0, hs))
