"""The ``chakamo`` command line: the parser and dispatch in :mod:`app.cli.main`, command groups beside it."""

from app.cli.main import console, main

__all__ = ["console", "main"]
