"""The registry is light (no numpy or numba on import) and ``METHOD_INFO`` agrees with the classes."""

import subprocess
import sys

import pytest

import estimators.orientation as orientation


def test_import_loads_neither_numpy_nor_numba():
    code = ("import sys, estimators.orientation as o; o.METHODS, o.DEFAULT_METHOD, o.METHOD_INFO; "
            "print(sorted(m for m in ('numpy', 'numba', 'scipy') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_method_info_matches_the_classes():
    assert orientation.METHODS == tuple(info.name for info in orientation.METHOD_INFO)
    assert orientation.METHOD_INFO[0].name == orientation.DEFAULT_METHOD
    assert len(set(orientation.METHODS)) == len(orientation.METHODS)
    for info in orientation.METHOD_INFO:
        cls = orientation.get_method(info.name)
        assert cls.name == info.name
        assert (cls.supports_6d, cls.supports_9d) == (info.has_6d, info.has_9d)
        assert info.label and info.reference
    with pytest.raises(ValueError, match="choose one of chakamo"):
        orientation.method_info("nope")


def test_lazy_base_class():
    from estimators.orientation.base import OrientationMethod

    assert orientation.OrientationMethod is OrientationMethod
    with pytest.raises(AttributeError):
        orientation.no_such_name  # noqa: B018
