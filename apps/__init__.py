"""End-to-end applications built from :mod:`cagekit`.

Each application lives in its own module here and is run with ``python -m apps.<name>``.
The first, landmark-driven deformation transfer, is tracked in the project's issues.
"""
