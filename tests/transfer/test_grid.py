"""The picture of a transfer (cagekit.transfer.grid): rest poses first, poses left out named."""

import numpy as np
import pytest
from matplotlib.image import imread

from cagekit.errors import InputError
from cagekit.transfer.grid import PANEL, grid_columns, transfer_grid

V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])


def test_the_rest_pose_comes_first_and_the_rest_is_named_when_left_out():
    names = [f"pose_{i:03d}" for i in range(20)]
    lines, left_out = grid_columns(names)
    assert lines == [[-1, 0, 1, 2, 3, 4], [5, 6, 7, 8, 9, 10]]
    assert left_out == names[11:]
    assert grid_columns(names[:3]) == ([[-1, 0, 1, 2]], [])


def test_the_picture_is_larger_and_says_what_it_leaves_out(tmp_path, monkeypatch):
    import cagekit.render

    drawn = {}
    real = cagekit.render.render_grid

    def spy(path, rows, **kwargs):
        drawn.update(rows=rows, **kwargs)
        return real(path, rows, **kwargs)

    monkeypatch.setattr(cagekit.render, "render_grid", spy)
    poses = [(V + i, F) for i in range(3)]
    left_out = transfer_grid(tmp_path / "g.png", (V, F), (2 * V, F), poses, poses,
                             ["a", "b", "c"], max_poses=2, per_line=2)
    assert left_out == ["c"]
    assert drawn["titles"] == [["rest pose", "a"], None, ["b"], None]
    assert np.array_equal(drawn["rows"][0][0][0], V) and np.array_equal(drawn["rows"][1][0][0],
                                                                         2 * V)
    assert "1 of 3 poses not shown: c" in drawn["captions"][-1]
    assert drawn["size"] == PANEL and PANEL[0] >= 300
    assert imread(tmp_path / "g.png").shape[1] == 2 * PANEL[0]


def test_one_pose_per_name():
    with pytest.raises(InputError, match="one template pose"):
        transfer_grid("x.png", (V, F), (V, F), [(V, F)], [], ["a"])
