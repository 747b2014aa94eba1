"""Mesh and point-cloud geometry shared by the rest of cagekit.

Vertices are ``(n, 3)`` float64 and faces ``(m, 3)`` int64, as libigl; a point cloud is a
mesh with no faces. Every function checks its input and raises
:class:`cagekit.errors.InputError` for non-finite coordinates, wrong shapes, out-of-range
indices and empty input; none returns NaN. One concept a module:

- :mod:`~cagekit.geometry.checks`: checked vertices, faces, shapes and counts;
- :mod:`~cagekit.geometry.laplacian`: face areas, cotangent and uniform Laplacians;
- :mod:`~cagekit.geometry.normals`: neighbourhoods, PCA planes and normals;
- :mod:`~cagekit.geometry.rotations`: the polar factor, ARAP's per-vertex rotations;
- :mod:`~cagekit.geometry.sampling`: seeded surface samples and subsets;
- :mod:`~cagekit.geometry.frame`: a shape's unit frame (:class:`~cagekit.geometry.frame.Frame`);
- :mod:`~cagekit.geometry.alignment`: box and similarity alignments;
- :mod:`~cagekit.geometry.parts`: the parts of a shape, pieces split at seams joined.

The names of the first four are re-exported here (``from cagekit.geometry import
as_shape``).
"""

from cagekit.geometry.checks import (
    as_count,
    as_faces,
    as_shape,
    as_vertices,
    remove_duplicate_faces,
    unique_rows,
)
from cagekit.geometry.laplacian import (
    cotangent_laplacian,
    face_areas,
    surface_laplacian,
    uniform_laplacian,
)
from cagekit.geometry.normals import (
    Neighborhoods,
    orient_normals,
    pca_normals,
    pca_planes,
    point_to_plane,
    vertex_neighborhoods,
)
from cagekit.geometry.rotations import polar, vertex_rotations

__all__ = ["Neighborhoods", "as_count", "as_faces", "as_shape", "as_vertices",
           "cotangent_laplacian", "face_areas", "orient_normals", "pca_normals", "pca_planes",
           "point_to_plane", "polar", "remove_duplicate_faces", "surface_laplacian",
           "uniform_laplacian", "unique_rows", "vertex_neighborhoods", "vertex_rotations"]
