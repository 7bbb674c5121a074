"""Compiled leaves: the forces of threads, bending springs and cables, contact laws, geometry
queries."""

from ..common import ordered_sums

ordered_sums.enable()  # before any kernel is compiled
