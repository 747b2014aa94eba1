"""Every public function and method of ``cagekit`` and ``cagekit_learn`` is annotated.

Public: named in its module's ``__all__`` (every name without a leading underscore when
the module has none), and the public methods (and ``__init__``) of public classes;
``typing.overload`` stubs are left out (the implementation is counted). ``make lint`` runs
mypy over both packages; this test keeps the annotations complete, which mypy does not
ask for. ``python tests/test_typing.py`` prints the counts.
"""

import ast
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("cagekit", "cagekit_learn")


def _public_names(tree) -> set[str] | None:
    """The module's ``__all__`` when it is a literal (None otherwise: every name without
    an underscore is public, and ``cagekit/__init__``'s lazy names are checked where they
    are defined)."""
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(
                isinstance(t, ast.Name) and t.id == "__all__" for t in node.targets):
            try:
                return set(ast.literal_eval(node.value))
            except ValueError:
                return None
    return None


def _is_public(name: str, names: set[str] | None) -> bool:
    return name in names if names is not None else not name.startswith("_")


def _overload(fn) -> bool:
    return any(isinstance(d, ast.Name) and d.id == "overload" for d in fn.decorator_list)


def public_functions(package: str):
    """(where, function node) of every public function and method of ``package``."""
    for path in sorted((ROOT / package).rglob("*.py")):
        tree = ast.parse(path.read_text())
        names = _public_names(tree)
        where = path.relative_to(ROOT)
        for node in tree.body:
            if (isinstance(node, ast.FunctionDef) and _is_public(node.name, names)
                    and not _overload(node)):
                yield f"{where}:{node.lineno} {node.name}", node
            elif isinstance(node, ast.ClassDef) and _is_public(node.name, names):
                for fn in node.body:
                    if (isinstance(fn, ast.FunctionDef) and not _overload(fn)
                            and (not fn.name.startswith("_") or fn.name == "__init__")):
                        yield f"{where}:{fn.lineno} {node.name}.{fn.name}", fn


def missing_annotations(fn) -> list[str]:
    """The parameters (and ``return``) of a function without an annotation."""
    args = fn.args.posonlyargs + fn.args.args + fn.args.kwonlyargs
    args += [a for a in (fn.args.vararg, fn.args.kwarg) if a is not None]
    missing = [a.arg for a in args if a.annotation is None and a.arg not in ("self", "cls")]
    if fn.returns is None and fn.name != "__init__":
        missing.append("return")
    return missing


def counts(package: str) -> tuple[int, int, int, int]:
    """(functions, fully annotated, annotations present, annotations possible)."""
    functions = full = present = possible = 0
    for _, fn in public_functions(package):
        args = fn.args.posonlyargs + fn.args.args + fn.args.kwonlyargs
        args += [a for a in (fn.args.vararg, fn.args.kwarg) if a is not None]
        slots = len([a for a in args if a.arg not in ("self", "cls")]) + 1
        missing = len(missing_annotations(fn))
        functions += 1
        full += missing == 0
        present += slots - missing
        possible += slots
    return functions, full, present, possible


@pytest.mark.parametrize("package", PACKAGES)
def test_every_public_function_is_annotated(package):
    bare = [f"{where} ({', '.join(missing)})" for where, fn in public_functions(package)
            if (missing := missing_annotations(fn))]
    assert not bare, "unannotated:\n" + "\n".join(bare)


def test_the_check_sees_a_missing_annotation():
    fn = ast.parse("def f(a: int, b, *c, d=1) -> int: ...").body[0]
    assert missing_annotations(fn) == ["b", "d", "c"]
    method = ast.parse("class C:\n    def __init__(self, x): ...").body[0].body[0]
    assert missing_annotations(method) == ["x"]


if __name__ == "__main__":
    for name in PACKAGES if len(sys.argv) < 2 else sys.argv[1:]:
        n, full, present, possible = counts(name)
        print(f"{name}: {n} public functions and methods, {full} fully annotated; "
              f"{present} of {possible} parameters and returns annotated "
              f"({100 * present / possible:.0f}%)")
