"""The ``kinder`` command line: one module per command group over :mod:`.common` (which imports
none of them), mounted by the root app in :mod:`.kinder`."""

from kinder_bench.cli.kinder import app, main

__all__ = ["app", "main"]
