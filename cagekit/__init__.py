"""cagekit: detail-preserving 3D shape deformation with cages.

The core package: mean value and Green coordinates (:func:`bind`: a :class:`CageBinding` or
a :class:`GreenBinding`), cage validation, automatic cages (:func:`fit_cage`), per-pair cage
deformation (:func:`deform`), frames, sampling, geometry (cotangent Laplacian, PCA normals),
the paper's metrics, mesh and landmark I/O. It never imports torch. docs/architecture.md
maps the modules.

The names below are loaded on first use (PEP 562), so that ``import cagekit`` and the
command line start in a fraction of a second; ``cagekit.bind`` and ``from cagekit import
bind`` work as usual.

Examples
--------
>>> import numpy as np, cagekit
>>> cage_v, cage_f = cagekit.cage.shapes.box_cage()
>>> b = cagekit.bind(np.array([[0.2, 0.0, -0.1]]), cage_v, cage_f)
>>> (b.deform(cage_v * [2.0, 1.0, 1.0]).round(12) + 0.0).tolist()
[[0.4, 0.0, -0.1]]
"""

import importlib

__version__ = "0.1.0"

#: public name -> the module that defines it
_EXPORTS = {
    "bind": "cagekit.coords", "CageBinding": "cagekit.coords",
    "mean_value_coordinates": "cagekit.coords", "GreenBinding": "cagekit.coords",
    "green_coordinates": "cagekit.coords",
    "cage_encloses": "cagekit.cage", "check_cage": "cagekit.cage",
    "winding_numbers": "cagekit.cage",
    "cotangent_laplacian": "cagekit.geometry", "Frame": "cagekit.geometry.frame",
    "sample_surface": "cagekit.geometry.sampling",
    "pca_normals": "cagekit.geometry", "point_to_plane": "cagekit.geometry",
    "chamfer": "cagekit.metrics", "point_chamfer": "cagekit.metrics",
    "Evaluation": "cagekit.metrics",
    "dcotlap": "cagekit.metrics", "evaluate": "cagekit.metrics",
    "deform": "cagekit.deformation", "DeformResult": "cagekit.deformation",
    "DeformOptions": "cagekit.deformation",
    "fit_cage": "cagekit.cage.fitting", "cage_report": "cagekit.cage.fitting",
    "FittedCage": "cagekit.cage.fitting", "CageReport": "cagekit.cage.fitting",
    "template_cage": "cagekit.cage.fitting", "CageFitError": "cagekit.cage.fitting",
    "InputError": "cagekit.errors", "MeshFileError": "cagekit.errors",
    "LandmarkFileError": "cagekit.errors", "CageError": "cagekit.errors",
    "CagekitWarning": "cagekit.errors", "MeshFileWarning": "cagekit.errors",
    "OutsideCageWarning": "cagekit.errors", "OutsideCageError": "cagekit.errors",
}
#: submodules reachable as attributes (``cagekit.io.load_mesh``) without importing them first
_SUBMODULES = ("batch", "cage", "coords", "datasets", "deformation", "errors", "geometry",
               "io", "metrics", "progress", "render", "transfer", "typed")

__all__ = [*_EXPORTS, *_SUBMODULES, "__version__"]


def __getattr__(name):
    if name in _EXPORTS:
        value = getattr(importlib.import_module(_EXPORTS[name]), name)
    elif name in _SUBMODULES:
        value = importlib.import_module(f"cagekit.{name}")
    else:
        raise AttributeError(f"module 'cagekit' has no attribute {name!r}")
    globals()[name] = value
    return value


def __dir__():
    return sorted(__all__)
