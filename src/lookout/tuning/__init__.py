"""Tuning gains by gradient through the simulation, inside the papers' conditions
(:mod:`lookout.tuning.tune`, :mod:`lookout.tuning.families`)."""
