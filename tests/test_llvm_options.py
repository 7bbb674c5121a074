"""The LLVM options the kernels compile with (bulletnet.common.llvm_options): a registered
function's vector loops are interleaved, nothing else's, and no result changes."""

from __future__ import annotations

import numba as nb
import numpy as np

from bulletnet.common import llvm_options


def _kernel():
    """A fresh compiled function (its own Python function, so registered or not on its own):
    a thread stencil's chain in miniature, a square root and a division per element."""

    def lengths(x, out):
        for i in range(out.shape[0]):
            out[i] = 1.0 / np.sqrt(x[i] * x[i] + 1.0)

    return nb.njit(error_model="numpy")(lengths)


def _square_roots(kernel) -> int:
    """Packed square roots in the assembly of a compiled function (SSE2 or AVX, any width)."""
    return kernel.inspect_asm(kernel.signatures[0]).count("sqrtpd")


def test_registered_function_is_interleaved_and_computes_the_same_bits():
    # Reference: LLVM's definition of the option: interleaving unrolls the vector loop, so
    # the registered function holds INTERLEAVE times the packed square roots of the plain
    # one, and it does the same operations on the same values, so the same bits.
    plain, interleaved = _kernel(), llvm_options.interleave(_kernel())
    x = np.random.default_rng(1).normal(size=1003)
    a, b = np.empty_like(x), np.empty_like(x)
    plain(x, a)
    interleaved(x, b)
    assert a.tobytes() == b.tobytes()
    assert _square_roots(plain) >= 1
    assert _square_roots(interleaved) == llvm_options.INTERLEAVE * _square_roots(plain)


def test_a_function_first_compiled_inside_a_registered_one_is_not_interleaved():
    # Reference: the module's contract: a callee compiled (and cached for other callers)
    # while a registered function compiles gets LLVM's own choice, as when compiled alone,
    # and so does whatever compiles after the registered function.
    callee, reference, after = _kernel(), _kernel(), _kernel()
    registered_after = llvm_options.interleave(_kernel())

    @llvm_options.interleave
    @nb.njit
    def caller(x, out):
        callee(x, out)

    x = np.linspace(0.0, 1.0, 257)
    out = np.empty_like(x)
    caller(x, out)
    reference(x, out)
    after(x, out)
    registered_after(x, out)
    assert _square_roots(callee) == _square_roots(reference)
    assert _square_roots(after) == _square_roots(reference)
    assert _square_roots(registered_after) == llvm_options.INTERLEAVE * _square_roots(reference)
