"""One step and the compiled loop: thread stencils and pair lists, the implicit solver, the contact
stage."""
