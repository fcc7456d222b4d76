"""JSON-ready conversion: numpy to Python, non-finite to None, recursively."""

import json

import numpy as np

from estimators.jsonable import json_ready


def test_nested_numpy_and_non_finite_values():
    value = {"a": np.array([1.0, np.nan, np.inf]), 2: (np.int64(3), np.bool_(True)), "b": [{"c": np.float32(0.5)}]}
    out = json_ready(value)
    assert out == {"a": [1.0, None, None], "2": [3, True], "b": [{"c": 0.5}]}
    json.dumps(out, allow_nan=False)  # strict JSON accepts it
    assert type(out["2"][0]) is int and type(out["2"][1]) is bool
