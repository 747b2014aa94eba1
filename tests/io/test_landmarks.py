"""Landmark files and pairing landmark sets by label (cagekit.io.landmarks)."""

import json
import os

import numpy as np
import pytest
from builders import bits, expect_error, write

from cagekit.errors import InputError, LandmarkFileError
from cagekit.io import landmarks as clm
from cagekit.io.landmarks import match_landmarks


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


# ---------------------------------------------------------------------- landmark files


EXPECTED_MARKS = {"nose": [0.5, 1.25, -2.0], "left_eye": [1e-3, 2.0, 3.0]}


def test_picked_landmarks_with_9_and_10_columns(tmp_path):
    path = write(
        tmp_path / "a.picked",
        "2\nPicked 12 0.2 0.3 0.5 nose 0.5 1.25 -2\n\n"
        "Picked 7 1 0 0 left_eye 1e-3 2 3 41\n",
    )
    marks = clm.load_landmarks(path)
    assert list(marks) == ["nose", "left_eye"]
    assert {k: v.tolist() for k, v in marks.items()} == EXPECTED_MARKS
    assert all(v.dtype == np.float64 and v.shape == (3,) for v in marks.values())


def test_json_and_csv_landmarks(tmp_path):
    as_json = write(tmp_path / "a.json", json.dumps(EXPECTED_MARKS))
    with_header = write(tmp_path / "a.csv", "label,x,y,z\nnose,0.5,1.25,-2\nleft_eye, 1e-3, 2, 3\n")
    no_header = write(tmp_path / "b.csv", "nose,0.5,1.25,-2\n\n# comment\nleft_eye,1e-3,2,3\n")
    for path in (as_json, with_header, no_header):
        marks = clm.load_landmarks(path)
        assert {k: v.tolist() for k, v in marks.items()} == EXPECTED_MARKS
        assert list(marks) == ["nose", "left_eye"]


@pytest.mark.parametrize("ext", [".json", ".csv"])
def test_landmark_round_trip_is_exact(tmp_path, ext):
    marks = {"tip, of nose": np.array([0.1, 1 / 3, -0.0]), "chin": [1e300, 5e-324, 2.0]}
    clm.save_landmarks(tmp_path / f"m{ext}", marks)
    loaded = clm.load_landmarks(tmp_path / f"m{ext}")
    assert list(loaded) == list(marks)
    for label, value in marks.items():
        assert np.array_equal(bits(loaded[label]), bits(np.asarray(value, dtype=float)))


BAD_LANDMARKS = [
    ("empty.json", "", "is empty"),
    ("count.picked", "3\nPicked 1 0 0 1 a 0 0 0\n", "says 3 landmarks but 1 follow"),
    ("header.picked", "Picked 1 0 0 1 a 0 0 0\n", "number of landmarks"),
    ("zero.picked", "0\n", "no landmarks"),
    ("columns.picked", "1\nPicked 1 0 0 1 a 0 0\n", "expected 9 or 10 columns"),
    ("eleven.picked", "1\nPicked 1 0 0 1 a 0 0 0 4 5\n", "found 11"),
    ("face.picked", "1\nPicked one 0 0 1 a 0 0 0\n", "must be numbers"),
    ("text.picked", "1\nPicked 1 0 0 1 a 0 zero 0\n", "not numbers"),
    ("nan.picked", "1\nPicked 1 0 0 1 a 0 nan 0\n", "not finite"),
    ("dup.picked", "2\nPicked 1 0 0 1 a 0 0 0\nPicked 2 0 0 1 a 1 1 1\n", "duplicate label 'a'"),
    ("dup.json", '{"a": [0, 0, 0], "a": [1, 1, 1]}', "duplicate label 'a'"),
    ("nan.json", '{"a": [0, NaN, 0]}', "not finite"),
    ("bigint.json", '{"a": [0, 1' + "0" * 400 + ', 0]}', "entry 1: coordinates of 'a' are not"),
    ("text.json", '{"a": [0, "1", 0]}', "[x, y, z] numbers"),
    ("bool.json", '{"a": [0, true, 0]}', "[x, y, z] numbers"),
    ("two.json", '{"a": [0, 1]}', "[x, y, z] numbers"),
    ("list.json", "[[0, 1, 2]]", "JSON object"),
    ("broken.json", '{"a": [0, 1, 2]', "not valid JSON"),
    ("nothing.json", "{}", "no landmarks"),
    ("columns.csv", "a,1,2\n", "expected 4 columns"),
    ("text.csv", "a,1,two,3\n", "not numbers"),
    ("inf.csv", "a,1,inf,3\n", "not finite"),
    ("dup.csv", "a,1,2,3\na,1,2,3\n", "line 2: duplicate label 'a'"),
    ("label.csv", ",1,2,3\n", "empty label"),
    ("onlyheader.csv", "label,x,y,z\n", "no landmarks"),
    ("marks.txt", "a 1 2 3\n", "unknown landmark extension"),
    ("separators.picked", "\x1c\x1d\n", "is empty"),
    ("carriage.csv", "a,1,2,3\nb\rc,4,5,6\n", "line 2: expected 4 columns"),
    ("huge.csv", "a" * 200_000 + ",1,2,3\n", "invalid CSV"),
]


@pytest.mark.parametrize("name, content, match", BAD_LANDMARKS, ids=[b[0] for b in BAD_LANDMARKS])
def test_bad_landmark_files(tmp_path, name, content, match):
    path = write(tmp_path / name, content)
    expect_error(path, cls=LandmarkFileError, loader=clm.load_landmarks, match=match)


def test_save_landmarks_validates(tmp_path):
    with pytest.raises(InputError, match="face index and barycentric"):
        clm.save_landmarks(tmp_path / "m.picked", EXPECTED_MARKS)
    with pytest.raises(InputError, match="3 finite numbers"):
        clm.save_landmarks(tmp_path / "m.json", {"a": [0, 1]})
    with pytest.raises(InputError, match="3 finite numbers"):
        clm.save_landmarks(tmp_path / "m.json", {"a": [0, 1, np.nan]})
    with pytest.raises(InputError, match="non-empty string"):
        clm.save_landmarks(tmp_path / "m.csv", {" a": [0, 1, 2]})
    with pytest.raises(InputError, match="no landmarks"):
        clm.save_landmarks(tmp_path / "m.csv", {})
    assert os.listdir(tmp_path) == []


def test_save_picked_round_trips_through_load_landmarks(tmp_path):
    from cagekit.io.landmarks import SurfacePoint, save_picked

    points = [SurfacePoint("nose", 12, (0.5, 0.25, 0.25), (0.1, 1.6, 0.12)),
              SurfacePoint("l_heel", 3, (1.0, 0.0, 0.0), (-0.2, 0.0, -1e-3))]
    save_picked(tmp_path / "marks.picked", points)
    lines = (tmp_path / "marks.picked").read_text().splitlines()
    assert lines[0] == "2" and all(len(line.split()) == 9 for line in lines[1:])
    loaded = clm.load_landmarks(tmp_path / "marks.picked")
    assert list(loaded) == ["nose", "l_heel"]
    np.testing.assert_array_equal(loaded["l_heel"], [-0.2, 0.0, -1e-3])


@pytest.mark.parametrize("label, name, message", [
    ("two words", "m.picked", "without spaces"),
    ("nose", "m.json", ".picked files only"),
])
def test_save_picked_refuses_what_thea_cannot_read(tmp_path, label, name, message):
    from cagekit.io.landmarks import SurfacePoint, save_picked

    with pytest.raises(InputError, match=message):
        save_picked(tmp_path / name, [SurfacePoint(label, 0, (1, 0, 0), (0, 0, 0))])
    assert not (tmp_path / name).exists()
