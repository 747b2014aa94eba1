"""Named poses of the humanoid template, for ``cagekit transfer`` (``humanoid:NAME``).

An artist choosing a pose for ``cagekit transfer`` gives a mesh of the template in that pose
(the template's vertices moved, same count and order, as a rig exports it) or one of these
names, which pose the humanoid template of ``python -m apps.humanoid_data`` by its rig:

- the rest poses of the novel characters of :data:`cagekit.datasets.characters.CHARACTERS`
  (:data:`REST_POSES`: ``t_pose``, ``a_pose``, ``arms_up``, ``relaxed``, ``arms_down``);
- ``pose_NNN``: test pose ``NNN`` of ``apps.humanoid_data``
  (``humanoid.random_pose(TEST_POSE_SEED + NNN)``), the pose of its ``poses/pose_NNN.obj``.
"""

from __future__ import annotations

import re

import numpy as np
from numpy.typing import ArrayLike

from cagekit.datasets import characters, humanoid
from cagekit.errors import InputError

__all__ = ["PREFIX", "REST_POSES", "TEST_POSE_SEED", "is_named_pose", "named_pose",
           "pose_names", "posed_template"]

#: what starts a named pose on the command line (``humanoid:a_pose``)
PREFIX = "humanoid:"
#: seed of test pose 0 of ``apps.humanoid_data`` (its training poses use seeds below)
TEST_POSE_SEED = 100_000
#: the rest poses named after the novel characters that stand in them
REST_POSES: tuple[str, ...] = ("t_pose", "a_pose", "arms_up", "relaxed", "arms_down")
#: how close (a share of the template's height) a TEMPLATE must be to the rig's rest pose
REST_TOLERANCE = 1e-6


def pose_names(test_poses: int = 20) -> list[str]:
    """The names :func:`named_pose` takes (``pose_NNN`` for any NNN; the first shown).

    Examples
    --------
    >>> pose_names(2)
    ['t_pose', 'a_pose', 'arms_up', 'relaxed', 'arms_down', 'pose_000', 'pose_001']
    """
    return [*REST_POSES, *(f"pose_{i:03d}" for i in range(test_poses))]


def is_named_pose(given: str) -> bool:
    """True if a POSE argument names a pose (``humanoid:NAME``) rather than a file.

    Examples
    --------
    >>> is_named_pose("humanoid:a_pose"), is_named_pose("poses/a_pose.obj")
    (True, False)
    """
    return str(given).startswith(PREFIX)


def named_pose(name: str) -> dict[str, np.ndarray]:
    """The joint rotations of a named pose.

    Parameters
    ----------
    name : str
        One of :func:`pose_names` (with or without :data:`PREFIX`).

    Returns
    -------
    dict[str, (3, 3) float64]
        Local rotations for :meth:`cagekit.datasets.humanoid.Rig.pose`.

    Raises
    ------
    InputError
        An unknown name (the message lists the names).

    Examples
    --------
    >>> sorted(named_pose("humanoid:a_pose"))[:2]
    ['chest', 'l_elbow']
    >>> len(named_pose("pose_003")) == len(humanoid.JOINTS)
    True
    """
    name = name.removeprefix(PREFIX)
    if name in REST_POSES:
        return characters.rest_pose(**characters.CHARACTERS[name][2])
    match = re.fullmatch(r"pose_(\d{3,})", name)
    if match:
        return humanoid.random_pose(TEST_POSE_SEED + int(match.group(1)))
    raise InputError(f"unknown pose {PREFIX}{name}; named poses: "
                     f"{', '.join(REST_POSES)}, pose_000, pose_001, ... (the test poses of "
                     "python -m apps.humanoid_data)")


def posed_template(name: str, template_v: ArrayLike, template_f: ArrayLike, *,
                   resolution: float = 1.0) -> np.ndarray:
    """The humanoid template in a named pose, vertex for vertex the given template's.

    Parameters
    ----------
    name : str
        As :func:`named_pose`.
    template_v : (n, 3) array_like of float
        The TEMPLATE given to ``cagekit transfer``: it must be the humanoid template of
        ``apps.humanoid_data`` at ``resolution`` (its rest pose, same vertex order).
    template_f : (m, 3) array_like of int
    resolution : float, default 1.0
        The template's mesh resolution (``apps.humanoid_data --resolution``).

    Returns
    -------
    (n, 3) float64
        The template's vertices in the pose.

    Raises
    ------
    InputError
        An unknown name, or a template that is not the humanoid template.
    """
    pose = named_pose(name)
    rig = humanoid.rig("template", resolution=resolution)
    V, F = np.asarray(template_v, np.float64), np.asarray(template_f)
    same = (V.shape == rig.vertices.shape and F.shape == rig.faces.shape
            and np.array_equal(F, rig.faces)
            and np.abs(V - rig.vertices).max() <= REST_TOLERANCE * np.ptp(V[:, 1]))
    if not same:
        raise InputError(f"a named pose ({PREFIX}{name.removeprefix(PREFIX)}) moves the "
                         f"humanoid template of python -m apps.humanoid_data (resolution "
                         f"{resolution:g}, {len(rig.vertices)} vertices); this template is "
                         f"another mesh ({len(V)} vertices): give the pose as a mesh file of "
                         "it instead")
    return rig.pose(pose)
