"""Compiled leaves: the forces of threads, bending springs and cables, contact laws, geometry
queries."""
