"""Leaves every layer uses: errors, package data, numba's cache, stop requests."""
