"""Packaging rules: the core never imports torch; the README's commands are the Makefile's."""

import re
import subprocess
import sys

from builders import REPOSITORY as ROOT


def test_import_cagekit_does_not_import_torch():
    code = ("import sys, cagekit, cagekit.cli, cagekit.io, cagekit.render; "
            "print('torch' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "False"


def test_the_command_line_starts_without_the_heavy_libraries():
    """Starting ``cagekit`` imports click, not numba/libigl/pymeshlab (the commands do), so
    ``--help`` is quick and Ctrl-C during start-up finds cagekit's handler almost at once."""
    code = ("import sys, cagekit, cagekit.cli; "
            "print(sorted(m for m in ('numba', 'igl', 'pymeshlab', 'trimesh', 'scipy') "
            "if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "[]"


def test_every_commands_help_imports_none_of_the_heavy_libraries():
    """``cagekit COMMAND --help`` stays fast: the commands import the library when they run."""
    code = ("import sys\nfrom cagekit.cli import main\n"
            "for command in ('apply', 'eval', 'render', 'fit-cage', 'synth', 'deform', "
            "'train'):\n"
            "    main([command, '--help'], standalone_mode=False)\n"
            "heavy = ('numba', 'igl', 'pymeshlab', 'trimesh', 'scipy', 'torch', 'matplotlib', "
            "'tqdm')\n"
            "print(sorted(m for m in heavy if m in sys.modules))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip().splitlines()[-1] == "[]"


def test_the_command_lines_choices_are_the_librarys():
    import cagekit
    from cagekit import fitting
    from cagekit.cli.common import (
        COORDINATE_METHODS,
        DEFORM_COORDINATE_METHODS,
        FIT_METHODS,
        MAX_FACES,
        MIN_FACES,
        TEMPLATE_FACES,
    )
    from cagekit.coords.binding import METHODS
    from cagekit.deformation import COORDS
    from cagekit.fitting import METHODS as FITTING
    from cagekit.fitting import TEMPLATE_FACES as FITTING_TEMPLATE_FACES

    assert COORDINATE_METHODS == METHODS and FIT_METHODS == FITTING
    assert DEFORM_COORDINATE_METHODS == COORDS
    assert TEMPLATE_FACES == FITTING_TEMPLATE_FACES
    assert (MIN_FACES, MAX_FACES) == (fitting.MIN_FACES, fitting.MAX_FACES)
    assert sorted(dir(cagekit)) == sorted(cagekit.__all__)
    for name in cagekit.__all__:  # every lazily exported name resolves
        assert getattr(cagekit, name) is not None


def test_core_sources_never_mention_a_torch_import():
    pattern = re.compile(r"^\s*(import torch|from torch)", re.MULTILINE)
    offenders = [p for p in (ROOT / "cagekit").rglob("*.py") if pattern.search(p.read_text())]
    assert offenders == []


def test_readme_opens_with_the_two_make_commands():
    text = (ROOT / "README.md").read_text()
    block = text.split("```")[1]
    commands = [line.split("#")[0].strip() for line in block.strip().splitlines()]
    assert commands == ["make demo", "make test"]
    makefile = (ROOT / "Makefile").read_text()
    assert re.search(r"^demo:", makefile, re.MULTILINE)
    assert re.search(r"^test:", makefile, re.MULTILINE)
    ci = (ROOT / ".ci" / "run").read_text().splitlines()
    assert "make test" in ci and "make test-emulated" in ci  # native, then another CPU
    assert re.search(r"^test-emulated:", makefile, re.MULTILINE)
