"""Landmark-driven deformation transfer to a novel character ("Neural Cages", section 4.2).

:mod:`cagekit.transfer.character` fits the character's cage, binds the character and moves
it like the template (:func:`fit_character`, :func:`transfer`); :mod:`cagekit.transfer.loose_pieces`
keeps a character's separate mesh pieces on what they touched. The learned template cage
is :mod:`cagekit_learn.transfer`; the command is ``cagekit transfer``.
"""

from cagekit.transfer.character import (
    PART_LANDMARKS,
    ROOTS,
    SMOOTHNESS,
    CharacterCage,
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

__all__ = ["PART_LANDMARKS", "ROOTS", "SMOOTHNESS", "CharacterCage", "LoosePieces",
           "cage_oracle", "check_landmarks_on_mesh", "classical_fitter", "corresponds",
           "find_loose_pieces", "fit_character", "landmark_parts", "render_grid",
           "template_cage_classical", "transfer"]
