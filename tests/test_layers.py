"""The layers point one way (docs/architecture.md, section 1): core < cagekit_learn < apps,
the command line using core and learn; the core and its command line never import the
applications (which may run the command line: ``python -m apps.deformation_transfer``). The
Blender add-on ships without ``apps`` (its extension holds the wheel of cagekit), so it
imports none of it.

Read from the source (ast), so a lazy import inside a function counts as well. No module
imports from a layer above its own, nor another module's private (``_name``) names. The
applications may use the command line's shared rules, :mod:`cagekit.cli.common`, which
imports only the core.
"""

import importlib
import inspect

import pytest
from architecture import imports
from architecture import module_files as modules
from builders import REPOSITORY as ROOT

LAYERS = {"core": 0, "learn": 1, "cli": 2, "apps": 3}


def layer(module: str) -> str | None:
    if module == "cagekit.cli.common" or module.startswith("cagekit.cli.common."):
        return "core"  # shared by the commands and the applications; imports the core only
    if module == "cagekit.cli" or module.startswith("cagekit.cli."):
        return "cli"
    for prefix, name in (("cagekit_learn", "learn"), ("apps", "apps"), ("cagekit", "core")):
        if module == prefix or module.startswith(prefix + "."):
            return name
    return None


def violations(files=None):
    """One line per bad import in ``files`` ((module name, path) pairs; default: all)."""
    found = []
    for name, path in modules() if files is None else files:
        own = layer(name)
        for line, module, names in imports(name, path):
            where = f"{path.name}:{line}" if ROOT not in path.parents else \
                f"{path.relative_to(ROOT)}:{line}"
            other = layer(module)
            if other is not None and LAYERS[other] > LAYERS[own]:
                found.append(f"{where}: {name} ({own}) imports {module} ({other})")
            for imported in names:
                if imported.startswith("_") and not imported.startswith("__") \
                        and module != name:
                    found.append(f"{where}: {name} imports the private {module}.{imported}")
    return found


def test_no_module_imports_a_layer_above_it_or_a_private_name():
    assert violations() == []


@pytest.mark.parametrize("source, expected", [
    ("from cagekit.cli import main\n", "imports cagekit.cli (cli)"),
    ("from cagekit.deformation import _minimise\n", "private cagekit.deformation._minimise"),
    ("def f():\n    import cagekit_learn.train\n", "imports cagekit_learn.train (learn)"),
    ("def f():\n    from apps import humanoid_data\n", "imports apps (apps)"),
])
def test_the_check_sees_a_bad_import(tmp_path, source, expected):
    probe = tmp_path / "probe.py"
    probe.write_text(source)
    assert any(expected in v for v in violations([("cagekit.probe", probe)]))


def test_the_blender_add_on_imports_nothing_from_apps():
    addon = ROOT / "apps" / "blender" / "cagekit_blender"
    found = [f"{path.name}:{line}: {module}" for path in sorted(addon.glob("*.py"))
             for line, module, _ in imports(f"cagekit_blender.{path.stem}", path)
             if module == "apps" or module.startswith("apps.")]
    assert found == []


def test_the_architecture_document_maps_every_module_as_the_code_is():
    """docs/architecture.md's module map is the code's: each module, its docstring's first
    sentence and what it imports (regenerate with ``make architecture``)."""
    import architecture

    assert architecture.documented() == architecture.block(), \
        "docs/architecture.md's module map is out of date: run make architecture"


def test_a_class_is_listed_by_its_own_module_or_a_package_only():
    """A plain module's ``__all__`` names no class defined in another module.

    autodoc documents what ``__all__`` lists, a re-exported class under its canonical
    name as well: two pages that re-export one class describe it twice, and the API
    reference's clean build (warnings are errors) fails or not with the order in which
    Sphinx reads the pages. A package (``__init__``) re-exports; a module defines.
    """
    found = []
    for name, path in modules():
        if name.startswith("apps") or path.name in ("__init__.py", "__main__.py"):
            continue
        module = importlib.import_module(name)
        for member in getattr(module, "__all__", ()):
            value = getattr(module, member)
            if inspect.isclass(value) and value.__module__ != name:
                found.append(f"{name}.{member} (from {value.__module__})")
    assert found == []
