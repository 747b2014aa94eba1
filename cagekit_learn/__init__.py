"""cagekit_learn: the learned mode of "Neural Cages" on cagekit's coordinate API (torch).

One concept a module: :mod:`~cagekit_learn.coords` (differentiable, batched mean value
coordinates, ``bind``/``deform`` as in the core, matching it in float64),
:mod:`~cagekit_learn.green` (differentiable Green coordinates: ``bind(..., method="green")``),
:mod:`~cagekit_learn.losses` (the same terms as :mod:`cagekit.deformation.terms`),
:mod:`~cagekit_learn.networks` (the PointNet encoder, N_c and N_d),
:mod:`~cagekit_learn.data` (folders of meshes, pairs, augmentation),
:mod:`~cagekit_learn.train` (``cagekit train``: Adam, checkpoints, exact resume,
DistributedDataParallel under torchrun), :mod:`~cagekit_learn.checkpoint` (atomic, read with
``weights_only=True``) and :mod:`~cagekit_learn.inference` (``cagekit deform --model``).
Install with ``pip install -e '.[learn]'`` (torch 2.13.0); the core package never imports
this one, nor torch. :func:`load_model` takes a run folder, a checkpoint or a shipped
model's name (``load_model("chairs")``, :mod:`~cagekit_learn.shipped`). See
docs/architecture.md.

Examples
--------
>>> import torch, cagekit_learn
>>> from cagekit.cage.shapes import box_cage
>>> v, f = box_cage()
>>> cage = torch.tensor(v, requires_grad=True)
>>> b = cagekit_learn.bind(torch.zeros(1, 3, dtype=torch.float64), cage, f)
>>> b.deform(2 * cage).sum().backward()
>>> tuple(b.weights.shape), bool(torch.isfinite(cage.grad).all())
((1, 8), True)
"""

from importlib import import_module as _import_module

__all__ = ["bind", "deform", "CageBinding", "GreenBinding", "mean_value_coordinates",
           "load_model"]

#: where each lazy name lives (the others: :mod:`cagekit_learn.coords`)
_HOMES = {"load_model": "cagekit_learn.train", "GreenBinding": "cagekit_learn.green"}


def __getattr__(name):
    # torch is imported on first use, so that ``cagekit_learn.data`` stays light
    if name in __all__:
        return getattr(_import_module(_HOMES.get(name, "cagekit_learn.coords")), name)
    raise AttributeError(f"module 'cagekit_learn' has no attribute {name!r}")


def __dir__():
    # the lazy names are listed although not loaded yet (``dir``, tab completion)
    return sorted(set(globals()) | set(__all__))
