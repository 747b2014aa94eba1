"""The landmark files shipped in data/characters/: the template's and the real characters'
agree label for label (issue 33), at the right heights of the body."""

from pathlib import Path

import numpy as np
import pytest
from builders import ROOT

from cagekit.datasets import humanoid
from cagekit.io.landmarks import load_landmarks, match_landmarks

FOLDER = Path(ROOT) / "data" / "characters"
CHARACTERS = sorted(FOLDER.glob("*.picked"))
#: arm labels: their height depends on the character's rest pose (T or A)
ARM_WORDS = ("arm", "hand", "thumb", "palm")


def test_the_picked_labels_are_60_of_the_template_s_on_both_sides():
    names = humanoid.PICKED_LANDMARK_NAMES
    assert len(names) == len(set(names)) == 60 and set(names) <= set(humanoid.LANDMARK_NAMES)
    left = {n[2:] for n in names if n.startswith("l_")}
    assert left == {n[2:] for n in names if n.startswith("r_")} and len(left) == 24


def test_the_template_file_holds_the_template_s_vertices():
    marks = load_landmarks(FOLDER / "template.json")
    assert list(marks) == list(humanoid.PICKED_LANDMARK_NAMES)
    rig = humanoid.rig("template")  # apps.humanoid_data's template.obj (resolution 1)
    for label, xyz in marks.items():
        np.testing.assert_allclose(xyz, rig.vertices[rig.landmarks[label]], atol=1e-12)


@pytest.mark.parametrize("path", CHARACTERS, ids=lambda p: p.stem)
def test_each_character_shares_at_least_60_labels_with_the_template(path):
    assert len(CHARACTERS) == 3
    match = match_landmarks(load_landmarks(FOLDER / "template.json"), load_landmarks(path))
    assert len(match.labels) >= 60
    assert match.source_only == [] == match.target_only


@pytest.mark.parametrize("path", CHARACTERS, ids=lambda p: p.stem)
def test_each_character_label_lies_at_the_template_s_height_on_the_body(path):
    template = load_landmarks(FOLDER / "template.json")
    character = load_landmarks(path)
    labels = [n for n in template if not any(w in n for w in ARM_WORDS)]
    assert len(labels) == 40

    def heights(marks):
        every = np.array(list(marks.values()))
        y = np.array([marks[n][1] for n in labels])
        return (y - every[:, 1].min()) / np.ptp(every[:, 1])

    # a label on another part (a kneecap on the chest) would be off by 0.2 or more
    assert np.abs(heights(character) - heights(template)).max() < 0.05
