"""``python -m cagekit.cli ...``, and ``torchrun -m cagekit.cli train ...`` for training."""

from cagekit.cli import main

main(prog_name="cagekit")
