"""Type stubs for the compiled core. The public API is the `inkwarp` package."""

__version__: str
