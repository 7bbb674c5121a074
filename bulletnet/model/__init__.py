"""A scene and what it builds: the scenario file, the net's topology and model, its state, the
debris, meshes, materials."""
