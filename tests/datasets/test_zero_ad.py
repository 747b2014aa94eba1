"""The game furniture of Debian's 0ad-data: unpacked once, read as meshes, credited."""

import os
import sys
import zipfile

import numpy as np
import pytest

from cagekit.datasets import zero_ad
from cagekit.errors import InputError
from cagekit.io import load_mesh

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "io"))
from test_pmd import pmd_bytes  # noqa: E402


def fake_archive(path, members):
    with zipfile.ZipFile(path, "w") as zf:
        for name in members:
            zf.writestr(name, pmd_bytes())
    return str(path)


def test_furniture_is_unpacked_once_in_kind_order_with_its_credit(tmp_path):
    members = [m for kind in zero_ad.FURNITURE.values() for _, m in kind]
    archive = fake_archive(tmp_path / "public.zip", members)
    cache = tmp_path / "cache"
    found = zero_ad.furniture(["stool or bench", "table"], cache=str(cache), archive=archive)
    assert [k for k, _ in found] == ["stool or bench"] * 2 + ["table"] * 4
    assert found[0][1].name == "Bench" and found[2][1].name == "Rectangular table"
    assert {m.license for _, m in found} == {"CC BY-SA 3.0"}
    assert {m.creator for _, m in found} == {"Wildfire Games"}
    first = found[2][1].path
    assert first.endswith("table_rect.pmd") and load_mesh(first)[1].shape == (4, 3)
    stamp = os.stat(first).st_mtime_ns
    again = zero_ad.furniture(["table"], cache=str(cache), archive=archive)
    assert [m.path for _, m in again] == [m.path for _, m in found[2:]]
    assert os.stat(first).st_mtime_ns == stamp  # not written twice
    assert zero_ad.furniture(["sofa"], cache=str(cache), archive=archive) == []


def test_a_missing_package_or_model_says_what_to_do(tmp_path):
    with pytest.raises(InputError, match="apt-get install 0ad-data"):
        zero_ad.furniture(archive=str(tmp_path / "none.zip"), cache=str(tmp_path))
    archive = fake_archive(tmp_path / "public.zip", ["art/meshes/props/bench.dae.cached.pmd"])
    with pytest.raises(InputError, match="has no art/meshes/props/table_rect"):
        zero_ad.furniture(["table"], cache=str(tmp_path / "c"), archive=archive)
    assert not os.path.exists(tmp_path / "c" / "table_rect.pmd")


@pytest.mark.skipif(not os.path.isfile(zero_ad.PUBLIC_ZIP), reason="needs Debian's 0ad-data")
def test_the_installed_game_furniture_is_low_poly_and_upright(tmp_path):
    for _, model in zero_ad.furniture(cache=str(tmp_path)):
        V, F = load_mesh(model.path)
        extent = V.max(0) - V.min(0)
        assert 40 <= len(F) <= 60, model.name  # a top and four legs, or a bench's boards
        assert abs(V[:, 1].min()) < 0.4 and extent[1] < extent[[0, 2]].max(), model.name
        assert np.isfinite(V).all()


@pytest.mark.skipif(not os.path.isfile(zero_ad.PUBLIC_ZIP), reason="needs Debian's 0ad-data")
def test_every_pmd_of_0ad_data_loads(tmp_path):
    """All 4,010 meshes of 0ad-data 0.0.26 (about 6 s): read, finite, faces in range."""
    path = tmp_path / "m.pmd"
    with zipfile.ZipFile(zero_ad.PUBLIC_ZIP) as zf:
        members = [m for m in zf.namelist() if m.endswith(".pmd")]
        assert len(members) >= 4000
        for member in members:
            path.write_bytes(zf.read(member))
            V, F = load_mesh(path)
            assert len(F) and F.max() < len(V) and np.isfinite(V).all(), member


def test_meshes_spreads_a_sample_evenly_and_names_each_by_folder(tmp_path):
    names = [f"art/meshes/{folder}/m{i:02d}.dae.cached.pmd"
             for folder in ("gaia", "props") for i in range(5)] + ["art/other/not_a.pmd.txt"]
    archive = fake_archive(tmp_path / "public.zip", names)
    everything = zero_ad.meshes(cache=str(tmp_path / "all"), archive=archive)
    assert [m.name for m in everything] == [f"m{i:02d}" for i in range(5)] * 2
    assert [m.catalog for m in everything] == ["gaia"] * 5 + ["props"] * 5
    some = zero_ad.meshes(3, cache=str(tmp_path / "all"), archive=archive)
    assert [(m.catalog, m.name) for m in some] == [("gaia", "m00"), ("gaia", "m03"),
                                                   ("props", "m01")]
    assert os.path.isfile(some[2].path) and some[2].path.endswith("props/m01.pmd")
    with pytest.raises(InputError, match="count must be at least 1"):
        zero_ad.meshes(0, archive=archive)
