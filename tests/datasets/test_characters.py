"""Novel characters with rest poses and meshes of their own (cagekit.datasets.characters)."""

import numpy as np
import pytest

from cagekit.datasets import characters, humanoid


@pytest.mark.parametrize("name", list(characters.CHARACTERS))
def test_each_character_has_its_own_mesh_rest_pose_and_landmarks(name):
    c = characters.character(name)
    template = humanoid.rig("template")
    assert len(c.vertices) != len(template.vertices)
    np.testing.assert_allclose(c.truth(c.rest_pose), c.vertices, atol=1e-12)
    # landmarks lie on the character's own surface, off its vertices
    for m in c.landmarks:
        tri = c.vertices[c.faces[m.face]]
        np.testing.assert_allclose(np.asarray(m.barycentric) @ tri, m.position, atol=1e-12)
        assert max(m.barycentric) < 0.75 and abs(sum(m.barycentric) - 1) < 1e-12
    labels = {m.label for m in c.landmarks}
    assert not labels & set(characters.MISSING)
    assert set(characters.MISSPELT.values()) <= labels
    assert not labels & set(characters.MISSPELT)


def test_remeshed_character_is_the_rig_at_another_resolution_in_another_order():
    c = characters.character("a_pose", seed=3)
    body, resolution, angles, _ = characters.CHARACTERS["a_pose"]
    rig = humanoid.rig(body, resolution=resolution)
    pose = humanoid.random_pose(5)
    truth = c.truth(pose)
    # the same points as the rig's, in another order
    a = np.lexsort(truth.T)
    b = np.lexsort(rig.pose(pose).T)
    np.testing.assert_allclose(truth[a], rig.pose(pose)[b], atol=1e-12)
    assert not np.allclose(truth, rig.pose(pose))


def test_robot_boxes_are_open_boxes_moved_rigidly():
    c = characters.character("robot_boxes")
    edges = np.sort(np.concatenate([c.faces[:, [0, 1]], c.faces[:, [1, 2]],
                                    c.faces[:, [2, 0]]]), axis=1)
    _, uses = np.unique(edges, axis=0, return_counts=True)
    assert (uses == 1).any()  # open: each box has no lid
    pose = humanoid.random_pose(2)
    X = c.truth(pose)
    # every face keeps its edge lengths (each box moves rigidly)
    for V in (X,):
        a = np.linalg.norm(V[c.faces[:, 1]] - V[c.faces[:, 0]], axis=1)
        b = np.linalg.norm(c.truth({})[c.faces[:, 1]] - c.truth({})[c.faces[:, 0]], axis=1)
        np.testing.assert_allclose(a, b, atol=1e-9)


def test_rest_pose_angles():
    r = humanoid.rig(resolution=0.5)
    up = r.pose(characters.rest_pose(arms=30))
    down = r.pose(characters.rest_pose(arms=-30))
    tip = r.landmarks["l_hand_tip"]
    assert up[tip, 1] > r.vertices[tip, 1] > down[tip, 1]
    # symmetric but for the turn
    mirror = np.array([-1.0, 1.0, 1.0])
    assert abs(up[tip, 1] - up[r.landmarks["r_hand_tip"], 1]) < 1e-9
    np.testing.assert_allclose((up * mirror)[r.landmarks["r_hand_tip"]], up[tip], atol=1e-9)


def test_long_limbed_wide_holds_its_long_arms_above_the_t_with_legs_apart():
    # the tree-like "Ent" of issue 30: arms 1.7x the template's, 35 degrees up
    c = characters.character("long_limbed_wide")
    rig = humanoid.rig("long_limbed")
    J = {name: i for i, name in enumerate(humanoid.JOINTS)}
    joints = rig.posed_joints(c.rest_pose)
    arm = joints[J["l_wrist"]] - joints[J["l_shoulder"]]
    assert 30 <= np.degrees(np.arctan2(arm[1], arm[0])) <= 40
    assert joints[J["l_ankle"], 0] - joints[J["l_hip"], 0] > 0.1 * np.linalg.norm(
        joints[J["l_ankle"]] - joints[J["l_hip"]])
    assert "long_limbed_wide" in characters.UNLIKE_CHARACTERS
    assert 8000 <= len(c.vertices) <= 12000  # about the user's 10,000


def test_unknown_character():
    with pytest.raises(ValueError, match="unknown character"):
        characters.character("dragon")
