"""Solver: parameters flattened into arrays (layouts), the numba kernels, the driver that runs them, and the linearised model."""
