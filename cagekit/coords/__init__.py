"""Generalised barycentric coordinates with respect to a cage."""

from cagekit._numba_setup import configure as _configure_numba

_configure_numba()  # before any kernel is defined (numba's cache folder, threading layer)

from cagekit.coords.binding import METHODS, CageBinding, GreenBinding, bind  # noqa: E402
from cagekit.coords.green import green_coordinates  # noqa: E402
from cagekit.coords.mvc import mean_value_coordinates  # noqa: E402
from cagekit.coords.textbook import mean_value_coordinates_textbook  # noqa: E402

__all__ = ["bind", "CageBinding", "GreenBinding", "METHODS", "green_coordinates",
           "mean_value_coordinates",
           "mean_value_coordinates_textbook"]
