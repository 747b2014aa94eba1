"""The artist-style cage of a T-pose humanoid (cagekit.datasets.humanoid_cage)."""

import numpy as np
import pytest

from cagekit.cage import check_cage, winding_numbers
from cagekit.datasets import humanoid
from cagekit.datasets.humanoid_cage import humanoid_cage


@pytest.mark.parametrize("body", ["template", "skinny", "stocky", "robot"])
def test_the_cage_is_valid_and_encloses_the_body(body):
    rig = humanoid.rig(body, resolution=0.5)
    v, f = humanoid_cage(rig)
    assert np.array_equal(check_cage(v, f), f)  # closed, manifold, outward, no crossing
    assert winding_numbers(rig.vertices, v, f).min() > 0.5
    assert len(v) == 130


def test_each_limb_has_its_own_tube():
    rig = humanoid.rig("template", resolution=0.5)
    v, f = humanoid_cage(rig)
    # between the legs, below the crotch, there is no cage: a point there is outside
    knee = rig.joints[humanoid.JOINTS.index("l_knee")]
    assert winding_numbers(np.array([[0.0, knee[1], knee[2]]]), v, f)[0] < 0.5
    # under an arm, beside the torso, neither
    shoulder = rig.joints[humanoid.JOINTS.index("l_shoulder")]
    below = shoulder + np.array([0.1, -0.25, 0.0])
    assert winding_numbers(below[None], v, f)[0] < 0.5
