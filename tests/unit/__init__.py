"""Unit tests: parameters, excitation, signal, results, metrics, CLI, cache and sweeps."""
