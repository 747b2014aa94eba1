"""Generalised barycentric coordinates with respect to a cage."""

import warnings

from numba.core.errors import NumbaWarning

# numba tries a system TBB first and warns on stderr when it is too old, then falls back to
# OpenMP or its own work queue; the warning says nothing a cagekit user can act on.
warnings.filterwarnings("ignore", message="The TBB threading layer requires TBB",
                        category=NumbaWarning)

from cagekit.coords.binding import METHODS, CageBinding, GreenBinding, bind  # noqa: E402
from cagekit.coords.green import green_coordinates  # noqa: E402
from cagekit.coords.mvc import mean_value_coordinates  # noqa: E402
from cagekit.coords.textbook import mean_value_coordinates_textbook  # noqa: E402

__all__ = ["bind", "CageBinding", "GreenBinding", "METHODS", "green_coordinates",
           "mean_value_coordinates",
           "mean_value_coordinates_textbook"]
