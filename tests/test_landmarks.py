"""Pairing landmark sets by label (cagekit.landmarks)."""

import numpy as np
import pytest

from cagekit.errors import InputError
from cagekit.landmarks import match_landmarks


def test_match_landmarks_pairs_by_label_and_reports_the_rest():
    a = {"nose": [0, 1, 2], "chin": [0, 0, 1], "l_eye": [1, 1, 1], "r_eye": [-1, 1, 1],
         "ear": [2, 0, 0]}
    b = {"r_eye": [-2, 2, 2], "chin": [0, 0, 2], "nose": [0, 2, 4], "l_eye": [2, 2, 2],
         "tail": [9, 9, 9]}
    m = match_landmarks(a, b)
    assert m.labels == ["nose", "chin", "l_eye", "r_eye"]  # the first set's order
    np.testing.assert_array_equal(m.target, 2 * m.source)
    assert m.source_only == ["ear"] and m.target_only == ["tail"]
    with pytest.raises(InputError, match=r"a\.json and b\.csv share 4 landmark label\(s\); "
                                         r"at least 5"):
        match_landmarks(a, b, minimum=5, source_name="a.json", target_name="b.csv")


def test_require_all_refuses_labels_in_one_set_only_and_names_them():
    a = {"nose": [0, 0, 0], "chin": [0, 1, 0], "ear": [1, 0, 0], "eye": [0, 0, 1]}
    b = {**a, "tail": [1, 1, 1]}
    assert match_landmarks(a, dict(a), require_all=True).labels == list(a)
    with pytest.raises(InputError, match=r"a\.json and b\.json must name the same "
                                         r"landmarks: 1 landmark .*tail \(only in b\.json\)"):
        match_landmarks(a, b, require_all=True, source_name="a.json", target_name="b.json")


def test_unmatched_lists_both_sides_on_one_line_and_shortens_long_lists():
    a = {f"s{i}": [i, 0, 0] for i in range(12)} | {"x": [0, 0, 0], "y": [1, 0, 0],
                                                   "z": [0, 1, 0], "w": [0, 0, 1]}
    b = {"x": [0, 0, 0], "y": [1, 0, 0], "z": [0, 1, 0], "w": [0, 0, 1], "t0": [1, 1, 1]}
    line = match_landmarks(a, b).unmatched("a.json", "b.json")
    assert "\n" not in line and line.startswith("13 landmark label(s) in one file only")
    assert "s0, s1" in line and "and 4 more (only in a.json)" in line
    assert line.endswith("t0 (only in b.json)")
    assert match_landmarks(b, b).unmatched() is None
