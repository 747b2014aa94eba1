"""Tests of cagekit.batch.crossing and of the amplify filter's third test: parts apart in the
source that pass through each other in the variation are found (exactly), named, recorded in
the manifest and reject the variation; parts that touch in the source never count."""

import csv
import os

import numpy as np
import pytest
import trimesh
from builders import cagekit

from cagekit.batch.amplify import COLUMNS, amplify
from cagekit.batch.crossing import Crossings, part_crossings
from cagekit.deformation import DeformResult
from cagekit.geometry.frame import Frame
from cagekit.io import save_mesh


def legs(gap=1.0, height=2.0):
    """Two upright legs (boxes 0.2 wide, ``height`` tall), ``gap`` apart along x."""
    V, F = [], []
    for k, x in enumerate((-gap / 2, gap / 2)):
        box = trimesh.creation.box(extents=(0.2, height, 0.2))
        V.append(box.vertices + [x, 0, 0])
        F.append(box.faces + 8 * k)
    return np.vstack(V), np.vstack(F)


def lean(V, angle_deg):
    """Each leg turned about its top centre by +-``angle_deg`` about z: their feet move
    towards each other (an X under the seat for a large enough angle)."""
    out = V.copy()
    for k, sign in ((0, 1.0), (1, -1.0)):
        part = slice(8 * k, 8 * k + 8)
        top = np.array([V[part, 0].mean(), V[part, 1].max(), 0.0])
        a = np.radians(sign * angle_deg)
        R = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
        out[part] = (V[part] - top) @ R.T + top
    return out


def test_legs_crossed_into_an_x_are_found_and_named():
    V, F = legs()
    crossed = part_crossings(V, F, lean(V, 35))  # feet pass each other: the legs cross
    assert crossed.pairs == ((1, 2),) and crossed.parts == 2
    assert crossed.named() == "1 and 2"


def test_legs_moved_without_crossing_are_not_counted():
    V, F = legs()
    assert part_crossings(V, F, lean(V, 10)).count == 0  # leaning in, still apart
    assert part_crossings(V, F, V * [3.0, 0.5, 1.0]).count == 0  # stretched apart
    assert part_crossings(V, F, V).count == 0


def test_parts_touching_in_the_source_never_count():
    V, F = legs(gap=0.2)  # faces against each other: they touch
    pushed = V.copy()
    pushed[8:, 0] -= 0.1  # the second leg half inside the first
    assert part_crossings(V, F, pushed).count == 0
    V, F = legs(gap=0.2 + 1e-2)  # a hair apart: within the touching gap of the diagonal
    pushed = V.copy()
    pushed[8:, 0] -= 0.1
    assert part_crossings(V, F, pushed).count == 0
    assert part_crossings(V, F, pushed, gap=0.0).pairs == ((1, 2),)


def test_parts_passing_through_each_other_in_the_source_may_go_deeper():
    # a leg pushed into its seat at rest (a tall box through a flat one); the variation
    # pushes it deeper: no crossing. A third part brought through the seat is one.
    seat = trimesh.creation.box(extents=(2.0, 0.2, 2.0))
    leg = trimesh.creation.box(extents=(0.2, 2.0, 0.2))
    other = trimesh.creation.box(extents=(0.2, 0.5, 0.2))
    V = np.vstack([seat.vertices, leg.vertices + [0, -0.95, 0], other.vertices + [0.7, 1, 0]])
    F = np.vstack([seat.faces, leg.faces + 8, other.faces + 16])
    deeper = V.copy()
    deeper[8:16, 1] += 0.3
    assert part_crossings(V, F, deeper).count == 0
    through = deeper.copy()
    through[16:, 1] -= 1.0
    assert part_crossings(V, F, through).pairs == ((1, 3),)


def test_a_part_crossing_itself_is_found():
    V, F = legs()
    # the two legs' tops joined by a strip: one part, a side frame of two legs
    F = np.vstack([F, [[6, 7, 10], [7, 11, 10]]])
    assert part_crossings(V, F, V).parts == 1
    assert part_crossings(V, F, lean(V, 35)) == Crossings(((1, 1),), 1)
    assert part_crossings(V, F, lean(V, 35)).named() == "1 itself"
    assert part_crossings(V, F, lean(V, 10)).count == 0


def test_the_source_gap_is_the_exact_distance_between_faces():
    # two triangles at right angles whose nearest points are on edges (0.01 apart at the
    # origin) while every vertex is at least 0.5 from the other triangle
    V = np.array([[-1, 0, 0], [1, 0, 0], [0, -0.5, 0],
                  [0, 0.01, -1], [0, 0.01, 1], [0, 0.51, 0]])
    F = np.array([[0, 1, 2], [3, 4, 5]])
    through = V.copy()
    through[3:, 1] -= 0.1  # the second one's edge through the first
    assert part_crossings(V, F, through).count == 0  # 0.01 apart: they touch
    assert part_crossings(V, F, through, gap=0.001).pairs == ((1, 2),)


def test_pairs_are_numbered_in_face_order_and_a_long_list_is_cut():
    crossings = Crossings(((1, 3), (2, 4), (3, 5), (4, 6)), parts=6)
    assert crossings.named(shown=2) == "1 and 3, 2 and 4 (+2 more)"
    boxes = [trimesh.creation.box().apply_translation((3.0 * k, 0, 0)) for k in range(3)]
    V = np.vstack([b.vertices for b in boxes])
    F = np.vstack([b.faces + 8 * k for k, b in enumerate(boxes)])
    moved = V.copy()
    moved[16:, 0] -= 6.5  # the third box onto the first
    assert part_crossings(V, F, moved).pairs == ((1, 3),)


# -------------------------------------------------------------------- the amplify filter


def leaning_deformer(V_src, F_src, V_tgt, F_tgt, seed):
    """A stand-in for a model: the source's legs leaning in by ``10 + 25 * seed`` degrees
    (seed 1: crossed)."""
    return DeformResult(vertices=lean(np.asarray(V_src), 10 + 25 * seed),
                        faces=np.asarray(F_src), method="model",
                        source_frame=Frame.of(V_src), target_frame=Frame.of(V_tgt))


@pytest.fixture
def two_stools(tmp_path):
    folder = tmp_path / "stools"
    folder.mkdir()
    for name, gap in (("narrow", 1.0), ("wide", 1.2)):
        save_mesh(folder / f"{name}.obj", *legs(gap))
    return folder


def test_amplify_rejects_crossed_legs_and_says_why(two_stools, tmp_path):
    run = dict(pairs="all", method="model", deformer=leaning_deformer, workers=1,
               max_cd=np.inf, max_nonaffinity=np.inf)
    apart = amplify(str(two_stools), str(tmp_path / "apart"), seed=0, **run)
    assert [(r["status"], r["reason"], r["crossing_parts"]) for r in apart] == [("ok", "", 0)] * 2
    crossed = amplify(str(two_stools), str(tmp_path / "crossed"), seed=1, **run)
    assert [(r["status"], r["reason"], r["crossing_parts"], r["crossing_pairs"])
            for r in crossed] == [("rejected", "parts cross: 1 and 2", 1, "1 and 2")] * 2
    assert sorted(os.listdir(tmp_path / "crossed" / "rejected")) == [
        "narrow__wide.obj", "wide__narrow.obj"]
    with open(tmp_path / "crossed" / "manifest.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert tuple(rows[0]) == COLUMNS and rows[0]["reason"] == "parts cross: 1 and 2"
    # a looser filter keeps them, without redoing them
    again = amplify(str(two_stools), str(tmp_path / "crossed"), seed=1, max_crossings=1,
                    **run)
    assert [(r["status"], r["reason"]) for r in again] == [("ok", "")] * 2
    assert [r["seconds"] for r in again] == [r["seconds"] for r in crossed]
    assert len(os.listdir(tmp_path / "crossed" / "variations")) == 2


def test_the_manifest_says_what_deformed_each_item(two_stools, tmp_path):
    # a model's deformer may hand on the box scaling (or a fitted cage's result): the
    # manifest's method stays the batch's, deformed_by is the result's own
    def deformer(V_src, F_src, V_tgt, F_tgt, seed):
        result = leaning_deformer(V_src, F_src, V_tgt, F_tgt, seed)
        result.method = "scale" if np.ptp(np.asarray(V_tgt)[:, 0]) > 1.3 else "learned"
        return result

    rows = amplify(str(two_stools), str(tmp_path / "out"), pairs="all", method="model",
                   deformer=deformer, workers=1, max_cd=np.inf, max_nonaffinity=np.inf)
    assert [(r["source"], r["method"], r["deformed_by"]) for r in rows] == [
        ("narrow", "model", "scale"), ("wide", "model", "learned")]
    with open(tmp_path / "out" / "manifest.csv", newline="") as fh:
        assert [r["deformed_by"] for r in csv.DictReader(fh)] == ["scale", "learned"]


def test_the_help_documents_the_crossing_test():
    result = cagekit("amplify", "--help")
    assert result.returncode == 0
    text = " ".join(result.stdout.split())
    assert "--max-crossings" in text and "parts cross: 2 and 3" in text
