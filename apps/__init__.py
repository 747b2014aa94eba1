"""Applications built from :mod:`cagekit` and run from the repository, never installed.

Each lives in its own module and runs with ``python -m apps.<name>``: the deformation
transfer (``apps.deformation_transfer``, the same as ``cagekit transfer``), the humanoid
data set (``apps.humanoid_data``), and the Blender add-on in ``apps/blender``.
"""
