"""The cuts of a four-sensor session's continuous recordings, keyed by knee (``left_thigh`` …, as the session
check and the wizard show them): accepted by ``check_split`` and applied by ``load_knees`` to that knee's sensor
only.  Before, ``check_split`` refused every key but ``thigh``/``shank``, so no cut of a four-sensor session could
be moved.

Truth: the simulator's protocol joined at known times (``test_continuous_session.py``) for both knees; the moved
cut is the one given, the untouched sensors keep the automatic split."""

from __future__ import annotations

import json

import pytest
from test_continuous_session import _continuous  # this folder is on sys.path (no packages)

from app.pipeline.ingestion import IngestionError, load_knees
from app.pipeline.ingestion.metabase import write_recording_metabase
from app.pipeline.ingestion.split import check_split

MACS = {("left", "thigh"): "D4F1A2B3C4E1", ("left", "shank"): "E8C2B1A0F9D1",
        ("right", "thigh"): "D4F1A2B3C4E2", ("right", "shank"): "E8C2B1A0F9D2"}
WORDS = {"left": "izquierda", "right": "derecha", "thigh": "muslo", "shank": "pierna"}


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    streams, _, truth = _continuous(seed=2, n_cycles=3)
    out = tmp_path_factory.mktemp("knees")
    for (side, seg), mac in MACS.items():
        write_recording_metabase(out, f"continuo-{WORDS[seg]}-{WORDS[side]}-ML1-13032023-1", mac, streams[seg])
    return out, truth


def _manifest(folder, split):
    (folder / "session.json").write_text(json.dumps({"side": "right", **({"split": split} if split else {})}),
                                         encoding="utf-8")


def test_a_knee_prefixed_cut_moves_that_knees_sensor_only(folder):
    path, truth = folder
    _manifest(path, None)
    auto = {side: {s.segment: s for s in k.splits} for side, k in load_knees(path).items()}
    assert set(auto) == {"left", "right"} and all(set(v) == {"thigh", "shank"} for v in auto.values())
    a, b = auto["left"]["thigh"].spans_s["standing"]
    moved = [round(a + 0.5, 3), round(b - 0.5, 3)]
    _manifest(path, {"left_thigh": {"standing": moved}})
    knees = load_knees(path)
    got = {side: {s.segment: s for s in k.splits} for side, k in knees.items()}
    assert got["left"]["thigh"].how == "session.json"
    assert list(got["left"]["thigh"].spans_s["standing"]) == pytest.approx(moved)
    for side, seg in (("left", "shank"), ("right", "thigh"), ("right", "shank")):
        assert got[side][seg].how == "role" and got[side][seg].spans_s == auto[side][seg].spans_s
    standing = knees["left"].recording("thigh", "standing")
    assert standing.t_s[-1] - standing.t_s[0] == pytest.approx(moved[1] - moved[0], abs=0.05)


def test_a_plain_key_cannot_say_which_knee_and_is_refused(folder):
    path, _ = folder
    _manifest(path, {"thigh": {"standing": [1.0, 3.0]}})
    with pytest.raises(IngestionError, match="left_thigh"):
        load_knees(path)
    assert set(check_split({"right_shank": {"task": [10.0, 20.0]}}, knees=True)) == {"right_shank"}
    with pytest.raises(IngestionError):
        check_split({"right_shank": {"task": [10.0, 20.0]}})  # a one-knee session's split takes plain keys only
    _manifest(path, None)
