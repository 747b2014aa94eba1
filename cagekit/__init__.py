"""cagekit: detail-preserving 3D shape deformation with cages.

The core package: mean value coordinates (:func:`bind`), cage validation, automatic cages
(:func:`fit_cage`), per-pair cage deformation (:func:`deform`), geometry
(cotangent Laplacian, normalisation, sampling, PCA normals), the paper's metrics and mesh
I/O. It never imports torch.

Examples
--------
>>> import numpy as np, cagekit
>>> cage_v, cage_f = cagekit.shapes.box_cage()
>>> b = cagekit.bind(np.array([[0.2, 0.0, -0.1]]), cage_v, cage_f)
>>> b.deform(cage_v * [2.0, 1.0, 1.0]).round(12).tolist()
[[0.4, 0.0, -0.1]]
"""

from cagekit import shapes
from cagekit.cage import cage_encloses, check_cage, winding_numbers
from cagekit.coords import CageBinding, bind, mean_value_coordinates
from cagekit.deformation import DeformResult, deform
from cagekit.errors import CageError, InputError, LandmarkFileError, MeshFileError
from cagekit.fitting import CageFitError, cage_report, fit_cage, template_cage
from cagekit.geometry import (
    cotangent_laplacian,
    denormalize,
    normalize,
    pca_normals,
    point_to_plane,
    sample_surface,
)
from cagekit.metrics import chamfer, chamfer_distance, dcotlap, evaluate

__version__ = "0.1.0"

__all__ = [
    "bind", "CageBinding", "mean_value_coordinates", "cage_encloses", "check_cage",
    "winding_numbers", "cotangent_laplacian", "normalize", "denormalize", "sample_surface",
    "pca_normals", "point_to_plane", "chamfer", "chamfer_distance", "dcotlap", "evaluate",
    "deform", "DeformResult", "fit_cage", "cage_report", "template_cage", "CageFitError",
    "InputError", "MeshFileError", "LandmarkFileError", "CageError", "shapes", "__version__",
]
