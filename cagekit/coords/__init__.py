"""Generalised barycentric coordinates with respect to a cage."""

from cagekit.coords.binding import METHODS, CageBinding, bind
from cagekit.coords.mvc import mean_value_coordinates
from cagekit.coords.textbook import mean_value_coordinates_textbook

__all__ = ["bind", "CageBinding", "METHODS", "mean_value_coordinates",
           "mean_value_coordinates_textbook"]
