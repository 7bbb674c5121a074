"""One step and the compiled loop: thread stencils and pair lists, the implicit solver, the contact
stage."""

from ..common import ordered_sums

ordered_sums.enable()  # before any kernel is compiled
