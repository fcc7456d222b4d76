"""ChakaMo's estimators: pure numerics (numpy, scipy, numba), no I/O, no web, no file paths.

``estimators.__version__`` is looked up in the installed package's metadata when first read (PEP 562
module ``__getattr__``): ``importlib.metadata`` costs ~40 ms, which importing any estimator need not pay.
"""

from __future__ import annotations

from functools import lru_cache


@lru_cache(maxsize=1)
def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("chakamo")
    except PackageNotFoundError:  # running from a source tree that was not installed
        return "0.0.0+source"


def __getattr__(name: str) -> str:
    if name == "__version__":
        return _version()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
