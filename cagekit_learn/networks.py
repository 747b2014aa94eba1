"""The networks of "Neural Cages" (section 3.2): a shared PointNet encoder, N_c and N_d.

The **encoder** maps a normalised cloud ``(B, P, 3)`` to a code (1-D convolutions
3-64-128-``bottleneck``, ReLU, max-pool, no batch normalisation). **N_c** predicts the source
cage: the template cage (:func:`cagekit.template_cage` x ``template_radius``) plus offsets
decoded per vertex from ``[vertex, source code]`` (AtlasNet-style), or the paper's ablations
(``identity``, ``source-invariant``) or a fixed cage. **N_d** predicts the deformed cage:
the source cage plus offsets from ``[cage vertex, source code, target code]``. Ours where
the paper is silent: the decoders' last layers start at zero (an untrained model returns
the template, unmoved); ``box_align`` (default) first stretches the source cage onto the
target's bounding box (:func:`cagekit_learn.alignment.box_scale`), so N_d learns only what
the boxes do not explain; a model trained with a fixed source keeps the template's samples
in its config and exposes them as :attr:`NeuralCages.fixed_source`. See
docs/architecture.md.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass, field

import numpy as np
import torch
from torch import nn

from cagekit.cage.fitting import template_cage
from cagekit_learn.alignment import box_scale

__all__ = ["ModelConfig", "PointNetEncoder", "VertexDecoder", "NeuralCages", "NC_VARIANTS"]

NC_VARIANTS = ("learned", "identity", "source-invariant")


@dataclass
class ModelConfig:
    """Everything that defines a :class:`NeuralCages` model (stored in checkpoints).

    Attributes
    ----------
    bottleneck : int
        Size of the PointNet code.
    nc : {"learned", "identity", "source-invariant"}
        The N_c variant.
    template_radius : float
        Radius of the template icosphere (normalised frame).
    box_align : bool
        Stretch the source cage onto the target's bounding box before N_d's offsets.
    decoder_widths : list of int
        Hidden widths of the two decoders' MLPs.
    fixed_cage_v, fixed_cage_f : list or None
        A fixed source cage (nested lists), replacing N_c. Its vertices are in the
        normalised source frame (with a fixed source: the template normalised on its own).
    fixed_source_points : list or None
        (P, 3) nested lists: the normalised samples of the fixed source (template) the
        model was trained with, or None for a model trained on pairs of shapes.
    fixed_source_rows : list or None
        (P,) vertex rows of the template behind ``fixed_source_points`` (L2 alignment on
        shapes in correspondence), else None (surface samples).
    fixed_source_vertex_count : int or None
        The template's vertex count.
    fixed_source_center : list or None
    fixed_source_scale : float or None
        The template's normalisation: ``normalised = (V - center) / scale``, so a cage of
        the normalised source frame maps back to the template's own frame by
        ``cage * scale + center``.
    coords : {"mvc", "green"}
        The coordinates the model's cages bind the source with, in training and at
        inference (Green: :mod:`cagekit_learn.green`).
    """

    bottleneck: int = 256
    nc: str = "learned"
    template_radius: float = 1.5
    box_align: bool = True
    decoder_widths: list = field(default_factory=lambda: [256, 128, 64])
    fixed_cage_v: list | None = None
    fixed_cage_f: list | None = None
    fixed_source_points: list | None = None
    fixed_source_rows: list | None = None
    fixed_source_vertex_count: int | None = None
    fixed_source_center: list | None = None
    fixed_source_scale: float | None = None
    coords: str = "mvc"

    def to_dict(self) -> dict:
        """Plain Python values only (so a checkpoint loads with ``weights_only=True``)."""
        return asdict(self)

    @classmethod
    def from_dict(cls, values: dict) -> ModelConfig:
        known = {k: v for k, v in values.items() if k in cls.__dataclass_fields__}
        return cls(**known)


class PointNetEncoder(nn.Module):
    """Per-point 1-D convolutions 3 -> 64 -> 128 -> ``bottleneck`` and a max-pool.

    Parameters
    ----------
    bottleneck : int, default 256

    Examples
    --------
    >>> enc = PointNetEncoder(32)
    >>> enc(torch.zeros(2, 100, 3)).shape
    torch.Size([2, 32])
    """

    def __init__(self, bottleneck: int = 256):
        super().__init__()
        self.layers = nn.Sequential(
            nn.Conv1d(3, 64, 1), nn.ReLU(),
            nn.Conv1d(64, 128, 1), nn.ReLU(),
            nn.Conv1d(128, bottleneck, 1),
        )

    def forward(self, points: torch.Tensor) -> torch.Tensor:
        """(B, P, 3) points -> (B, bottleneck) codes."""
        return self.layers(points.transpose(1, 2)).amax(dim=2)


class VertexDecoder(nn.Module):
    """An AtlasNet-style decoder: one MLP applied to every ``[vertex, code]`` row.

    Parameters
    ----------
    code_size : int
        Length of the code appended to each vertex.
    widths : sequence of int
        Hidden widths.

    Examples
    --------
    >>> dec = VertexDecoder(8, [16])
    >>> dec(torch.zeros(2, 5, 3), torch.zeros(2, 8)).abs().max().item()  # starts at zero
    0.0
    """

    def __init__(self, code_size: int, widths: Sequence[int] = (256, 128, 64)):
        super().__init__()
        layers, size = [], 3 + code_size
        for width in widths:
            layers += [nn.Conv1d(size, width, 1), nn.ReLU()]
            size = width
        last = nn.Conv1d(size, 3, 1)
        nn.init.zeros_(last.weight)
        if last.bias is not None:  # a Conv1d has one by default
            nn.init.zeros_(last.bias)
        self.layers = nn.Sequential(*layers, last)

    def forward(self, vertices: torch.Tensor, code: torch.Tensor) -> torch.Tensor:
        """(B, k, 3) vertices and (B, c) codes -> (B, k, 3) offsets."""
        rows = torch.cat([vertices, code[:, None, :].expand(-1, vertices.shape[1], -1)], dim=2)
        return self.layers(rows.transpose(1, 2)).transpose(1, 2)


class NeuralCages(nn.Module):
    """N_c and N_d with a shared encoder.

    Parameters
    ----------
    config : ModelConfig, optional

    Attributes
    ----------
    cage_f : (m, 3) int64 buffer
        The faces of every predicted cage (the template's, or the fixed cage's).
    template : (k, 3) buffer
        The template cage's vertices (N_c's starting point).
    fixed_source : (P, 3) float32 buffer or None
        The fixed source's normalised samples (``config.fixed_source_points``), not part
        of the state dict; None for a model trained on pairs of shapes.

    Examples
    --------
    >>> model = NeuralCages(ModelConfig(bottleneck=16))
    >>> out = model(torch.rand(2, 64, 3) - 0.5, torch.rand(2, 64, 3) - 0.5)
    >>> out["source_cage"].shape, out["deformed_cage"].shape
    (torch.Size([2, 42, 3]), torch.Size([2, 42, 3]))
    """

    template: torch.Tensor
    cage_f: torch.Tensor
    fixed_source: torch.Tensor | None

    def __init__(self, config: ModelConfig | None = None):
        super().__init__()

        self.config = config = config or ModelConfig()
        if config.nc not in NC_VARIANTS:
            raise ValueError(f"nc must be one of {', '.join(NC_VARIANTS)}, got {config.nc!r}")
        if config.fixed_cage_v is not None:
            v = np.asarray(config.fixed_cage_v, dtype=np.float64)
            f = np.asarray(config.fixed_cage_f, dtype=np.int64)
        else:
            v, f = template_cage()
            v = v * config.template_radius
        self.register_buffer("template", torch.as_tensor(v, dtype=torch.float32))
        self.register_buffer("cage_f", torch.as_tensor(f, dtype=torch.int64))
        fixed = None
        if config.fixed_source_points is not None:
            fixed = torch.as_tensor(np.asarray(config.fixed_source_points, dtype=np.float32))
            if fixed.ndim != 2 or fixed.shape[1] != 3 or len(fixed) < 1:
                raise ValueError(f"fixed_source_points must be (P, 3), got "
                                 f"{tuple(fixed.shape)}")
            rows = config.fixed_source_rows
            if rows is not None and len(rows) != len(fixed):
                raise ValueError(f"{len(rows)} fixed_source_rows for {len(fixed)} "
                                 "fixed_source_points")
        self.register_buffer("fixed_source", fixed, persistent=False)
        self.encoder = PointNetEncoder(config.bottleneck)
        widths = list(config.decoder_widths)
        self.nc_decoder = None
        self.nc_offsets = None
        if config.fixed_cage_v is None and config.nc == "learned":
            self.nc_decoder = VertexDecoder(config.bottleneck, widths)
        elif config.fixed_cage_v is None and config.nc == "source-invariant":
            self.nc_offsets = nn.Parameter(torch.zeros_like(self.template))
        self.nd_decoder = VertexDecoder(2 * config.bottleneck, widths)

    def nc_parameters(self) -> list:
        """N_c's own parameters (trained at a tenth of the learning rate)."""
        if self.nc_decoder is not None:
            return list(self.nc_decoder.parameters())
        return [self.nc_offsets] if self.nc_offsets is not None else []

    def source_cage(self, source: torch.Tensor, code: torch.Tensor | None = None
                    ) -> torch.Tensor:
        """N_c: (B, P, 3) source clouds -> (B, k, 3) source cages."""
        batch = source.shape[0]
        template = self.template.to(source.dtype).expand(batch, -1, -1)
        if self.nc_decoder is not None:
            code = self.encoder(source) if code is None else code
            return template + self.nc_decoder(template, code)
        if self.nc_offsets is not None:
            return template + self.nc_offsets.to(source.dtype)
        return template

    def forward(self, source: torch.Tensor, target: torch.Tensor) -> dict:
        """Predict the source cage and its deformation.

        Parameters
        ----------
        source, target : (B, P, 3) float tensors
            Point clouds, each normalised on its own (the paper's frame).

        Returns
        -------
        dict
            ``source_cage`` (B, k, 3) and ``deformed_cage`` (B, k, 3), in the source's and
            the target's normalised frames; the faces are :attr:`cage_f`.
        """
        code_s = self.encoder(source)
        code_t = self.encoder(target)
        cage = self.source_cage(source, code_s)
        start = cage * box_scale(source, target)[:, None, :] if self.config.box_align else cage
        offsets = self.nd_decoder(start, torch.cat([code_s, code_t], dim=1))
        return {"source_cage": cage, "deformed_cage": start + offsets}
