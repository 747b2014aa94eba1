"""Every docstring example runs (doctest), in the core, the learned mode and the apps.

The examples are checked by :class:`number_checker.NumberChecker` (numbers to the precision
they are written with, ``-0.0`` equal to ``0.0``), so that they pass on every CPU; an
example whose expected output holds a float written to the last bit is refused.
"""

import ast
import doctest
import importlib

import number_checker
import pytest
from builders import REPOSITORY as ROOT
from number_checker import MAX_DIGITS, NumberChecker, exact_floats

OPTIONS = doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE


def module_names():
    for package in ("cagekit", "cagekit_learn", "apps"):
        for path in sorted((ROOT / package).rglob("*.py")):
            parts = path.relative_to(ROOT).with_suffix("").parts
            if parts[-1] == "__main__":
                continue
            if parts[:2] == ("apps", "blender") and parts[2] != "cagekit_blender":
                continue  # scripts run with Blender's bpy (build, render), not modules
            yield ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def import_module(name):
    """The module ``name``, or a skip when it needs an optional library not installed."""
    if name.startswith("cagekit_learn"):
        pytest.importorskip("torch")
    if name.startswith("apps.blender"):
        pytest.importorskip("bpy")  # the add-on (make test-blender)
    return importlib.import_module(name)


def run_examples(module):
    """Run every docstring example of ``module`` with the suite's checker; the failure count."""
    runner = doctest.DocTestRunner(checker=NumberChecker(), optionflags=OPTIONS, verbose=False)
    for test in doctest.DocTestFinder().find(module):
        runner.run(test)
    return runner.summarize(verbose=False).failed


@pytest.mark.parametrize("name", list(module_names()))
def test_docstring_examples(name, tmp_path, monkeypatch):
    module = import_module(name)
    monkeypatch.chdir(tmp_path)  # examples that write files write them here
    failed = run_examples(module)
    assert failed == 0, f"{failed} failing example(s) in {name} (see stdout)"


def docstrings(path):
    """(name, line, docstring) of the module, each class and each function of a source file."""
    tree = ast.parse(path.read_text(), filename=str(path))
    for node in [tree, *ast.walk(tree)]:
        if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef):
            text = ast.get_docstring(node, clean=False)
            if text:
                yield getattr(node, "name", path.stem), getattr(node, "lineno", 1), text


SOURCES = sorted(path for package in ("cagekit", "cagekit_learn", "apps")
                 for path in (ROOT / package).rglob("*.py"))


@pytest.mark.parametrize("path", SOURCES, ids=lambda p: str(p.relative_to(ROOT)))
def test_no_example_expects_a_float_to_the_last_bit(path):
    # read from the source, not imported: the examples of modules that need torch or bpy too
    exact = [f"{name} (line {line}): {floats}"
             for name, line, text in docstrings(path)
             for example in doctest.DocTestParser().get_examples(text)
             if (floats := exact_floats(example.want))]
    assert not exact, (f"{path.name}: expected floats written with more than {MAX_DIGITS} "
                       f"significant digits (round them, or print fewer digits): {exact}")


def test_the_checker_runs_its_own_examples():
    assert run_examples(number_checker) == 0


CHECK = NumberChecker().check_output


@pytest.mark.parametrize("want, got", [
    ("(2.0, [1.0, 1.0, 1.0])\n", "(2.0, [1.0, 1.0000000000000004, 1.0000000000000002])\n"),
    ("[[[1.0, 0.0, 0.0]]]\n", "[[[1.0, 0.0, -0.0]]]\n"),
    ("array([1., 2., 0.])\n", "array([ 1.,  2., -0.])\n"),  # numpy's room for the sign
    ("0.33...\n", "0.32999999999\n"),
    ("1e-05\n", "1.0000000000000001e-05\n"),
    ("shift 0 mm\n", "shift -0 mm\n"),
    ("max error 0.0\n", "max error 3.3e-17\n"),
])
def test_numbers_match_to_the_precision_written(want, got):
    assert CHECK(want, got, OPTIONS)


@pytest.mark.parametrize("want, got", [
    ("(2.0, [1.0, 1.0, 1.0])\n", "(2.0, [1.0, 1.1, 1.0])\n"),  # a real difference
    ("0.33\n", "0.336\n"),
    ("7 vertices\n", "8 vertices\n"),  # integers are exact
    ("[1.0, 2.0]\n", "[1.0, 2.0, 3.0]\n"),  # so is everything but the numbers
    ("1e-05\n", "2e-05\n"),
    ("-1.0\n", "1.0\n"),  # only a zero's sign is free
    ("v1.2\n", "v1.3\n"),  # a version is text
])
def test_numbers_that_differ_do_not_match(want, got):
    assert not CHECK(want, got, OPTIONS)


@pytest.mark.parametrize("want, exact", [
    ("0.3333333333333333", ["0.3333333333333333"]),
    ("(1.4142135623730951, 2.0)", ["1.4142135623730951"]),
    ("1.0000000000000004e-05", ["1.0000000000000004e-05"]),
    ("array([0.33333333, 1.        ])", []),  # numpy's 8 digits
    ("0.000012345678", []),  # leading zeros are not significant
    ("123456789012345", []),  # an integer is exact by nature
])
def test_floats_written_to_the_last_bit_are_found(want, exact):
    assert exact_floats(want) == exact
