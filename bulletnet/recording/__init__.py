"""The HDF5 recording: its writer and its reader."""
