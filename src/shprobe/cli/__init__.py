"""The ``shprobe`` command-line tool: a thin layer over the library.

One module per command group; each defines ``register(group)``. Heavy imports stay inside the
command functions so that ``shprobe --help`` is fast.
"""
