"""Real assets: the sweethome3d-furniture catalogs (issue 14) and their loader.

The catalog tests need Debian's ``sweethome3d-furniture`` (``.ci/run`` installs it when run
as root); without it they are skipped. The parser and unpacking tests use a small archive
made here.
"""

import os
import warnings
import zipfile

import numpy as np
import pytest

import cagekit
from cagekit import io
from cagekit.datasets import sweethome3d
from cagekit.errors import InputError, MeshFileWarning

INSTALLED = os.path.isfile(os.path.join(sweethome3d.FURNITURE_DIR, "KatorLegaz.sh3f"))
needs_package = pytest.mark.skipif(not INSTALLED, reason="needs Debian's sweethome3d-furniture")

PROPERTIES = (
    "# a catalog\nid=Test\nlicense=Creative Commons Attribution 3.0 license\n"
    "name#1=Caf\\u00e9 chair\ncategory#1=Kitchen\nmodel#1=/test/chair/chair.obj\n"
    "creator#1=Someone\n"
    "name#2=Long \\\n    name\nmodel#2=/test/table/table.obj\nlicense#2=Public domain\n"
)
TETRA = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 2 3 4\nf 1 4 3\nf 1 2\n"


def _archive(folder, name="Test", extra=None):
    path = folder / f"{name}.sh3f"
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr("PluginFurnitureCatalog.properties", PROPERTIES.encode("latin-1"))
        zf.writestr("test/chair/chair.obj", TETRA)
        zf.writestr("test/table/table.obj", TETRA)
        for member, text in (extra or {}).items():
            zf.writestr(member, text)
    return path


def test_read_properties_unescapes_and_joins_lines():
    props = sweethome3d.read_properties(PROPERTIES)
    assert props["name#1"] == "Café chair" and props["name#2"] == "Long name"
    assert props["model#1"] == "/test/chair/chair.obj" and "id" in props


def test_models_of_an_archive_are_unpacked_once_with_names_and_credits(tmp_path):
    _archive(tmp_path)
    cache = tmp_path / "cache"
    models = sweethome3d.models(["Test"], cache=str(cache), furniture_dir=str(tmp_path))
    assert [m.name for m in models] == ["Café chair", "Long name"]
    assert models[0].credit == "Café chair by Someone (Creative Commons Attribution 3.0 license)"
    assert models[1].license == "Public domain" and models[1].creator == ""
    assert all(os.path.isfile(m.path) for m in models)
    stamp = os.path.getmtime(cache / "Test" / ".unpacked")
    sweethome3d.models(["Test"], cache=str(cache), furniture_dir=str(tmp_path))
    assert os.path.getmtime(cache / "Test" / ".unpacked") == stamp  # not unpacked again
    with pytest.warns(MeshFileWarning, match="dropped 1 face"):
        V, F = io.load_mesh(models[0].path)
    assert V.shape == (4, 3) and F.shape == (4, 3)


def test_missing_catalogs_and_unsafe_archives_are_clear_errors(tmp_path):
    with pytest.raises(InputError, match="apt-get install sweethome3d-furniture"):
        sweethome3d.models(["Test"], cache=str(tmp_path / "c"), furniture_dir=str(tmp_path))
    _archive(tmp_path, "Evil", extra={"../../escape.txt": "x"})
    with pytest.raises(InputError, match="unsafe path"):
        sweethome3d.models(["Evil"], cache=str(tmp_path / "c"), furniture_dir=str(tmp_path))
    assert not (tmp_path / "escape.txt").exists()


# ------------------------------------------------------------------- the real catalogs


@pytest.fixture(scope="module")
def catalog(tmp_path_factory):
    return sweethome3d.models(cache=str(tmp_path_factory.mktemp("sh3d")))


def _count_v_lines(path):
    with open(path, errors="replace") as fh:
        return sum(1 for line in fh if line.startswith("v "))


@needs_package
def test_the_package_has_its_820_models(catalog):
    assert len(catalog) == 820
    assert {m.catalog for m in catalog} == set(sweethome3d.CATALOGS)


@needs_package
def test_the_seats_split_holds_out_one_in_four_of_each_kind_and_never_scopia(catalog):
    furniture = [m for m in catalog if m.catalog in sweethome3d.FURNITURE_CATALOGS]
    train, held_out = sweethome3d.held_out_split(furniture)
    assert (len(train), len(held_out)) == (44, 15)
    assert not {m.path for _, m in train} & {m.path for _, m in held_out}
    for kind in sweethome3d.SEAT_KINDS:
        of_kind = [m for m in furniture if sweethome3d.furniture_kind(m.name) == kind]
        assert [m for k, m in held_out if k == kind] == of_kind[1::4]
    assert {m.catalog for _, m in train + held_out} <= set(sweethome3d.FURNITURE_CATALOGS)


@needs_package
@pytest.mark.parametrize("stem", ["male-01-suit", "window-08", "fridge", "tv", "desk"])
def test_real_files_with_line_elements_load_with_one_warning(catalog, stem):
    """These have two-vertex ``f`` lines (the audit's male-01-suit was refused for one)."""
    model = next(m for m in catalog if os.path.basename(m.path) == f"{stem}.obj")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        V, F = io.load_mesh(model.path)
    dropped = [w for w in caught if issubclass(w.category, MeshFileWarning)]
    assert len(dropped) == 1 and "fewer than 3 vertices" in str(dropped[0].message)
    assert len(V) == _count_v_lines(model.path)  # every vertex kept, in file order
    assert len(F) > 0


@needs_package
@pytest.mark.parametrize("stem", ["fridge", "park-light", "coffee_table"])
def test_real_models_get_a_guaranteed_cage(catalog, stem):
    model = next(m for m in catalog if os.path.basename(m.path) == f"{stem}.obj")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MeshFileWarning)
        V, F = io.load_mesh(model.path)
    cv, cf, report = cagekit.fit_cage(V, F, faces=200)
    assert report.ok and len(cf) <= 200
    assert cagekit.cage_report(V, F, cv, cf, faces=200, seed=1).ok
    assert np.isfinite(cv).all()


@needs_package
@pytest.mark.slow
def test_every_model_of_the_package_loads(catalog):
    failures = []
    for model in catalog:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", MeshFileWarning)
                V, F = io.load_mesh(model.path)
            assert len(F) and np.isfinite(V).all()
        except InputError as exc:
            failures.append(str(exc))
    assert failures == []
