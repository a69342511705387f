"""Simulator of synthetic ALOS-PRISM 1B2 triplets with known truth.

``geometry`` holds the rigorous pushbroom geometry (numpy only); ``terrain``, ``texture``
and ``render`` make the pictures; ``writer`` the files; :func:`simulate` ties them together.
"""
from prismstation.sim.run import simulate

__all__ = ["simulate"]
