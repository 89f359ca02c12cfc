"""Solver: flattening of parameters into arrays, the numba kernel and the linearised model."""
