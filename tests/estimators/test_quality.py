"""QualityWarning: code, English message and params, JSON-ready and read-only."""

from __future__ import annotations

import copy
import json
import pickle
from dataclasses import asdict, dataclass, replace

import numpy as np
import pytest

from estimators.quality import QualityWarning


def test_params_are_plain_json_values_and_default_empty():
    w = QualityWarning("x", "the angle is 7.3°", {"angle_deg": np.float64(7.26), "n": np.int64(3), "what": "thigh"})
    d = w.to_dict()
    assert d == {"code": "x", "message": "the angle is 7.3°", "params": {"angle_deg": 7.26, "n": 3, "what": "thigh"}}
    assert [type(v) for v in d["params"].values()] == [float, int, str]
    assert type(d["params"]) is dict and json.loads(json.dumps(d)) == d
    assert QualityWarning("y", "m").to_dict() == {"code": "y", "message": "m", "params": {}}


def test_params_are_read_only_and_copied():
    given = {"angle_deg": 1.0}
    w = QualityWarning("x", "m", given)
    given["angle_deg"] = 2.0
    assert w.params["angle_deg"] == 1.0
    with pytest.raises(TypeError, match="read-only"):
        w.params["angle_deg"] = 3.0  # type: ignore[index]
    with pytest.raises(TypeError, match="read-only"):
        w.params.update(angle_deg=3.0)  # type: ignore[attr-defined]
    assert w.params == {"angle_deg": 1.0}


def test_equality_hash_copy_pickle_and_asdict():
    w = QualityWarning("x", "m", {"a": 1.5})
    assert w == QualityWarning("x", "m", {"a": 1.5}) and w != QualityWarning("x", "m", {"a": 2.5})
    assert hash(w) == hash(QualityWarning("x", "m", {"a": 2.5}))  # params take no part in the hash
    assert pickle.loads(pickle.dumps(w)) == w and copy.deepcopy(w) == w
    assert replace(w, message="n").params == {"a": 1.5}

    @dataclass(frozen=True)
    class Holder:  # as MagQuality, whose to_dict goes through dataclasses.asdict
        warnings: tuple[QualityWarning, ...]

    assert asdict(Holder((w,))) == {"warnings": ({"code": "x", "message": "m", "params": {"a": 1.5}},)}


@pytest.mark.parametrize("params, match", [({"a": [1, 2]}, "params\\['a'\\] must be a number or a string"),
                                           ({"a": None}, "must be a number or a string"),
                                           ({3: 1.0}, "keys must be field names")])
def test_bad_params_are_refused(params, match):
    with pytest.raises(TypeError, match=match):
        QualityWarning("x", "m", params)
