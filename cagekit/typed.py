"""Type aliases for arrays, as trimesh's ``typed.py``: what an annotation promises.

NumPy's types state a dtype, not a shape, so each alias's name says the shape and its
comment the dtype; docstrings give the exact shapes. Inputs are :data:`ArrayLike`
(anything :func:`numpy.asarray` turns into the array asked for, checked by
:mod:`cagekit.geometry.checks`); outputs are the precise arrays below.

- ``Vertices``: (n, 3) float64 vertices, points, a cage's vertices;
- ``Faces``: (m, 3) int64 triangles, indices into a vertex array;
- ``Floats``: float64 of any other shape (weights (n, k), values (n,), matrices);
- ``Ints``: int64 of any other shape (indices, labels, counts);
- ``Bools``: bool masks of any shape.

Examples
--------
>>> import numpy as np
>>> from cagekit.typed import Faces, Vertices
>>> def centroid(V: Vertices, F: Faces) -> Vertices:
...     return V[F].mean(axis=1)
>>> centroid(np.eye(3), np.array([[0, 1, 2]])).shape
(1, 3)
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["ArrayLike", "Bools", "Faces", "Floats", "Ints", "NDArray", "Vertices"]

#: (n, 3) float64: vertices, points, a cage's vertices
Vertices = NDArray[np.float64]
#: (m, 3) int64: triangles, indices into a vertex array
Faces = NDArray[np.int64]
#: float64 of any other shape: weights (n, k), values (n,), matrices
Floats = NDArray[np.float64]
#: int64 of any other shape: indices, labels, counts
Ints = NDArray[np.int64]
#: bool of any shape: masks
Bools = NDArray[np.bool_]
