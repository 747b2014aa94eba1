"""cagekit: detail-preserving 3D shape deformation with cages."""

from cagekit.errors import CageError, InputError, LandmarkFileError, MeshFileError

__version__ = "0.1.0"

__all__ = ["InputError", "MeshFileError", "LandmarkFileError", "CageError", "__version__"]
