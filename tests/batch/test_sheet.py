"""Tests of the names and the contact sheet of ``cagekit amplify``: shortest distinctive
names (files and captions), output files without a repeated stem, the sheet's grid growing
in lines, its colours and captions."""

import numpy as np
import pytest
from matplotlib.image import imread

from cagekit.batch.amplify import amplify, pair_title
from cagekit.batch.collection import short_names
from cagekit.batch.sheet import (
    SHEET_COLUMNS,
    TILE_SIZE,
    Tile,
    draw_contact_sheet,
    sheet_size,
    status_colour,
    tile_verdict,
)
from cagekit.datasets import synthetic
from cagekit.errors import InputError
from cagekit.io import save_mesh

TETRA = (np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]]),
         np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]))


@pytest.mark.parametrize("names, expected", [
    # Sweet Home 3D: a catalog folder, then <model>/<model>.obj
    (["blendswap-cc-0/antiqueChair/antiqueChair", "blendswap-cc-0/chairWithCushion/"
      "chairWithCushion", "blendswap-cc-by/chairWithCushion/chairWithCushion"],
     ["antiqueChair", "blendswap-cc-0/chairWithCushion", "blendswap-cc-by/chairWithCushion"]),
    # ShapeNet: <synset>/<id>/model.obj
    (["03001627/1a2b/model", "03001627/3c4d/model"], ["1a2b", "3c4d"]),
    (["tall/a", "tall/b", "low/c"], ["a", "b", "c"]),
    (["x/chair", "y/chair", "y/table"], ["x/chair", "y/chair", "table"]),
    (["a/model", "b/c/model"], ["a", "c"]),
    (["chairs_000", "chairs_001"], ["chairs_000", "chairs_001"]),
    (["only/one/one"], ["one"]),
])
def test_short_names_are_the_shortest_distinctive_tails(names, expected):
    assert [short_names(names)[n] for n in names] == expected


def test_pair_titles_fit_and_keep_both_ends():
    assert pair_title("antiqueChair", "chair2") == "antiqueChair → chair2"
    long = pair_title("blendswap-cc-0/chairWithCushion", "blendswap-cc-by/chairWithCushion")
    assert len(long) <= 40 and long.startswith("blends") and "Cushion →" in long
    assert long.endswith("Cushion")
    # a short name leaves its room to the long one
    title = pair_title("stool", "kush_nuba_camp_bench.dae.cached", width=34)
    assert len(title) == 34 and title.startswith("stool → kush_nuba_")
    assert title.endswith(".dae.cached")


def test_a_one_part_source_shows_no_worst_part_the_filter_ignores():
    from cagekit.batch.amplify import _decisive_figures

    row = {"cd": 0.0354, "parts": 1, "part_nonaffinity_worst": 0.0578, "crossing_parts": 0}
    assert _decisive_figures(row) == "CD x1e2 3.54 · one part · crossing 0"
    assert _decisive_figures({**row, "parts": 3}) == (
        "CD x1e2 3.54 · worst part 5.78% · crossing 0")


def test_a_line_wider_than_its_tile_is_cut_to_fit_in_pixels():
    """A count of characters does not bound a width: W is wider than i."""
    from matplotlib.font_manager import FontProperties
    from matplotlib.textpath import TextPath

    from cagekit.batch.sheet import _fit_pixels

    def pixels(text):
        path = TextPath((0, 0), text, prop=FontProperties(size=10, weight="bold"))
        return path.get_extents().x1 * 100 / 72

    assert _fit_pixels("i" * 30, 10, "bold", 288) == "i" * 30
    wide = _fit_pixels("W" * 30, 10, "bold", 288)
    assert pixels("W" * 30) > 288 >= pixels(wide) > 240
    assert wide.startswith("WWWW") and "..." in wide and wide.endswith("WWWW")
    # a pair title keeps its arrow, the longer name cut first; a $ is not maths
    title = _fit_pixels("WoodenChairMMMMMMMM → ModernWWWWWChairWW", 10, "bold", 288)
    source, target = title.split(" → ")
    assert pixels(title) <= 288 and source.startswith("Wood") and target.endswith("WW")
    assert _fit_pixels("a$\\foo$b → c", 10, "bold", 288) == "a$\\foo$b → c"


def test_outputs_are_named_without_the_repeated_stem(tmp_path):
    folder = tmp_path / "catalog"
    for k, name in enumerate(("antiqueChair/antiqueChair", "chair2/chair2", "x/chair",
                              "y/chair")):
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        save_mesh(folder / f"{name}.obj", *synthetic.chair(seed=k, resolution=0.5))
    pairs = tmp_path / "pairs.csv"
    pairs.write_text("antiqueChair/antiqueChair,chair2/chair2\nx/chair,y/chair\n")
    rows = amplify(str(folder), str(tmp_path / "out"), pairs=str(pairs), method="scale",
                   workers=1)
    assert [r["output"] for r in rows] == ["antiqueChair__chair2.obj", "x-chair__y-chair.obj"]


def test_the_sheet_is_a_grid_growing_in_lines():
    assert sheet_size(1) == TILE_SIZE
    assert sheet_size(SHEET_COLUMNS) == (SHEET_COLUMNS * TILE_SIZE[0], TILE_SIZE[1])
    assert sheet_size(SHEET_COLUMNS + 1) == (SHEET_COLUMNS * TILE_SIZE[0], 2 * TILE_SIZE[1])
    assert sheet_size(24, columns=6) == (6 * TILE_SIZE[0], 4 * TILE_SIZE[1])


def test_status_colours():
    assert status_colour("ok") == "#2e7d32"
    assert status_colour("rejected", "parts cross: 1 and 2") == "#c62828"
    assert status_colour("rejected", "CD x1e2 6.00 > 5.00") == "#e65100"


def test_the_drawn_sheet_has_its_size_and_each_tile_its_status_colour(tmp_path):
    tiles = [Tile(TETRA, TETRA, TETRA, f"s{k} → t{k}", "CD x1e2 1.00 · worst part 0.10% · "
                  "crossing 0", "ok" if k % 2 else "rejected",
                  "" if k % 2 else "parts cross: 1 and 2") for k in range(7)]
    path = draw_contact_sheet(tiles, tmp_path / "sheet.png", columns=3)
    image = imread(path)[..., :3]
    assert image.shape[:2] == (3 * TILE_SIZE[1], 3 * TILE_SIZE[0])  # 3 lines of 3
    green, red = (np.array([0x2e, 0x7d, 0x32]) / 255, np.array([0xc6, 0x28, 0x28]) / 255)

    def has(colour, line, column):
        tile = image[line * TILE_SIZE[1]:(line + 1) * TILE_SIZE[1],
                     column * TILE_SIZE[0]:(column + 1) * TILE_SIZE[0]]
        return bool(np.any(np.abs(tile - colour).max(axis=-1) < 0.05))

    assert has(red, 0, 0) and not has(green, 0, 0)  # tile 0: rejected
    assert has(green, 0, 1) and not has(red, 0, 1)  # tile 1: ok
    assert not has(red, 2, 1) and not has(green, 2, 1)  # no tile 7: blank
    with pytest.raises(InputError, match="at least one tile"):
        draw_contact_sheet([], tmp_path / "empty.png")


def test_a_tile_says_what_made_its_variation_when_the_method_did_not():
    from cagekit.batch.amplify import _handed_on

    def tile(status, reason="", handed_on=""):
        return Tile(TETRA, TETRA, TETRA, "a -> b", "", status, reason, handed_on)

    assert tile_verdict(tile("ok")) == "ok"
    assert tile_verdict(tile("rejected", "CD x1e2 6.00 > 5.00")) == \
        "REJECTED: CD x1e2 6.00 > 5.00"
    assert tile_verdict(tile("ok", "", "box scaling")) == "ok (by box scaling)"
    assert tile_verdict(tile("rejected", "parts cross: 1 and 2", "a fitted cage")) == \
        "REJECTED (by a fitted cage): parts cross: 1 and 2"
    # from a manifest's row: only a model's items are handed on
    assert _handed_on({"method": "model", "deformed_by": "scale"}) == "box scaling"
    assert _handed_on({"method": "model", "deformed_by": "cage"}) == "a fitted cage"
    assert _handed_on({"method": "model", "deformed_by": "learned"}) == ""
    assert _handed_on({"method": "scale", "deformed_by": "scale"}) == ""
    assert _handed_on({"method": "cage", "deformed_by": "cage"}) == ""
