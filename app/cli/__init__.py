"""The ``chakamo`` command line: the parser and dispatch in :mod:`app.cli.main`, command groups beside it."""

from app.cli.main import main

__all__ = ["main"]
