"""Shapes the project makes itself: procedural families for tests, demos and training."""

from cagekit.datasets import synthetic

__all__ = ["synthetic"]
