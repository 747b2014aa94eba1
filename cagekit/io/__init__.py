"""Files in and out: meshes and point clouds, landmarks, checked reading and atomic writing.

- :mod:`~cagekit.io.meshes`: :func:`load_mesh`, :func:`save_mesh`, point clouds;
- :mod:`~cagekit.io.assets`: a deformed shape written as a copy of its source file, keeping
  UVs, materials, groups, colours and (carried) normals;
- :mod:`~cagekit.io.pmd`: :func:`read_pmd`, 0 A.D.'s PMD models (``load_mesh`` reads them);
- :mod:`~cagekit.io.landmarks`: landmark files and matching landmarks by label;
- :mod:`~cagekit.io.files`: checked reading, atomic writing, output folders removed on
  failure.

The mesh and landmark functions are re-exported here (``cagekit.io.load_mesh``).
"""

from cagekit.io.assets import (
    asset_contents,
    kept_extension,
    move_deformed,
    remove_deformed,
    save_deformed,
)
from cagekit.io.landmarks import load_landmarks, save_landmarks, save_picked
from cagekit.io.meshes import (
    SUPPORTED_MESH_EXTENSIONS,
    SUPPORTED_POINT_EXTENSIONS,
    WRITTEN_MESH_EXTENSIONS,
    load_mesh,
    load_points,
    load_shape,
    save_mesh,
    save_points,
)
from cagekit.io.pmd import PmdModel, read_pmd

__all__ = ["SUPPORTED_MESH_EXTENSIONS", "SUPPORTED_POINT_EXTENSIONS",
           "WRITTEN_MESH_EXTENSIONS", "PmdModel", "asset_contents", "read_pmd",
           "kept_extension", "load_landmarks", "move_deformed", "remove_deformed",
           "load_mesh", "load_points", "load_shape", "save_landmarks", "save_mesh",
           "save_deformed", "save_picked", "save_points"]
