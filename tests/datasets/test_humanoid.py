"""Procedural humanoids with skinning and landmarks (cagekit.datasets.humanoid)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from cagekit.datasets import humanoid as hm
from cagekit.datasets.humanoid import (
    BODY_SHAPES,
    JOINTS,
    LANDMARK_NAMES,
    NOVEL_BODIES,
    PARENTS,
    BodyShape,
    humanoid,
    random_body,
    random_pose,
    rig,
)

RES = 0.5  # fast; the default resolution is checked where it matters
BODIES = [*BODY_SHAPES, "random7"]


def _shape(name):
    return random_body(7) if name == "random7" else name


@pytest.fixture(scope="module")
def rigs():
    return {name: rig(_shape(name), resolution=RES) for name in BODIES}


@pytest.fixture(scope="module")
def template():
    return rig("template", resolution=RES)


def _components(V, F):
    n = len(V)
    edges = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    graph = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n))
    return connected_components(graph, directed=False)


# ------------------------------------------------------------------------ geometry


@pytest.mark.parametrize("name", BODIES)
def test_every_component_is_closed_manifold_and_outward(rigs, name):
    r = rigs[name]
    V, F = r.vertices, r.faces
    assert V.dtype == np.float64 and F.dtype == np.int64
    assert V.shape[1] == 3 and F.shape[1] == 3
    count, labels = _components(V, F)
    assert count == len(r.parts) == 25
    face_label = labels[F[:, 0]]
    for c in range(count):
        verts = np.flatnonzero(labels == c)
        remap = np.full(len(V), -1)
        remap[verts] = np.arange(len(verts))
        mesh = trimesh.Trimesh(V[verts], remap[F[face_label == c]], process=False)
        assert mesh.is_watertight, c
        assert mesh.is_winding_consistent, c
        assert mesh.volume > 0, c
    # no degenerate triangle: distinct corners and a real area
    assert np.all((F[:, 0] != F[:, 1]) & (F[:, 1] != F[:, 2]) & (F[:, 2] != F[:, 0]))
    area = 0.5 * np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]),
                                axis=1)
    assert area.min() > 1e-9
    assert np.all(np.isfinite(V))


def test_parts_are_the_components(template):
    r = template
    _, labels = _components(r.vertices, r.faces)
    for name, sl in r.parts.items():
        assert len(np.unique(labels[sl])) == 1, name
    starts = sorted(sl.start for sl in r.parts.values())
    assert starts[0] == 0 and sum(sl.stop - sl.start for sl in r.parts.values()) == len(
        r.vertices)


def test_topology_is_identical_for_every_body(rigs):
    ref = rigs["template"]
    for name in BODIES:
        r = rigs[name]
        assert r.vertices.shape == ref.vertices.shape, name
        assert np.array_equal(r.faces, ref.faces), name
        assert r.parts == ref.parts, name
        assert r.landmarks == ref.landmarks, name
        if name != "template":
            assert not np.allclose(r.vertices, ref.vertices), name


def test_resolution_sets_the_size():
    full = rig("template")
    assert 6000 <= len(full.vertices) <= 12000
    half = rig("stocky", resolution=0.5)
    assert len(half.vertices) < 0.5 * len(full.vertices)
    assert set(half.landmarks) == set(full.landmarks)
    with pytest.raises(ValueError, match="resolution"):
        rig("template", resolution=0)
    with pytest.raises(ValueError, match="unknown body"):
        rig("giant")


def test_frame_height_and_ground(rigs):
    for name in BODY_SHAPES:
        r = rigs[name]
        V = r.vertices
        assert V[:, 1].min() == pytest.approx(0.0, abs=1e-12)
        assert V[:, 1].max() == pytest.approx(BODY_SHAPES[name].height, abs=1e-9)
        lm = {k: V[i] for k, i in r.landmarks.items()}
        assert lm["nose_tip"][2] > lm["head_back"][2]  # faces +z
        reach = 0.3 * BODY_SHAPES[name].height  # T-pose along x (a child's arms: 0.39 h)
        assert lm["l_hand_tip"][0] > reach and lm["r_hand_tip"][0] < -reach
        assert abs(lm["l_hand_tip"][1] - r.joints[JOINTS.index("l_shoulder")][1]) < 0.05
        assert lm["l_toe"][2] > lm["l_heel"][2]
    assert rigs["template"].vertices[:, 1].max() == pytest.approx(1.75)


def test_novel_bodies_differ_as_described(rigs):
    assert set(NOVEL_BODIES) <= set(BODY_SHAPES) and "template" in BODY_SHAPES

    def limb_radius(r, part):
        V = r.vertices[r.parts[part]]
        j0, j1 = {"l_upper_arm": ("l_shoulder", "l_elbow"),
                  "l_thigh": ("l_hip", "l_knee")}[part]
        a, b = r.joints[JOINTS.index(j0)], r.joints[JOINTS.index(j1)]
        d = (b - a) / np.linalg.norm(b - a)
        rel = V - a
        return np.median(np.linalg.norm(rel - np.outer(rel @ d, d), axis=1))

    t, sk, st = rigs["template"], rigs["skinny"], rigs["stocky"]
    height = {n: rigs[n].vertices[:, 1].max() for n in BODY_SHAPES}
    assert height["skinny"] > height["template"] > height["stocky"]
    for part in ("l_upper_arm", "l_thigh"):
        assert limb_radius(sk, part) < 0.8 * limb_radius(t, part)
        assert limb_radius(st, part) > 1.3 * limb_radius(t, part)
    head = {n: np.ptp(rigs[n].vertices[rigs[n].parts["head"]][:, 1]) / height[n]
            for n in BODY_SHAPES}
    assert head["stocky"] > 1.15 * head["template"]

    def fill(name):  # cross-section area / bounding-box area at the waist ring
        r = rigs[name]
        torso = r.vertices[r.parts["torso"]]
        n_sectors = hm._part_counts("torso", RES)[0]
        ring = torso[1 + n_sectors * 8: 1 + n_sectors * 9][:, [0, 2]]
        x, z = ring[:, 0], ring[:, 1]
        area = 0.5 * abs(np.dot(x, np.roll(z, 1)) - np.dot(z, np.roll(x, 1)))
        return area / (np.ptp(x) * np.ptp(z))

    assert fill("template") < 0.8 < 0.9 < fill("robot")


# ------------------------------------------------------------------------ skinning


def test_weights_are_a_partition_of_unity(rigs):
    for name in BODIES:
        r = rigs[name]
        W = r.weights
        assert W.shape == (len(r.vertices), len(JOINTS)) and W.dtype == np.float64
        assert W.min() >= 0.0
        assert np.abs(W.sum(axis=1) - 1.0).max() < 1e-12
        assert (W > 0).sum(axis=1).max() <= 3


def test_weights_blend_smoothly_at_the_elbow(template):
    r = template
    W, V = r.weights, r.vertices
    e = JOINTS.index("l_elbow")
    forearm = V[r.parts["l_forearm"]]
    w = W[r.parts["l_forearm"], e]
    assert np.any(w == 1.0) and np.any((w > 0.05) & (w < 0.95))
    x_elbow = r.joints[e, 0]
    upper = r.parts["l_upper_arm"]
    # upper-arm vertices far from the elbow are not moved by it; the blend is monotone
    assert W[upper, e][V[upper, 0] < x_elbow - 0.1].max() == 0.0
    order = np.argsort(forearm[:, 0])
    near = forearm[order, 0] < x_elbow + 0.05
    assert np.all(np.diff(w[order][near]) >= -1e-12)
    # the blend zone around each joint spans 10-40 % of the segment
    for joint, child, parts in (("l_elbow", "l_wrist", ("l_upper_arm", "l_forearm")),
                                ("l_knee", "l_ankle", ("l_thigh", "l_shin"))):
        j, c = JOINTS.index(joint), JOINTS.index(child)
        seg = np.linalg.norm(r.joints[c] - r.joints[j])
        idx = np.concatenate([np.arange(r.parts[p].start, r.parts[p].stop) for p in parts])
        d = (r.joints[c] - r.joints[j]) / seg
        s = (V[idx] - r.joints[j]) @ d
        wj = W[idx, j]
        zone = s[(wj > 0) & (wj < 1) & (np.abs(s) < 0.5 * seg)]
        assert 0.1 * seg < np.ptp(zone) < 0.4 * seg, joint
    # a bent elbow stretches no edge much (smooth bend, no tearing)
    bent = r.pose({"l_elbow": [0.0, -np.radians(100), 0.0]})
    E = np.concatenate([r.faces[:, [0, 1]], r.faces[:, [1, 2]]])
    rest_len = np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1)
    bent_len = np.linalg.norm(bent[E[:, 0]] - bent[E[:, 1]], axis=1)
    assert (bent_len / rest_len).max() < 3.0


def test_rest_pose_is_exact(template):
    r = template
    assert np.array_equal(r.pose({}), r.vertices)
    assert np.array_equal(r.pose(None), r.vertices)
    identity = {j: np.eye(3) for j in JOINTS}
    assert np.abs(r.pose(identity) - r.vertices).max() <= 1e-12
    zeros = {j: np.zeros(3) for j in JOINTS}
    assert np.abs(r.pose(zeros) - r.vertices).max() <= 1e-12
    assert np.array_equal(r.posed_joints({}), r.joints)
    assert np.abs(r.pose(random_pose(4, amount=0.0)) - r.vertices).max() <= 1e-12


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_rigid_parts_move_rigidly(template, seed):
    r = template
    pose = random_pose(seed)
    V, P = r.vertices, r.pose(pose)
    for joint in ("l_elbow", "r_elbow", "head", "l_knee"):
        idx = np.flatnonzero(r.weights[:, JOINTS.index(joint)] == 1.0)
        assert len(idx) > 20, joint
        pick = idx[np.linspace(0, len(idx) - 1, 40).astype(int)]
        rest = np.linalg.norm(V[pick, None] - V[None, pick], axis=-1)
        posed = np.linalg.norm(P[pick, None] - P[None, pick], axis=-1)
        assert np.abs(rest - posed).max() < 1e-9, joint
    assert not np.allclose(P, V, atol=1e-3)


def test_bone_lengths_are_kept(template):
    r = template
    for seed in range(4):
        J = r.posed_joints(random_pose(seed))
        for j, name in enumerate(JOINTS):
            if PARENTS[name] is not None:
                p = JOINTS.index(PARENTS[name])
                rest = np.linalg.norm(r.joints[j] - r.joints[p])
                assert np.linalg.norm(J[j] - J[p]) == pytest.approx(rest, abs=1e-9)


def test_root_rotation_rotates_everything_about_the_root(template):
    r = template
    R = Rotation.from_rotvec([0.3, -1.1, 0.5]).as_matrix()
    root = r.joints[JOINTS.index("pelvis")]
    expected = (r.vertices - root) @ R.T + root
    assert np.abs(r.pose({"pelvis": R}) - expected).max() < 1e-12
    assert np.abs(r.pose({"pelvis": [0.3, -1.1, 0.5]}) - expected).max() < 1e-12
    assert np.abs(r.posed_joints({"pelvis": R}) - ((r.joints - root) @ R.T + root)).max() < 1e-12


def test_local_rotations_compose_down_the_chain(template):
    r = template
    bend = Rotation.from_rotvec([0.0, 0.0, 0.7]).as_matrix()
    J = r.posed_joints({"l_shoulder": bend})
    s = JOINTS.index("l_shoulder")
    for child in ("l_elbow", "l_wrist", "l_index3"):
        c = JOINTS.index(child)
        assert np.allclose(J[c] - J[s], bend @ (r.joints[c] - r.joints[s]), atol=1e-12)
    # raising the left arm (+z rotation) lifts the hand
    hand = r.landmarks["l_hand_tip"]
    assert r.pose({"l_shoulder": bend})[hand, 1] > r.vertices[hand, 1] + 0.3


def test_bad_poses_are_rejected(template):
    with pytest.raises(ValueError, match="l_elbo"):
        template.pose({"l_elbo": np.eye(3)})
    with pytest.raises(ValueError, match="tail"):
        template.posed_joints({"tail": [0.0, 0.0, 0.1]})
    with pytest.raises(ValueError, match="rotation"):
        template.pose({"l_elbow": 2.0 * np.eye(3)})
    with pytest.raises(ValueError, match="shape"):
        template.pose({"l_elbow": np.zeros(4)})


# --------------------------------------------------------------------------- poses


def test_random_pose_is_deterministic_and_varied():
    a, b, c = random_pose(11), random_pose(11), random_pose(12)
    assert list(a) == list(JOINTS)
    for j in JOINTS:
        assert np.array_equal(a[j], b[j])
        assert a[j].shape == (3, 3) and a[j].dtype == np.float64
        assert np.allclose(a[j].T @ a[j], np.eye(3), atol=1e-12)
        assert np.linalg.det(a[j]) == pytest.approx(1.0)
    assert sum(not np.allclose(a[j], c[j]) for j in JOINTS) > 40
    assert all(np.array_equal(m, np.eye(3)) for m in random_pose(5, amount=0.0).values())
    small = random_pose(11, amount=0.5)
    angle = lambda R: np.degrees(Rotation.from_matrix(R).magnitude())  # noqa: E731
    assert angle(small["l_knee"]) == pytest.approx(0.5 * angle(a["l_knee"]), rel=1e-9)


def test_random_pose_respects_joint_limits():
    for seed in range(30):
        pose = random_pose(seed)
        for side, sign in (("l", 1.0), ("r", -1.0)):
            knee = Rotation.from_matrix(pose[f"{side}_knee"]).as_rotvec()
            assert abs(knee[1]) < 1e-12 and abs(knee[2]) < 1e-12
            assert 0.0 <= np.degrees(knee[0]) <= 120.0  # bends backwards only
            elbow = Rotation.from_matrix(pose[f"{side}_elbow"]).as_rotvec()
            assert 0.0 <= np.degrees(-sign * elbow[1]) <= 130.0
            curl = Rotation.from_matrix(pose[f"{side}_index2"]).as_rotvec()
            assert 0.0 <= np.degrees(-sign * curl[2]) <= 80.0 + 1e-9
        for j in ("spine", "neck"):
            assert np.degrees(Rotation.from_matrix(pose[j]).magnitude()) < 60


def test_same_pose_on_two_bodies_is_ground_truth(rigs):
    pose = random_pose(21)
    t, s = rigs["template"], rigs["stocky"]
    Vt, Vs = t.pose(pose), s.pose(pose)
    assert np.array_equal(t.faces, s.faces)
    assert Vt.shape == Vs.shape and not np.allclose(Vt, Vs, atol=1e-2)
    V, F = humanoid("stocky", pose, resolution=RES)
    assert np.array_equal(V, Vs) and np.array_equal(F, s.faces)
    V0, _ = humanoid("stocky", resolution=RES)
    assert np.array_equal(V0, s.vertices)


def test_random_body_is_deterministic_and_plausible():
    assert random_body(3) == random_body(3)
    assert random_body(3) != random_body(4)
    bodies = [random_body(s) for s in range(5)]
    assert all(isinstance(b, BodyShape) for b in bodies)
    assert len({b.height for b in bodies}) == 5
    assert all(1.4 < b.height < 2.0 and 0.0 <= b.squareness <= 1.0 for b in bodies)
    with pytest.raises(ValueError, match="height"):
        BodyShape(height=-1.0)


# ----------------------------------------------------------------------- landmarks


def test_landmark_names(template):
    names = LANDMARK_NAMES
    assert len(names) >= 96 and len(set(names)) == len(names)
    assert list(template.landmarks) == list(names)
    limbs = [n for n in names if n.split("_")[-1] in ("front", "back", "outer", "inner")
             and any(p in n for p in ("upper_arm", "forearm", "thigh", "shin"))]
    assert len(limbs) == 96
    for required in ("head_top", "nose_tip", "chin", "l_hand_tip", "r_hand_tip", "l_toe",
                     "r_toe", "l_heel", "r_heel", "chest_front", "belly", "back",
                     "pelvis_front", "l_shin_mid_front"):
        assert required in names
    idx = np.array(list(template.landmarks.values()))
    assert idx.min() >= 0 and idx.max() < len(template.vertices)
    assert len(set(idx.tolist())) == len(idx)


@pytest.mark.parametrize("name", BODIES)
def test_landmarks_sit_where_their_names_say(rigs, name):
    r = rigs[name]
    V, lm = r.vertices, r.landmarks
    head = np.arange(r.parts["head"].start, r.parts["head"].stop)
    assert lm["nose_tip"] == head[np.argmax(V[head, 2])]
    assert lm["head_top"] == np.argmax(V[:, 1])
    for n, i in lm.items():
        if n.startswith("l_"):
            assert V[i, 0] > 0, n
        elif n.startswith("r_"):
            assert V[i, 0] < 0, n
    front, back = V[lm["l_thigh_mid_front"]], V[lm["l_thigh_mid_back"]]
    assert front[2] > back[2]
    outer, inner = V[lm["l_thigh_mid_outer"]], V[lm["l_thigh_mid_inner"]]
    assert outer[0] > inner[0]
    assert V[lm["l_upper_arm_mid_outer"], 1] > V[lm["l_upper_arm_mid_inner"], 1]
    assert V[lm["l_forearm_prox_front"], 0] < V[lm["l_forearm_dist_front"], 0]
    assert V[lm["chin"], 1] < V[lm["nose_tip"], 1] < V[lm["head_top"], 1]


def test_mirror_landmarks_and_symmetry(template):
    V, lm = template.vertices, template.landmarks
    for n, i in lm.items():
        if n.startswith("l_"):
            j = lm["r_" + n[2:]]
            assert np.abs(V[j] - V[i] * [-1, 1, 1]).max() < 1e-12, n
        elif not n.startswith("r_"):
            assert abs(V[i, 0]) < 1e-12, n  # central landmarks lie on the plane x = 0
    mirrored = V * [-1, 1, 1]
    dist, _ = cKDTree(V).query(mirrored)
    assert dist.max() < 1e-12
    # and the skeleton
    J = template.joints
    for j, name in enumerate(JOINTS):
        if name.startswith("l_"):
            assert np.array_equal(J[JOINTS.index("r_" + name[2:])], J[j] * [-1, 1, 1])


def test_landmarks_follow_the_pose(rigs):
    pose = random_pose(8)
    for name in ("template", "robot"):
        r = rigs[name]
        P = r.pose(pose)
        i = r.landmarks["l_forearm_mid_front"]
        assert np.array_equal(P[i], r.pose(pose)[i])
        assert not np.allclose(P[i], r.vertices[i])


def _proportions(body):
    """Shoulder width, leg length (hip to ankle), arm length and head height over height."""
    r = rig(body, resolution=0.5)
    J = {name: r.joints[i] for i, name in enumerate(JOINTS)}
    height = r.vertices[:, 1].max()
    return {"shoulders": np.linalg.norm(J["l_shoulder"] - J["r_shoulder"]) / height,
            "legs": (J["l_hip"][1] - J["l_ankle"][1]) / height,
            "arms": np.linalg.norm(J["l_shoulder"] - J["l_wrist"]) / height,
            "head": (height - J["neck"][1]) / height}


@pytest.mark.parametrize("body, expected", [
    ("brute", {"shoulders": (1.6, 2.0), "legs": (0.5, 0.7)}),
    ("child", {"head": (1.5, 2.2), "arms": (0.6, 0.7), "legs": (0.6, 0.75)}),
    ("tall_thin", {"arms": (1.25, 1.4), "legs": (1.1, 1.3)}),
    ("long_torso", {"arms": (0.6, 0.8), "legs": (0.6, 0.8)}),
    ("long_limbed", {"arms": (1.6, 1.8), "legs": (1.2, 1.4), "shoulders": (0.6, 0.8)}),
])
def test_unlike_bodies_have_the_proportions_they_claim(body, expected):
    from cagekit.datasets.humanoid import UNLIKE_BODIES

    assert body in UNLIKE_BODIES and not set(UNLIKE_BODIES) & set(NOVEL_BODIES)
    mine, template = _proportions(body), _proportions("template")
    for name, (low, high) in expected.items():
        assert low <= mine[name] / template[name] <= high, (name, mine[name] / template[name])


@pytest.mark.parametrize("seed", [1, 4])
def test_each_rigid_part_s_landmarks_move_nearly_rigidly(template, seed):
    # landmark_part groups the landmarks by the bones that carry them: the best rigid
    # motion of one part's landmarks misses them by little (the hand's fingers bend, the
    # torso's ends blend with the limbs), that of all landmarks by much
    from cagekit.geometry import polar

    posed, height = template.pose(hm.random_pose(seed)), np.ptp(template.vertices[:, 1])

    def rigid_miss(names):
        idx = [template.landmarks[n] for n in names]
        P = template.vertices[idx] - template.vertices[idx].mean(0)
        Q = posed[idx] - posed[idx].mean(0)
        R = polar((Q.T @ P)[None])[0][0]
        return np.sqrt(((P @ R.T - Q) ** 2).sum(1).mean()) / height

    for part in hm.RIGID_PARTS:
        names = [n for n in LANDMARK_NAMES if hm.landmark_part(n) == part]
        assert len(names) >= 4, part
        assert rigid_miss(names) < 0.03, part
    assert {hm.landmark_part(n) for n in LANDMARK_NAMES} == set(hm.RIGID_PARTS)
    assert rigid_miss(LANDMARK_NAMES) > 0.1
    assert hm.landmark_part("l_upper_arm_mid_outer") == "l_upper_arm"
    assert hm.landmark_part("not_a_landmark") is None
