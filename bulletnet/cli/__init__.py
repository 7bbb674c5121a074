"""The ``bulletnet`` command line."""
