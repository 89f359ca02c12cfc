"""The package version, in a module of its own: a layer that imported the package root for
it would, by the layer contract's reading, import everything the root re-exports."""

__version__ = "0.1.0"
