"""Tests of cagekit.errors: one-line input errors naming their file, the warning classes."""

import pathlib
import warnings

import pytest

import cagekit
from cagekit import errors
from cagekit.errors import (
    CageError,
    CagekitWarning,
    InputError,
    LandmarkFileError,
    MeshFileError,
    MeshFileWarning,
    OutsideCageWarning,
)


def test_input_error_without_a_path_is_the_message():
    error = InputError("the array holds NaN")
    assert str(error) == "the array holds NaN"
    assert error.path is None and error.problem == "the array holds NaN"
    assert isinstance(error, ValueError)


def test_input_error_with_a_path_prefixes_it():
    error = InputError("is empty", path=pathlib.Path("meshes") / "a.obj")
    assert str(error) == "meshes/a.obj: is empty"
    assert error.path == "meshes/a.obj" and isinstance(error.path, str)
    assert error.problem == "is empty"
    assert str(InputError("is empty", "b.ply")) == "b.ply: is empty"


@pytest.mark.parametrize("cls", [MeshFileError, LandmarkFileError, CageError])
def test_file_and_cage_errors_are_input_errors(cls):
    assert issubclass(cls, InputError) and issubclass(cls, ValueError)
    with pytest.raises(InputError, match=r"^c\.obj: not closed$") as info:
        raise cls("not closed", path="c.obj")
    assert type(info.value) is cls and info.value.path == "c.obj"
    assert info.value.problem == "not closed"


@pytest.mark.parametrize("cls", [MeshFileWarning, OutsideCageWarning])
def test_warnings_are_cagekit_warnings(cls):
    assert issubclass(cls, CagekitWarning) and issubclass(CagekitWarning, UserWarning)
    assert not issubclass(cls, InputError)
    with pytest.warns(CagekitWarning, match="dropped 2 faces"):
        warnings.warn("dropped 2 faces", cls, stacklevel=1)


def test_every_public_name_is_exported_by_cagekit():
    for name in errors.__all__:
        assert getattr(cagekit, name) is getattr(errors, name)
