"""The scenario layer: the registry of the kinds lookout can compose (each declared next
to its class with :mod:`lookout.declare`), and what turns a scenario file into them.

This package's ``__init__`` imports nothing, so importing one of its modules loads
only what that module imports.
"""
