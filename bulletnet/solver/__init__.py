"""One step and the compiled loop: thread stencils and pair lists, the implicit solver, the contact
stage."""

from ..common import llvm_options

llvm_options.enable()  # before any kernel is compiled
