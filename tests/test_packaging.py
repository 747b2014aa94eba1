"""Packaging rules: the core never imports torch; the README's commands are the Makefile's."""

import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_import_cagekit_does_not_import_torch():
    code = ("import sys, cagekit, cagekit.cli, cagekit.io, cagekit.render; "
            "print('torch' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "False"


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
    assert (ROOT / ".ci" / "run").read_text().strip().endswith("make test")
