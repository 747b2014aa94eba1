"""Training N_c and N_d on a collection of shapes (section 3.3 of "Neural Cages").

One step (:meth:`Trainer.step`): a batch of source-target pairs (:mod:`cagekit_learn.data`),
the model predicts a source cage and its deformation (:mod:`cagekit_learn.networks`), the
source points are bound to the predicted cage with the differentiable MVC and moved, and
the loss is ``L_align + ALPHA_MVC * L_MVC + alpha_enclosure * L_enclosure + alpha_shape * (L_p2f +
L_normal) [+ L_symm] + alpha_parts * L_parts`` (``L_enclosure``, ours:
:func:`cagekit_learn.enclosure.enclosure_loss`, every source point at least
:data:`~cagekit_learn.enclosure.ENCLOSURE_MARGIN` inside its predicted cage; ``L_parts``, ours:
:func:`cagekit_learn.losses.part_affinity_loss`, each connected part of the source an affine
map of itself, as ``cagekit deform``'s part-affinity term)
(the paper's weights, :mod:`cagekit.deformation.terms`; ``L_align`` Chamfer, or the L2 distance of
corresponding points with ``align="l2"``). Adam at ``lr``, N_c at :data:`NC_LR_FACTOR` of it.
Everything random is a function of ``(seed, epoch, step)`` and checkpoints hold the model,
the optimiser, the counters and the RNG state, so a resumed run computes the weights of
one never stopped; a resumed run reads the data it is given, takes every other setting from
its checkpoint but the budget and the device (:data:`FROM_THE_CALLER`), and refuses a
checkpoint ``deform --model`` would refuse. A step that cannot be taken finitely is skipped
on every rank, the parameters and the optimiser's state left as they were before it: a loss
or gradient that is not finite, cages that are not (:class:`NonFiniteStep`), a
linear-algebra routine that fails on what overflowed (``LinAlgError``), or an update that
leaves a weight or Adam's state non-finite; the first skip is warned about (one line), all
are counted.
Under torchrun (``torchrun -m cagekit.cli train``) the model is wrapped in
DistributedDataParallel and each rank takes its shard of every epoch's pairs; rank 0 writes
the log and the checkpoints. With a fixed source (one template character, its poses as the
targets) the template's samples and normalisation go into the model config, so a checkpoint
carries its source. See docs/architecture.md.
"""

from __future__ import annotations

import csv
import math
import os
import sys
import time
import warnings
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import torch

from cagekit import io
from cagekit.cage import check_cage
from cagekit.datasets.synthetic import FAMILIES
from cagekit.deformation.terms import ALPHA_MVC, ALPHA_SHAPE, mirror_partners
from cagekit.errors import CagekitWarning, InputError
from cagekit.geometry import as_count
from cagekit.geometry.frame import Frame
from cagekit.progress import progress_bar, progress_enabled
from cagekit.typed import Ints
from cagekit_learn import losses
from cagekit_learn.checkpoint import (
    CHECKPOINT_NAME,
    load_checkpoint,
    nonfinite_tensors,
    resolve,
    save_checkpoint,
)
from cagekit_learn.coords import mean_value_coordinates
from cagekit_learn.data import (
    FixedSource,
    ShapeCollection,
    epoch_pairs,
    fixed_source_pairs,
    make_batch,
    shard,
)
from cagekit_learn.enclosure import enclosure_loss
from cagekit_learn.green import green_coordinates, green_deform
from cagekit_learn.networks import ModelConfig, NeuralCages

__all__ = ["TrainConfig", "TrainResult", "Trainer", "train", "training_loss", "load_collection",
           "load_model", "load_source_cage", "resume_config", "fixed_source_matches",
           "source_cage_matches", "NonFiniteStep", "LOG_NAME", "TERMS", "MAX_LR",
           "FROM_THE_CALLER"]

LOG_NAME = "log.csv"
TERMS = ("align", "mvc", "enclosure", "p2f", "normal", "symmetry", "parts")
#: N_c's learning rate relative to ``lr`` (the paper's ratio)
NC_LR_FACTOR = 0.1
#: the largest learning rate accepted: Adam moves each weight by about ``lr`` a step, so
#: beyond it the first steps overflow float32 (the paper's is 1e-3)
MAX_LR = 1.0
#: settings a resumed run takes from the caller's config (the data, the budget and the
#: device); every other one is the checkpoint's
FROM_THE_CALLER = ("data", "epochs", "max_steps", "max_minutes", "device")
#: settings that earlier versions stored and this one fixes (a checkpoint with other
#: values is refused on resume rather than continued differently)
_RETIRED_SETTINGS = {"alpha_mvc": ALPHA_MVC, "alpha_symmetry": 1.0,
                     "nc_lr_factor": NC_LR_FACTOR}


ALPHA_ENCLOSURE = 10.0
"""Default weight of the enclosure term: large enough that the source stays inside the
predicted cage (with ``L_MVC`` alone N_c flattened it onto the seat of real chairs); a
cage that encloses the source with its margin costs nothing."""

ALPHA_PARTS = 60.0
"""Default weight of the part-affinity term, chosen so that it weighs as much as the
alignment term where the paper's loss leads. Both are mean squared distances in the unit
frame, as in ``cagekit deform`` (weight 300 there,
:data:`cagekit.deformation.problem.PARTS_WEIGHT`).
At the start of training the term is 0: the zero-initialised N_d and the box alignment move
the whole source by one affine map (measured on procedural chairs, 16 shapes, 1024 points,
batch 4: about 1e-11 over the first 20 steps, 2e-7 by step 110, while Chamfer stays near
0.015). The shipped ``chairs`` model, trained 3000 steps without the term, has on procedural
chair pairs Chamfer 0.012 and a part term of 2.0e-4 (batches of four: ratios 48 to 71), so a
weight of about 60 makes the bending it learns cost as much as its misalignment; the
per-pair optimiser's 300 would let the term dominate Chamfer five times over."""


@dataclass
class TrainConfig:
    """Everything a training run needs (stored in its checkpoints).

    Attributes
    ----------
    data : str
        A folder of meshes (searched recursively), or ``synthetic:FAMILY[:N]`` for N
        (default 64) procedural chairs, tables or vases.
    run_dir : str
        Where the checkpoint, the log and the config go.
    epochs, batch_size, lr : int or None, int, float
        ``lr`` in ``(0, MAX_LR]`` (:data:`MAX_LR`, 1). ``epochs`` None: a resumed run's
        own (:func:`train` with ``resume``); a new run needs a number.
    points : int
        Samples per shape.
    seed : int
    device : {"auto", "cpu", "cuda"}
    checkpoint_every : int
        Steps between checkpoints (and one at the end).
    alpha_shape : float
        Weight of the shape terms (the paper's 0.1; 0 turns them off). ``L_MVC`` has the
        paper's weight :data:`cagekit.deformation.terms.ALPHA_MVC`, the symmetry term weight 1.
    alpha_enclosure : float
        Weight of the enclosure term (:func:`cagekit_learn.enclosure.enclosure_loss`) on the
        predicted source cage; 0 turns it off, as in runs from before it existed (a
        checkpoint without the setting resumes with 0). It is not computed for a cage that
        is not predicted (a fixed source cage, ``nc="identity"``).
    alpha_parts : float
        Weight of the part-affinity term (:func:`cagekit_learn.losses.part_affinity_loss`,
        ``cagekit deform``'s: each part of the source, a connected component, kept an
        affine map of itself); 0 turns it off, as in runs from before it existed (a
        checkpoint without the setting resumes with 0). It costs nothing on a source of
        fewer than two parts (a point cloud, a fixed source, one connected mesh).
    symmetry : {"x", "y", "z"} or None
    align : {"chamfer", "l2"}
    augment : bool
        The paper's anisotropic scaling of sources and targets (of the targets only with
        a fixed source).
    max_steps : int or None
        Stop after this many steps in all (for smoke tests).
    max_minutes : float or None
        Stop (with a checkpoint) after this much training time.
    model : dict
        A :class:`cagekit_learn.networks.ModelConfig` as a dict.
    fixed_source : str or None
        Path of a template mesh that is the source of every pair (the collection's shapes
        are the targets). :func:`train` reads it once and stores its samples in
        ``model`` (``fixed_source_points``...); a resumed run uses the stored ones.
    """

    data: str
    run_dir: str
    epochs: int | None = 100
    batch_size: int = 8
    lr: float = 1e-3
    points: int = 1024
    seed: int = 0
    device: str | None = "auto"
    checkpoint_every: int = 200
    alpha_shape: float = ALPHA_SHAPE
    alpha_enclosure: float = ALPHA_ENCLOSURE
    alpha_parts: float = ALPHA_PARTS
    symmetry: str | None = None
    align: str = "chamfer"
    augment: bool = True
    max_steps: int | None = None
    max_minutes: float | None = None
    model: dict = field(default_factory=lambda: ModelConfig().to_dict())
    fixed_source: str | None = None

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, values: dict) -> TrainConfig:
        # stored before the terms existed: off
        values = {"alpha_enclosure": 0.0, "alpha_parts": 0.0, **values}
        return cls(**{k: v for k, v in values.items() if k in cls.__dataclass_fields__})


@dataclass
class TrainResult:
    """What :func:`train` returns (on every rank)."""

    model: NeuralCages
    step: int
    epoch: int
    skipped: int
    last_losses: dict
    seconds: float
    pairs_per_second: float


# --------------------------------------------------------------------------------- data


def load_collection(data: str, points: int, seed: int, progress: bool = False,
                    corresponding: bool = False) -> ShapeCollection:
    """The shapes of ``data``: a folder of meshes or ``synthetic:FAMILY[:N]``.

    ``corresponding=True`` (the L2 alignment) reads a folder of meshes sharing one vertex
    order with :meth:`ShapeCollection.corresponding`.
    """
    if data.startswith("synthetic:"):
        parts = data.split(":")
        family = parts[1] if len(parts) > 1 else "chairs"
        try:
            count = int(parts[2]) if len(parts) > 2 else 64
        except ValueError:
            raise InputError(f"expected synthetic:FAMILY[:N], got {data!r}") from None

        if family not in FAMILIES or count < 2:
            raise InputError(f"expected synthetic:FAMILY[:N] with FAMILY one of "
                             f"{', '.join(FAMILIES)} and N >= 2, got {data!r}")
        if corresponding:
            raise InputError("--align l2 needs shapes in correspondence; synthetic "
                             "shapes are not")
        return ShapeCollection.synthetic(family, count, seed=seed, points=points)
    if not Path(data).is_dir():
        raise InputError(f"{data}: not a folder of meshes (or synthetic:FAMILY[:N])")
    if corresponding:
        return ShapeCollection.corresponding(data, points=points, seed=seed)
    return ShapeCollection.from_folder(data, points=points, seed=seed, progress=progress)


def load_source_cage(cage_path: str | os.PathLike,
                     template: str | os.PathLike | None = None) -> tuple[list, list]:
    """A fixed source cage from a mesh file, in the normalised source frame.

    Parameters
    ----------
    cage_path : str or os.PathLike
        A closed, consistently oriented triangle mesh.
    template : str or os.PathLike, optional
        The fixed source's mesh (``--fixed-source``). When given, the cage file is in the
        template's own frame (the cage drawn around ``template.obj``) and is mapped into
        the normalised source frame with the template's normalisation,
        ``(V - center) / scale`` (:meth:`cagekit.Frame.of` of the template). Without it
        the cage file is already in the normalised source frame (the source normalised
        to ``[-1, 1]``).

    Returns
    -------
    cage_v, cage_f : nested lists
        (k, 3) float vertices and (m, 3) int faces, ready for
        ``ModelConfig.fixed_cage_v`` and ``fixed_cage_f``.

    Raises
    ------
    InputError
        An unreadable file or an invalid cage (naming the cage file), an unreadable or
        degenerate template (naming the template).
    """
    import numpy as np


    cage_v, cage_f = io.load_mesh(cage_path)
    if template is not None:
        V = io.load_shape(template)[0]
        try:
            frame = Frame.of(V)
            center, scale = frame.centre, frame.scale
        except InputError as exc:
            raise InputError(exc.problem, template) from None
        cage_v = (np.asarray(cage_v, dtype=np.float64) - center) / scale
    cage_f = check_cage(cage_v, cage_f, name=str(cage_path))
    return np.asarray(cage_v, dtype=np.float64).tolist(), np.asarray(cage_f).tolist()


def _with_fixed_source(config: TrainConfig, collection: ShapeCollection) -> TrainConfig:
    """``config`` with the fixed source's samples in its model config (read when absent).

    A resumed run (whose model config holds them) keeps the stored samples and only
    checks them against the collection.
    """
    from dataclasses import replace

    model = dict(config.model)
    l2 = config.align == "l2"
    if model.get("fixed_source_points") is None:
        if l2 and getattr(collection, "vertex_count", None) is None:
            raise InputError("the L2 alignment with a fixed source needs a collection in "
                             "correspondence (ShapeCollection.corresponding)")
        # the caller passes a config without stored samples only with a template file
        assert config.fixed_source is not None
        source = FixedSource.from_file(config.fixed_source, points=config.points,
                                       seed=config.seed, corresponding=l2,
                                       vertex_count=getattr(collection, "vertex_count",
                                                            None))
        model.update(
            fixed_source_points=source.points.tolist(),
            fixed_source_rows=None if source.rows is None else source.rows.tolist(),
            fixed_source_vertex_count=source.vertex_count,
            fixed_source_center=source.center.tolist(),
            fixed_source_scale=source.scale)
    points = model["fixed_source_points"]
    if len(points) != collection.points.shape[1]:
        raise InputError(f"the fixed source has {len(points)} samples but the shapes "
                         f"{collection.points.shape[1]}", config.fixed_source)
    if l2:
        count = getattr(collection, "vertex_count", None)
        rows = getattr(collection, "rows", None)
        if count is not None and count != model.get("fixed_source_vertex_count"):
            raise InputError(f"{model.get('fixed_source_vertex_count')} vertices, but the "
                             f"training shapes have {count}: with the L2 alignment the "
                             "fixed source shares their vertex order", config.fixed_source)
        if (rows is not None and model.get("fixed_source_rows") is not None
                and list(map(int, rows)) != list(model["fixed_source_rows"])):
            raise InputError("the fixed source's vertex rows differ from the collection's "
                             "(another --points or --seed?)", config.fixed_source)
    return replace(config, model=model)


# --------------------------------------------------------------------------------- loss



def _unwrap(model):
    return model.module if hasattr(model, "module") else model


def training_loss(model: torch.nn.Module, source: torch.Tensor, target: torch.Tensor,
                  config: TrainConfig, knn: int = 16,
                  source_parts: torch.Tensor | None = None
                  ) -> tuple[torch.Tensor, dict[str, float]]:
    """The training loss of one batch.

    Parameters
    ----------
    model : NeuralCages (or a DistributedDataParallel wrapping one)
    source, target : (B, P, 3) tensors
        Normalised point clouds.
    config : TrainConfig
    knn : int, default 16
        Neighbourhood size of the shape terms.
    source_parts : (B, P) integer tensor, optional
        The part of each source point (:func:`cagekit_learn.data.make_batch`'s
        ``"source_parts"``; -1: none). The part-affinity term (``config.alpha_parts``) is
        computed only when given, its parts' bases from ``source`` as the rest points.

    Returns
    -------
    total : scalar tensor
    terms : dict of str to float
        Each term's batch mean (unweighted).

    Raises
    ------
    NonFiniteStep
        The model's cages hold NaN or inf (weights or a batch that overflowed).
    """
    out = model(source, target)
    _require_finite_cages(out)
    net = _unwrap(model)
    cage_f = net.cage_f
    green = getattr(net.config, "coords", "mvc") == "green"
    cached = (None if green
              else _fixed_source_cache(net, source, knn if config.alpha_shape else None))
    if green:
        X = _green_deformed(source, out["source_cage"], out["deformed_cage"], cage_f)
    elif cached is not None:
        W, ref = cached
        X = W @ out["deformed_cage"]
    else:
        W = mean_value_coordinates(source, out["source_cage"], cage_f)
        X = W @ out["deformed_cage"]
    if config.align == "l2":
        align = losses.landmark_loss(X, target)
    else:
        align = losses.chamfer_loss(X, target)
    terms = {"align": align.mean()}
    total = terms["align"]
    if not green:  # the paper's L_MVC (negative MVC weights); Green's psi have no sign
        terms["mvc"] = losses.mvc_loss(W).mean()
        total = total + ALPHA_MVC * terms["mvc"]
    if config.alpha_enclosure and out["source_cage"].requires_grad:
        terms["enclosure"] = enclosure_loss(source, out["source_cage"].to(source.dtype),
                                            cage_f).mean()
        total = total + config.alpha_enclosure * terms["enclosure"]
    if config.alpha_shape:
        if cached is None:
            with torch.no_grad():
                index = losses.knn_neighborhoods(source, k=min(knn, source.shape[1]))
            ref = losses.shape_reference(source, index)
        shape = losses.shape_losses(X, ref)
        terms["p2f"], terms["normal"] = shape["p2f"].mean(), shape["normal"].mean()
        total = total + config.alpha_shape * (terms["p2f"] + terms["normal"])
    if config.symmetry is not None:
        partner = _template_partners(net, config.symmetry)
        zero = torch.zeros_like(out["source_cage"])
        symm = (losses.symmetry_loss(X, config.symmetry)
                + losses.cage_symmetry_loss(out["source_cage"], partner, zero, config.symmetry)
                + losses.cage_symmetry_loss(out["deformed_cage"], partner, zero,
                                            config.symmetry))
        terms["symmetry"] = symm.mean()
        total = total + terms["symmetry"]
    if config.alpha_parts and source_parts is not None:
        terms["parts"] = _parts_term(source, X, source_parts)
        total = total + config.alpha_parts * terms["parts"]
    return total, {name: float(value.detach()) for name, value in terms.items()}


def _parts_term(source: torch.Tensor, X: torch.Tensor,
                source_parts: torch.Tensor) -> torch.Tensor:
    """The batch mean of the part-affinity term of the deformed points ``X``, each part's
    affine basis from its points in ``source`` (the rest shape: an augmented source is an
    affine map of the stored one, so its parts span the same affine functions)."""
    ref = losses.part_reference(source, source_parts)
    return losses.part_affinity_loss(X, ref).mean()


class NonFiniteStep(FloatingPointError):
    """A training step's values are not finite (NaN or inf), so it cannot be taken: the
    training loop skips it (:meth:`Trainer.step`)."""


def _require_finite_cages(out: dict) -> None:
    """Raise :class:`NonFiniteStep` when the model's source or deformed cage is not finite.

    Parameters
    ----------
    out : dict
        The model's output, with ``source_cage`` and ``deformed_cage`` (B, k, 3) tensors.
    """
    for name in ("source_cage", "deformed_cage"):
        if not bool(torch.isfinite(out[name].detach()).all()):
            raise NonFiniteStep(f"the model's {name.replace('_', ' ')} is not finite "
                                "(NaN or inf)")


def _green_deformed(source, source_cage, deformed_cage, cage_f):
    """Each batch item's source deformed by its cages under Green coordinates, (B, P, 3)."""

    faces = cage_f.cpu().numpy()
    out = []
    for b in range(source.shape[0]):
        rest = source_cage[b].to(source.dtype)
        phi, psi = green_coordinates(source[b], rest, faces)
        out.append(green_deform(phi, psi, rest, deformed_cage[b].to(source.dtype), faces))
    return torch.stack(out)


def _fixed_source_cache(net, source, knn):
    """(weights, shape reference) of a fixed source in a fixed cage, computed once.

    With both the source and its cage fixed (``--fixed-source`` with ``--source-cage``;
    the source is never augmented) the source's coordinates and its shape reference are
    the same at every step, and nothing learned enters them: they are computed on the
    first batch and reused (the same numbers, so a resumed run stays exact; the gain is in
    docs/benchmarks.md, "Design notes"). Returns None otherwise.
    """
    fixed = getattr(net, "fixed_source", None)
    if fixed is None or net.config.fixed_cage_v is None:
        return None
    if source.shape[1:] != fixed.shape or not torch.equal(source, fixed.expand_as(source)):
        return None
    key = (source.shape[0], source.dtype, source.device, knn)
    cache = net.__dict__.setdefault("_fixed_source_terms", {})
    entry = cache.get(key)
    if entry is None or not (torch.equal(entry[0], fixed) and torch.equal(entry[1], net.template)):
        # (re)computed when the source or the cage changed (load_state_dict, edits)
        with torch.no_grad():
            W = mean_value_coordinates(source, net.template.to(source.dtype), net.cage_f)
            ref = None
            if knn is not None:
                index = losses.knn_neighborhoods(source, k=min(knn, source.shape[1]))
                ref = losses.shape_reference(source, index)
        entry = cache[key] = (fixed.clone(), net.template.clone(), W, ref)
    return entry[2], entry[3]


def _template_partners(net, axis):

    key = f"_partners_{axis}"
    if not hasattr(net, key):
        partner, _ = mirror_partners(net.template.double().cpu().numpy(), axis)
        setattr(net, key, torch.as_tensor(partner, device=net.template.device))
    return getattr(net, key)


# ------------------------------------------------------------------------ distribution


#: set when :func:`train` started the process group (and so ends it)
_OWNED_GROUP: list = []


def _distributed(device: str | None):
    """(rank, world size, local rank); initialises the process group under torchrun."""
    world = int(os.environ.get("WORLD_SIZE", "1"))
    if world <= 1:
        return 0, 1, 0
    import torch.distributed as dist

    if not dist.is_initialized():
        backend = "nccl" if torch.cuda.is_available() and device != "cpu" else "gloo"
        dist.init_process_group(backend=backend)
        _OWNED_GROUP.append(True)
    return dist.get_rank(), dist.get_world_size(), int(os.environ.get("LOCAL_RANK", "0"))


def _device(name: str | None, local_rank: int) -> torch.device:
    if name == "auto":
        name = "cuda" if torch.cuda.is_available() else "cpu"
    if name == "cuda":
        if not torch.cuda.is_available():
            raise InputError("--device cuda: no CUDA device is available here")
        return torch.device("cuda", local_rank)
    if name != "cpu":
        raise InputError(f"device must be auto, cpu or cuda, got {name!r}")
    return torch.device("cpu")


def _agree(ok: bool, device: torch.device, world: int) -> bool:
    """Whether ``ok`` holds on every rank (an all-reduce under torchrun)."""
    if world <= 1:
        return ok
    import torch.distributed as dist

    flag = torch.tensor([1.0 if ok else 0.0], device=device)
    dist.all_reduce(flag, op=dist.ReduceOp.MIN)
    return bool(flag.item() > 0.5)


def _finite(tensors) -> bool:
    """Whether every tensor of ``tensors`` is finite (one device synchronisation).

    The tensors may lie on several devices (Adam keeps its step counts on the CPU).
    """
    flags = [torch.isfinite(t).all() for t in tensors]
    if not flags:
        return True
    return bool(torch.stack([f.to(flags[0].device) for f in flags]).all())


def _all_finite(loss, model, world) -> bool:
    """Whether the loss and every gradient are finite, on every rank."""
    grads = [p.grad for p in model.parameters() if p.grad is not None]
    return _agree(_finite([loss.detach(), *grads]), loss.device, world)


def _state_tensors(model, optimizer) -> list:
    """The model's weights and the optimiser's floating-point state tensors."""
    state = [v for entry in optimizer.state.values() for v in entry.values()
             if isinstance(v, torch.Tensor) and v.is_floating_point()]
    return [*model.parameters(), *state]


def _snapshot(model, optimizer):
    """Copies of the model's weights and the optimiser's state, to undo an update."""
    weights = [p.detach().clone() for p in model.parameters()]
    state = {p: {k: v.clone() if isinstance(v, torch.Tensor) else v for k, v in entry.items()}
             for p, entry in optimizer.state.items()}
    return weights, state


def _undo(model, optimizer, snapshot) -> None:
    """Put back the weights and optimiser state of :func:`_snapshot`."""
    weights, state = snapshot
    with torch.no_grad():
        for p, saved in zip(model.parameters(), weights):
            p.copy_(saved)
    optimizer.state.clear()
    optimizer.state.update(state)


#: what computing a step's loss raises when its values overflow: the step is skipped
_STEP_FAILURES = (FloatingPointError, torch.linalg.LinAlgError, np.linalg.LinAlgError)


# ---------------------------------------------------------------------------- logging


class _Log:
    """CSV log (and TensorBoard when installed) of rank 0; quiet on other ranks."""

    def __init__(self, run_dir: Path, active: bool, resume_step: int):
        self.active = active
        self.columns = ["step", "epoch", "loss", *TERMS, "skipped", "seconds"]
        self.handle = self.writer = self.board = None
        if not active:
            return
        path = run_dir / LOG_NAME
        rows = []
        if resume_step and path.exists():  # keep the rows the checkpoint covers
            with open(path, newline="") as handle:
                rows = [r for r in csv.DictReader(handle) if int(r["step"]) <= resume_step]
        self.handle = open(path, "w", newline="")  # noqa: SIM115 - closed in close()
        self.writer = csv.DictWriter(self.handle, fieldnames=self.columns)
        self.writer.writeheader()
        self.writer.writerows(rows)
        try:
            from torch.utils.tensorboard import SummaryWriter

            self.board = SummaryWriter(str(run_dir / "tensorboard"))
        except Exception:  # noqa: BLE001 - tensorboard is optional
            self.board = None

    def write(self, row: dict) -> None:
        if not self.active or self.writer is None or self.handle is None:
            return
        self.writer.writerow({k: row.get(k, "") for k in self.columns})
        self.handle.flush()
        if self.board is not None:
            for name in ("loss", *TERMS):
                if name in row:
                    self.board.add_scalar(f"train/{name}", row[name], row["step"])

    def close(self) -> None:
        if self.handle is not None:
            self.handle.close()
        if self.board is not None:
            self.board.close()


# ---------------------------------------------------------------------------- training


@contextmanager
def _usable(path):
    """Turn what a malformed checkpoint makes torch or Python raise into an InputError.

    An InputError raised inside is passed on, given ``path`` when it names no file.
    """
    try:
        yield
    except InputError as exc:
        if exc.path is not None:
            raise
        raise InputError(exc.problem, str(path)) from None
    except (KeyError, TypeError, ValueError, RuntimeError, AttributeError) as exc:
        first = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
        raise InputError(f"not a usable cagekit checkpoint ({type(exc).__name__}: "
                         f"{first})", str(path)) from None


def _refuse_nonfinite(state_dict, path) -> None:
    bad = nonfinite_tensors(state_dict)
    if bad:
        raise InputError(f"{len(bad)} of the model's weight tensors hold NaN or inf (first: "
                         f"{bad[0]}): the training diverged or the file is damaged",
                         str(resolve(path)))


def _model_of(payload: dict, path) -> NeuralCages:
    """The checkpoint's model holding its weights, validated as inference needs it.

    Parameters
    ----------
    payload : dict
        From :func:`cagekit_learn.checkpoint.load_checkpoint`.
    path : str or Path
        The checkpoint file (named by the errors).

    Returns
    -------
    NeuralCages
        Built from ``payload["model_config"]``, in training mode.

    Raises
    ------
    InputError
        Naming ``path``: the stored model config does not describe the weights exactly
        (a strict load: every name and shape), or a weight holds NaN or inf.
    """
    with _usable(path):
        model = NeuralCages(ModelConfig.from_dict(payload["model_config"]))
        try:
            model.load_state_dict(payload["model"], strict=True)
        except RuntimeError as exc:  # names or shapes differ: say which (the first)
            lines = [line.strip() for line in str(exc).splitlines() if line.strip()]
            detail = (lines[1:] or lines or ["they differ"])[0]
            detail = detail if len(detail) <= 200 else detail[:197] + "..."
            raise InputError(f"its weights do not match its model config ({detail})") \
                from None
    _refuse_nonfinite(model.state_dict(), path)
    return model


def load_model(path: str | os.PathLike,
               map_location: str | torch.device = "cpu") -> tuple[NeuralCages, dict]:
    """A trained model (in eval mode) and its checkpoint from a file or run folder.

    Raises :class:`cagekit.InputError` naming the file for a checkpoint that cannot be
    used, including one whose stored model config does not match its weights or whose
    weights hold NaN or inf (a diverged run or a damaged file): every prediction would be
    NaN.
    """
    payload = load_checkpoint(path, map_location=map_location)
    model = _model_of(payload, resolve(path))
    model.eval()
    return model, payload


#: the counters of a checkpoint and their least values (``world_size`` absent: 1)
_COUNTERS = (("step", 0), ("skipped", 0), ("world_size", 1))


def _resumable(payload: dict, path) -> TrainConfig:
    """The stored config of a checkpoint that a run can continue from, or an InputError.

    The checkpoint is validated as :func:`load_model` (``deform --model``) validates it,
    its training config's model must be its ``model_config``, its settings must pass the
    checks of a new run and its counters (``step``, ``skipped``, ``world_size``) must be
    integers of at least 0, 0 and 1.

    Parameters
    ----------
    payload : dict
        From :func:`cagekit_learn.checkpoint.load_checkpoint`.
    path : str or Path
        The checkpoint file (named by the errors).

    Returns
    -------
    TrainConfig
        The stored config, as saved.

    Raises
    ------
    InputError
        Naming ``path``.
    """
    _model_of(payload, path)
    with _usable(path):
        stored = TrainConfig.from_dict(payload["config"])
        _refuse_retired(payload["config"])
        _same_model(stored.model, payload["model_config"])
        _check(stored)
        for name, least in _COUNTERS:
            as_count(payload.get(name, 1) if name == "world_size" else payload[name],
                     f"its {name}", least)
    return stored


def _refuse_retired(values: dict) -> None:
    """InputError for a setting of an earlier version with a value this one lacks."""
    for name, value in _RETIRED_SETTINGS.items():
        if values.get(name, value) != value:
            raise InputError(f"was trained with {name}={values[name]}, which this version "
                             f"fixes at {value}: it cannot continue exactly")


def _same_model(model: dict, model_config: dict) -> None:
    """InputError unless a checkpoint's training config and model config agree."""
    a = ModelConfig.from_dict(model).to_dict()
    b = ModelConfig.from_dict(model_config).to_dict()
    differ = [name for name in a if a[name] != b[name]]
    if differ:
        raise InputError(f"its config and its model_config disagree on "
                         f"{', '.join(differ)}: the file is damaged")


def resume_config(run_dir: str | os.PathLike) -> TrainConfig:
    """The config a resumed run of ``run_dir`` continues with, its checkpoint validated.

    Parameters
    ----------
    run_dir : str or Path
        A run folder holding ``checkpoint.pt``.

    Returns
    -------
    TrainConfig
        The stored one (before the settings of :data:`FROM_THE_CALLER` are replaced).

    Raises
    ------
    InputError
        Naming the checkpoint, for one that :func:`train` would not resume.
    """
    path = Path(run_dir) / CHECKPOINT_NAME
    return _resumable(load_checkpoint(path), path)


def fixed_source_matches(path: str | os.PathLike, model: dict) -> bool:
    """Whether the mesh at ``path`` is the fixed source a model config stores.

    The same vertex count and normalisation and, when the model took vertex rows (L2
    alignment), the same normalised positions there; the file's name does not matter.

    Parameters
    ----------
    path : str or os.PathLike
        A template mesh (``--fixed-source``).
    model : dict
        A :class:`~cagekit_learn.networks.ModelConfig` as a dict.

    Returns
    -------
    bool
        False also when the model has no fixed source.

    Raises
    ------
    InputError
        An unreadable or degenerate file (naming it).
    """

    if model.get("fixed_source_points") is None:
        return False
    V = io.load_shape(path)[0]
    try:
        frame = Frame.of(V)
        Vn, center, scale = frame.to_unit(V), frame.centre, frame.scale
    except InputError as exc:
        raise InputError(exc.problem, path) from None
    if (len(V) != model.get("fixed_source_vertex_count")
            or not math.isclose(scale, model["fixed_source_scale"], rel_tol=1e-9)
            or not np.allclose(center, model["fixed_source_center"], rtol=0,
                               atol=1e-9 * scale)):
        return False
    rows = model.get("fixed_source_rows")
    return rows is None or bool(np.allclose(Vn[np.asarray(rows, dtype=np.int64)],
                                            model["fixed_source_points"], rtol=0,
                                            atol=1e-6))


def source_cage_matches(path: str | os.PathLike, model: dict) -> bool:
    """Whether the cage file at ``path`` is the fixed source cage a model config stores.

    Parameters
    ----------
    path : str or os.PathLike
        A cage mesh (``--source-cage``), in the fixed source's own frame when the model
        has a fixed source (mapped with its stored normalisation), else in the normalised
        source frame.
    model : dict
        A :class:`~cagekit_learn.networks.ModelConfig` as a dict.

    Returns
    -------
    bool
        False also when the model has no fixed cage.

    Raises
    ------
    InputError
        An unreadable file or an invalid cage (naming it).
    """
    if model.get("fixed_cage_v") is None:
        return False
    cage_v, cage_f = load_source_cage(path)
    V = np.asarray(cage_v, dtype=np.float64)
    if model.get("fixed_source_center") is not None:
        V = (V - np.asarray(model["fixed_source_center"])) / model["fixed_source_scale"]
    stored_v = np.asarray(model["fixed_cage_v"], dtype=np.float64)
    return (V.shape == stored_v.shape
            and np.array_equal(np.asarray(cage_f), np.asarray(model["fixed_cage_f"]))
            and bool(np.allclose(V, stored_v, rtol=0, atol=1e-9)))


def _optimizer(net: NeuralCages, config: TrainConfig) -> torch.optim.Adam:
    nc = {id(p) for p in net.nc_parameters()}
    rest = [p for p in net.parameters() if id(p) not in nc]
    groups = [{"params": rest, "lr": config.lr}]
    if nc:
        groups.append({"params": net.nc_parameters(), "lr": config.lr * NC_LR_FACTOR})
    return torch.optim.Adam(groups)


def _check(config: TrainConfig) -> None:
    if config.epochs is None:
        raise InputError("epochs must be given for a new run (None keeps a resumed run's)")
    for name in ("epochs", "batch_size", "points", "checkpoint_every"):
        if int(getattr(config, name)) < 1:
            raise InputError(f"{name} must be at least 1, got {getattr(config, name)}")
    if not (math.isfinite(config.lr) and 0 < config.lr <= MAX_LR):
        raise InputError(f"learning rate must be finite, > 0 and at most {MAX_LR}, got "
                         f"{config.lr}")
    if config.align not in ("chamfer", "l2"):
        raise InputError(f"align must be chamfer or l2, got {config.align!r}")
    if config.symmetry not in (None, "x", "y", "z"):
        raise InputError(f"symmetry must be x, y, z or None, got {config.symmetry!r}")


def train(config: TrainConfig, resume: bool = False, progress: bool = True,
          collection: ShapeCollection | None = None) -> TrainResult:
    """Train (or resume training) a :class:`NeuralCages` model.

    Parameters
    ----------
    config : TrainConfig
        With ``resume`` the checkpoint's own config is used, except the settings of
        :data:`FROM_THE_CALLER`: ``data`` (the shapes are read from the caller's folder),
        ``epochs``, ``max_steps``, ``max_minutes`` and ``device`` (each unless None;
        raised to train longer). The caller refuses other settings that contradict the
        checkpoint (``cagekit train --resume`` does, with :func:`resume_config`).
    resume : bool
        Continue from ``run_dir/checkpoint.pt`` exactly where it stopped; the checkpoint
        is validated first (as :func:`load_model` validates it, and its counters), an
        InputError naming it otherwise.
    progress : bool
        A progress bar with the loss terms on a terminal (rank 0).
    collection : ShapeCollection, optional
        The shapes, when already loaded (otherwise from ``config.data``). With a fixed
        source and ``align="l2"`` it must come from
        :meth:`ShapeCollection.corresponding` (its ``rows`` and ``vertex_count``).

    With ``config.fixed_source`` (or fixed-source samples already in ``config.model``)
    every pair is (template, shape), every shape once per epoch, the template never
    augmented (the module docstring, and docs/architecture.md).

    Returns
    -------
    TrainResult
    """
    return Trainer(config, resume=resume, progress=progress, collection=collection).run()


class Trainer:
    """One training run: set up by the constructor, advanced by :meth:`step`.

    The constructor reads the checkpoint (``resume``), the collection and the fixed
    source, builds the model and its optimiser (wrapped for DistributedDataParallel under
    torchrun); :meth:`step` trains one batch, :meth:`checkpoint` writes the run's state
    (rank 0) and :meth:`run` loops until the budget is spent. :func:`train` is
    ``Trainer(...).run()``.

    Attributes
    ----------
    config : TrainConfig
        The run's own (the checkpoint's, when resumed).
    net : NeuralCages
    step_count, skipped : int
        Steps taken and steps skipped (a non-finite loss, gradient or update, or a loss
        that could not be computed).
    warned : bool
        Whether a skipped step was warned about (once a run).
    steps_per_epoch, total_steps : int
    rank, world : int
    """

    def __init__(self, config: TrainConfig, resume: bool = False, progress: bool = True,
                 collection: ShapeCollection | None = None):
        self.run_dir = Path(config.run_dir)
        payload = None
        if resume:
            payload = load_checkpoint(self.run_dir / CHECKPOINT_NAME)
            config = self._resumed_config(config, payload)
        _check(config)
        self.rank, self.world, local_rank = _distributed(config.device)
        self.device = _device(config.device, local_rank)
        if self.device.type == "cuda":  # collectives without device_ids use the current one
            torch.cuda.set_device(self.device)
        if self.rank == 0:
            self.run_dir.mkdir(parents=True, exist_ok=True)
        if collection is None:
            collection = load_collection(config.data, config.points, config.seed,
                                         progress=progress and self.rank == 0,
                                         corresponding=config.align == "l2")
        if (config.fixed_source is not None
                or config.model.get("fixed_source_points") is not None):
            config = _with_fixed_source(config, collection)
        self.config, self.collection, self.progress = config, collection, progress
        torch.manual_seed(config.seed)
        self.net = NeuralCages(ModelConfig.from_dict(config.model)).to(self.device)
        self.fixed = None if self.net.fixed_source is None else (
            self.net.fixed_source.cpu().numpy())
        self.optimizer = _optimizer(self.net, config)
        self.step_count = self.skipped = 0
        self.warned = False
        if payload is not None:
            self._restore(payload)
        self.model: torch.nn.Module = self.net
        if self.world > 1:
            from torch.nn.parallel import DistributedDataParallel

            self.model = DistributedDataParallel(
                self.net,
                device_ids=[self.device.index] if self.device.type == "cuda" else None)
        per_rank = len(shard(self.pairs_of(0), 0, self.world))
        self.steps_per_epoch = per_rank // config.batch_size
        if self.steps_per_epoch < 1:
            ranks = "" if self.world == 1 else f" on each of {self.world} ranks"
            lower = f"--batch-size {per_rank} or lower" if per_rank else "more shapes"
            raise InputError(f"{len(collection)} shapes give {per_rank} pair(s) an epoch"
                             f"{ranks}, not a full batch of {config.batch_size}: use {lower}")
        self.total_steps = self.steps_per_epoch * int(config.epochs or 0)  # _check: not None
        if config.max_steps is not None:
            self.total_steps = min(self.total_steps, config.max_steps)
        self.trained_pairs = 0
        self.last: dict[str, float] = {}

    def _resumed_config(self, config, payload) -> TrainConfig:
        """The checkpoint's config (validated) with the caller's data, budget and device."""
        stored = _resumable(payload, self.run_dir / CHECKPOINT_NAME)
        for name in FROM_THE_CALLER:
            if getattr(config, name) is not None:  # None: keep the stopped run's own
                setattr(stored, name, getattr(config, name))
        stored.run_dir = config.run_dir
        return stored

    def _restore(self, payload) -> None:
        """Weights, optimiser, counters and RNG from a checkpoint (:func:`_resumable`)."""
        path = self.run_dir / CHECKPOINT_NAME
        with _usable(path):
            self.net.load_state_dict(payload["model"], strict=True)
            self.optimizer.load_state_dict(payload["optimizer"])
            self.step_count, self.skipped = int(payload["step"]), int(payload["skipped"])
            torch.set_rng_state(payload["rng"])
            ranks = int(payload.get("world_size", 1))
        if ranks != self.world:
            raise InputError(f"was trained by {ranks} process(es); resume it with the same "
                             f"number (now {self.world}) so that it continues exactly",
                             str(path))

    def pairs_of(self, epoch: int) -> Ints:
        """The (source, target) index pairs of an epoch, before sharding."""
        if self.fixed is not None:
            return fixed_source_pairs(len(self.collection), epoch, self.config.seed)
        return epoch_pairs(len(self.collection), epoch, self.config.seed)

    def step(self) -> dict:
        """Train one batch; its terms (the loss NaN when it could not be computed).

        A step that cannot be taken finitely is skipped (:meth:`_skip`), the weights and
        the optimiser's state left as they were before it.
        """
        config = self.config
        epoch, index = divmod(self.step_count, self.steps_per_epoch)
        pairs = shard(self.pairs_of(epoch), self.rank, self.world)
        rows = pairs[index * config.batch_size:(index + 1) * config.batch_size]
        batch = make_batch(self.collection, rows, epoch=epoch,
                           step=index * self.world + self.rank, seed=config.seed,
                           augmentation=config.augment, source_points=self.fixed)
        source = batch["source"].to(self.device)
        target = batch["target"].to(self.device)
        self.optimizer.zero_grad(set_to_none=True)
        loss, terms, why = self._loss(source, target, batch["source_parts"].to(self.device))
        if why is None:
            why = self._descend(loss)
        if why is not None:
            self._skip(why)
        self.step_count += 1
        self.trained_pairs += len(rows) * self.world
        self.last = {"loss": float("nan") if loss is None else float(loss.detach()), **terms}
        return self.last

    def _loss(self, source, target, source_parts):
        """The batch's loss, or why a rank could not compute it.

        Overflowing values make the loss raise (:data:`_STEP_FAILURES`: cages that are not
        finite, an eigendecomposition that fails); every rank learns whether one did.

        Returns
        -------
        loss : scalar tensor or None
        terms : dict of str to float
            Empty when there is no loss.
        why : str or None
            None when every rank has its loss.
        """
        try:
            loss, terms = training_loss(self.model, source, target, self.config,
                                        source_parts=source_parts)
            why = None
        except _STEP_FAILURES as exc:
            loss, terms = None, {}
            text = str(exc).strip().splitlines() or ["no message"]
            why = f"its loss could not be computed ({type(exc).__name__}: {text[0]})"
        if not _agree(why is None, self.device, self.world):
            loss, terms = None, {}
            why = why or "another process could not compute its loss"
        return loss, terms, why

    def _descend(self, loss) -> str | None:
        """Back-propagate and update; why the step must be skipped instead, or None.

        An update that leaves a weight or the optimiser's state non-finite is undone.
        """
        loss.backward()
        if not _all_finite(loss, self.net, self.world):
            return "its loss or a gradient is not finite"
        before = _snapshot(self.net, self.optimizer)
        self.optimizer.step()
        if _agree(_finite(_state_tensors(self.net, self.optimizer)), self.device,
                  self.world):
            return None
        _undo(self.net, self.optimizer, before)
        return "its update left a weight or the optimiser's state not finite"

    def _skip(self, why: str) -> None:
        """Count a skipped step; the first one of the run is warned about (rank 0)."""
        self.skipped += 1
        self.optimizer.zero_grad(set_to_none=True)
        if self.warned or self.rank != 0:
            return
        self.warned = True
        warnings.warn(CagekitWarning(
            f"step {self.step_count + 1} skipped: {why}; the weights stay as they were "
            "(skipped steps are counted in log.csv and the summary)"), stacklevel=3)

    def checkpoint(self) -> None:
        """Write the run's state (rank 0), then wait for every rank."""
        if self.rank == 0:
            save_checkpoint(self.run_dir / CHECKPOINT_NAME, {
                "model": self.net.state_dict(), "optimizer": self.optimizer.state_dict(),
                "config": self.config.to_dict(), "model_config": self.net.config.to_dict(),
                "step": self.step_count, "epoch": self.step_count // self.steps_per_epoch,
                "skipped": self.skipped, "rng": torch.get_rng_state(),
                "world_size": self.world})
        if self.world > 1:
            import torch.distributed as dist

            dist.barrier()

    def _out_of_time(self, start: float) -> bool:
        """Whether ``max_minutes`` are spent (the same answer on every rank)."""
        minutes = self.config.max_minutes
        out = minutes is not None and time.perf_counter() - start > 60 * minutes
        if self.world > 1 and minutes is not None:
            import torch.distributed as dist

            flag = torch.tensor([1.0 if out else 0.0], device=self.device)
            dist.all_reduce(flag, op=dist.ReduceOp.MAX)
            out = bool(flag.item() > 0.5)
        return out

    def run(self) -> TrainResult:
        """Step until the budget (epochs, steps, minutes) is spent, checkpointing."""
        log = bar = None
        start = time.perf_counter()
        self.model.train()
        try:
            log = _Log(self.run_dir, self.rank == 0, self.step_count)
            bar = progress_bar("train", "step", total=self.total_steps,
                               initial=self.step_count,
                               enabled=self.progress and self.rank == 0 and progress_enabled(),
                               leave=True)
            while self.step_count < self.total_steps:
                epoch = self.step_count // self.steps_per_epoch
                last = self.step()
                log.write({"step": self.step_count, "epoch": epoch, **last,
                           "skipped": self.skipped,
                           "seconds": round(time.perf_counter() - start, 3)})
                bar.update(1)
                bar.set_postfix({k: f"{v:.4g}" for k, v in last.items()}, refresh=False)
                out_of_time = self._out_of_time(start)
                if (self.step_count % self.config.checkpoint_every == 0
                        or self.step_count == self.total_steps or out_of_time):
                    self.checkpoint()
                if out_of_time:
                    break
        finally:
            if log is not None:
                log.close()
            if bar is not None:
                bar.close()
            if _OWNED_GROUP:
                import torch.distributed as dist

                dist.destroy_process_group()
                _OWNED_GROUP.clear()
        seconds = time.perf_counter() - start
        return TrainResult(self.net, self.step_count,
                           self.step_count // self.steps_per_epoch, self.skipped, self.last,
                           seconds,
                           self.trained_pairs / seconds if seconds > 0 else float("nan"))


if __name__ == "__main__":  # the entry of earlier versions: say where it went
    print("python -m cagekit_learn.train is gone: run `cagekit train ...`, `python -m "
          "cagekit.cli train ...` or `torchrun ... -m cagekit.cli train ...`", file=sys.stderr)
    sys.exit(2)
