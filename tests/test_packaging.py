"""The wheel: the packages ``cagekit`` and ``cagekit_learn``, each with its
``py.typed`` (PEP 561), the shipped models, and nothing else at the top (no ``apps``, a
folder name any other project may use), built from a copy of the sources with this
environment's setuptools (no network)."""

import shutil
import subprocess
import sys
import zipfile

from builders import REPOSITORY

#: what setup.cfg and pyproject.toml need to build the wheel
SOURCES = ("setup.cfg", "pyproject.toml", "README.md", "cagekit", "cagekit_learn", "apps")


def test_the_wheel_holds_cagekit_and_cagekit_learn_only(tmp_path):
    src = tmp_path / "src"
    src.mkdir()
    for name in SOURCES:
        path = REPOSITORY / name
        if path.is_dir():
            shutil.copytree(path, src / name, ignore=shutil.ignore_patterns("__pycache__"))
        else:
            shutil.copy(path, src / name)
    done = subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps",
                           "--no-build-isolation", "-w", tmp_path / "dist", src],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    (wheel,) = (tmp_path / "dist").glob("cagekit-*.whl")
    names = zipfile.ZipFile(wheel).namelist()
    top = {name.split("/")[0] for name in names if not name.split("/")[0].endswith(".dist-info")}
    assert top == {"cagekit", "cagekit_learn"}
    assert "cagekit/transfer/character.py" in names  # the transfer is the core's
    assert {"cagekit/py.typed", "cagekit_learn/py.typed"} <= set(names)  # PEP 561
    shipped = {n for n in names if n.startswith("cagekit_learn/models/")}
    assert {"cagekit_learn/models/chairs.pt", "cagekit_learn/models/chairs.json"} <= shipped
