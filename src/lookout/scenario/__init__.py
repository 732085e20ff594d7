"""The scenario layer: the components lookout can compose, declared in code
(:mod:`lookout.scenario.declare`), and what turns a scenario file into them.

This package's ``__init__`` imports nothing, so a component module can import
:mod:`lookout.scenario.declare` without pulling in the rest of the layer.
"""
