"""The ``cagekit`` command line (click): one module per command, shared rules in common.

Each command parses its options, loads its inputs, calls the library and reports; the rules
every command follows (errors, outputs, JSON, progress) are in :mod:`cagekit.cli.common`.
Library modules are imported inside the commands, so ``cagekit --help`` stays fast.
"""

from __future__ import annotations

import click

from cagekit import __version__
from cagekit.cli import (
    amplify,
    apply,
    deform,
    evaluate,
    fit_cage,
    render,
    synth,
    train,
    transfer,
)
from cagekit.cli.common import Group

__all__ = ["main"]


@click.group(cls=Group, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, "--version", prog_name="cagekit",
                      message="%(prog)s %(version)s")
@click.option("--debug", is_flag=True, help="Show full tracebacks on errors (any command).")
def main(debug: bool) -> None:
    """Detail-preserving shape deformation with cages (after Neural Cages, CVPR 2020).

    Bad input exits with status 2 and one line on stderr naming the file; --debug shows
    the traceback.
    """


for _module, _name in ((apply, "apply"), (evaluate, "eval_"), (render, "render"),
                       (fit_cage, "fit_cage"), (synth, "synth"), (deform, "deform"),
                       (train, "train"), (transfer, "transfer"), (amplify, "amplify")):
    main.add_command(getattr(_module, _name))
