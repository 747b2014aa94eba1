"""Cages: what a valid cage is, primitive cages, automatic cages, a cage's self-contact.

- :mod:`~cagekit.cage.topology`: edges and components of a triangle mesh;
- :mod:`~cagekit.cage.checks`: :func:`check_cage` (the gate every cage passes),
  self-intersections, winding numbers and the enclosure test;
- :mod:`~cagekit.cage.placement`: why a shape lies outside its cage (other units, another
  origin), for the messages;
- :mod:`~cagekit.cage.shapes`: primitive cages (:func:`~cagekit.cage.shapes.box_cage`);
- :mod:`~cagekit.cage.fitting`: :func:`~cagekit.cage.fitting.fit_cage` (``cagekit fit-cage``);
- :mod:`~cagekit.cage.contact`: an IPC barrier keeping a moving cage free of self-contact.

The names of the first three are re-exported here (``from cagekit.cage import
check_cage``); fitting and contact load heavier libraries (pymeshlab, ipctk) and are
imported from their modules.
"""

from cagekit.cage.checks import (
    cage_encloses,
    check_cage,
    distance_in_diagonals,
    self_intersecting_faces,
    warn_self_intersecting,
    winding_numbers,
)
from cagekit.cage.shapes import box_cage, icosphere_cage
from cagekit.cage.topology import (
    CageTopology,
    cage_topology,
    face_components,
    signed_volume,
    unique_edges,
    vertex_components,
)

__all__ = ["CageTopology", "box_cage", "cage_encloses", "cage_topology", "check_cage",
           "distance_in_diagonals", "face_components", "icosphere_cage", "self_intersecting_faces",
           "signed_volume", "unique_edges", "vertex_components", "warn_self_intersecting",
           "winding_numbers"]
