"""Every docstring example runs (doctest), in the core, the learned mode and the apps."""

import doctest
import importlib

import pytest
from builders import REPOSITORY as ROOT


def module_names():
    for package in ("cagekit", "cagekit_learn", "apps"):
        for path in sorted((ROOT / package).rglob("*.py")):
            parts = path.relative_to(ROOT).with_suffix("").parts
            if parts[-1] == "__main__":
                continue
            if parts[:2] == ("apps", "blender") and parts[2] != "cagekit_blender":
                continue  # scripts run with Blender's bpy (build, render), not modules
            yield ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


@pytest.mark.parametrize("name", list(module_names()))
def test_docstring_examples(name, tmp_path, monkeypatch):
    if name.startswith(("cagekit_learn", "apps.deformation_transfer")):
        pytest.importorskip("torch")
    if name.startswith("apps.blender"):
        pytest.importorskip("bpy")  # the add-on (make test-blender)
    monkeypatch.chdir(tmp_path)  # examples that write files write them here
    module = importlib.import_module(name)
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE,
                             report=True, verbose=False)
    assert result.failed == 0, f"{result.failed} failing example(s) in {name} (see stdout)"
