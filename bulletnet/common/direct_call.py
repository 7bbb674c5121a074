"""A compiled kernel called without numba's dispatch at every call.

A call of a numba dispatcher types each of its arguments and looks up the compiled version
for those types, every time. For the fast engine's loop, whose 17 arguments hold about 150
arrays in named tuples, that is 11 of the 13.6 us of a call (2.4 us left: the arguments'
unboxing), and a capture returns to Python every 4 steps for the debris' dynamics: 2.8 us a
step of its 140. :class:`DirectCall` looks the compiled version up once for the arguments'
kinds and calls it directly until they change.
"""

from __future__ import annotations

from collections.abc import Callable

import numba as nb
import numpy as np


def signature(args: tuple) -> tuple:
    """numba's argument types of a call with ``args``, as a dispatcher types a call."""
    return tuple(nb.typeof(a) for a in args)


class _Same:
    """A value compared by identity (a named tuple of arrays: made once, never changed)."""

    __slots__ = ("value",)

    def __init__(self, value):
        self.value = value

    def __eq__(self, other) -> bool:
        return isinstance(other, _Same) and other.value is self.value

    __hash__ = None


def _kind(value) -> object:
    """What sets ``value``'s numba type, cheaply: an array's dtype, dimensions and flags, a
    tuple itself (by identity), a scalar's or None's Python type."""
    if isinstance(value, np.ndarray):
        f = value.flags
        return value.dtype, value.ndim, f.c_contiguous, f.f_contiguous, f.writeable, f.aligned
    if isinstance(value, tuple):
        return _Same(value)
    return type(value)


class DirectCall:
    """``dispatcher``'s compiled version for the arguments of :meth:`resolve`, compiled (or
    loaded from the cache) there if need be, called directly: the caller calls :meth:`resolve`
    with the arguments whenever one of their kinds may have changed (a named tuple replaced
    by another, an array's dtype, a scalar's type), and then calls the result with arguments
    of the same kinds only."""

    def __init__(self, dispatcher):
        self.dispatcher = dispatcher
        self._kinds: tuple = ()
        self._entry: Callable | None = None

    def resolve(self, args: tuple) -> Callable:
        """The compiled version for ``args`` (looked up again only if their kinds changed)."""
        kinds = tuple(_kind(a) for a in args)
        if self._entry is None or kinds != self._kinds:
            self._entry = self.dispatcher.compile(signature(args))
            self._kinds = kinds
        return self._entry
