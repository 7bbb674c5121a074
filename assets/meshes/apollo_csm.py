"""Writes apollo_csm.obj: the outline of assets/apollo_csm.toml (SPS nozzle extension,
service module, command module) revolved about the body y axis as one closed, non-convex
triangle mesh of 96 sections, in metres. Run from this folder: python apollo_csm.py"""

import numpy as np
import trimesh

SECTIONS = 96
PROFILE = [(0.0, -5.5), (1.25, -5.5), (0.5, -3.8), (1.95, -3.8), (1.95, 2.3), (0.42, 5.5),
           (0.0, 5.5)]  # (radius, y) [m], from the nozzle exit to the apex

mesh = trimesh.creation.revolve(np.array(PROFILE), sections=SECTIONS)  # about z
mesh.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0]))  # z -> y
mesh.merge_vertices()
assert mesh.is_watertight and mesh.volume > 0
mesh.export("apollo_csm.obj", digits=6)
