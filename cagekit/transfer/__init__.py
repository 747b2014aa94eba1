"""Landmark-driven deformation transfer to a novel character ("Neural Cages", section 4.2).

One concept, one folder: :mod:`~cagekit.transfer.character` runs it (the character's cage,
the binding, each pose: :func:`fit_character`, :func:`transfer`);
:mod:`~cagekit.transfer.character_cage` fits the template's cage to the character by its
landmarks; :mod:`~cagekit.transfer.surface_binding` binds a character whose limbs touch its
body, refined by :mod:`~cagekit.transfer.robust_arap`; :mod:`~cagekit.transfer.rules` moves
the character's cage like the template's; :mod:`~cagekit.transfer.loose_pieces` keeps
separate mesh pieces on what they touched. The learned template cage is
:mod:`cagekit_learn.transfer`; the command is ``cagekit transfer``.
"""

from cagekit.transfer.character import (
    PART_LANDMARKS,
    ROOTS,
    SMOOTHNESS,
    CharacterCage,
    ClassicalFitter,
    cage_oracle,
    check_landmarks_on_mesh,
    classical_fitter,
    corresponds,
    fit_character,
    landmark_parts,
    render_grid,
    template_cage_classical,
    transfer,
)
from cagekit.transfer.loose_pieces import LoosePieces, find_loose_pieces

__all__ = ["PART_LANDMARKS", "ROOTS", "SMOOTHNESS", "CharacterCage", "ClassicalFitter",
           "LoosePieces",
           "cage_oracle", "check_landmarks_on_mesh", "classical_fitter", "corresponds",
           "find_loose_pieces", "fit_character", "landmark_parts", "render_grid",
           "template_cage_classical", "transfer"]
