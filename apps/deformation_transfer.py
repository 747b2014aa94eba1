"""The deformation-transfer application: ``python -m apps.deformation_transfer ARGS`` is
``cagekit transfer ARGS`` (the same arguments, options and exit statuses).

The algorithm is in the core, :mod:`cagekit.transfer` (the learned template cage in
:mod:`cagekit_learn.transfer`); this script only runs the command from the repository.
"""

import sys

from cagekit.cli import main

if __name__ == "__main__":
    main(["transfer", *sys.argv[1:]], prog_name="python -m apps.deformation_transfer")
