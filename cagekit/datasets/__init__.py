"""Shapes the project makes itself: procedural families for tests, demos and training."""

from cagekit.datasets import humanoid, synthetic

__all__ = ["humanoid", "synthetic"]
