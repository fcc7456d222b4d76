"""Cycles the clinician excluded from an analysis: who left which cycle out, and why.

A detected cycle is either accepted or not, and a cycle that is not has one reason (``results.json``
``cycles.rejected``): the pipeline's (incomplete, ``rmse``, a turn…) or ``excluded_by_clinician``
(:data:`estimators.motor_task.EXCLUDED`).  Both come out of one mechanism,
:func:`estimators.motor_task.reject_cycles`: the excluded cycles leave the candidates before the pipeline's RMSE
rejection runs on the cycles kept.  Re-including a cycle is asking for the analysis again without its exclusion.

An exclusion is recorded whole (:class:`CycleExclusion`): the cycle as the reports number it (1-based), the knee
(None in a one-knee session), the clinician's reason, who (the logged-in user, or the command line's user) and when.
``results.json`` ``cycles.excluded`` lists those of its knee; the web keeps them on the job that made the analysis
(``jobs.cycle_exclusions``), and that analysis supersedes the earlier ones (:mod:`app.jobs.work`).
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Iterable, Mapping
from dataclasses import asdict, dataclass
from typing import Any

from app.choices import SIDE_NAMES

#: the longest reason kept (a sentence, not a note)
REASON_CHARS = 300


@dataclass(frozen=True)
class CycleExclusion:
    """One cycle left out by the clinician.

    cycle : 1-based, as the reports and the UI number the detected cycles.   knee : ``left``/``right`` in a session
    of both knees, None for the only knee.   reason : the clinician's words.   by : who.   at : ISO 8601 UTC.
    """

    cycle: int
    knee: str | None = None
    reason: str = ""
    by: str = ""
    at: str = ""

    def __post_init__(self) -> None:
        if isinstance(self.cycle, bool) or not isinstance(self.cycle, int) or self.cycle < 1:
            raise ValueError(f"a cycle number starts at 1, got {self.cycle!r}")
        if self.knee is not None and self.knee not in SIDE_NAMES:
            raise ValueError(f"knee must be one of {', '.join(SIDE_NAMES)}, got {self.knee!r}")
        object.__setattr__(self, "reason", str(self.reason or "").strip()[:REASON_CHARS])

    @property
    def index(self) -> int:
        """0-based, as :func:`estimators.motor_task.reject_cycles` takes it."""
        return self.cycle - 1

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def now_iso() -> str:
    return dt.datetime.now(dt.timezone.utc).isoformat(timespec="seconds")


class BadCycle(ValueError):
    """An ``--exclude-cycles`` item that is neither a cycle number nor ``knee:number`` (``item``)."""

    def __init__(self, item: str) -> None:
        self.item = item
        super().__init__(f"{item!r}: a cycle number (e.g. 3) or knee:number (e.g. right:3)")


def parse_cli(text: str, *, reason: str = "", by: str = "", at: str | None = None) -> tuple[CycleExclusion, ...]:
    """``--exclude-cycles 3,7`` (the only knee) or ``right:3,left:7`` (a session of both knees); ValueError with the
    item that is wrong."""
    out = []
    for item in (x.strip() for x in text.split(",")):
        if not item:
            continue
        knee, _, number = item.rpartition(":")
        try:
            cycle = int(number)
        except ValueError:
            raise BadCycle(item) from None
        out.append(CycleExclusion(cycle, knee or None, reason, by, at or now_iso()))
    return normalised(out)


def from_records(records: Iterable[Mapping[str, Any]] | None) -> tuple[CycleExclusion, ...]:
    """Exclusions from their stored form (``jobs.cycle_exclusions``, ``results.json`` ``cycles.excluded``)."""
    return normalised(CycleExclusion(int(r["cycle"]), r.get("knee"), r.get("reason") or "", r.get("by") or "",
                                     r.get("at") or "") for r in records or ())


def normalised(exclusions: Iterable[CycleExclusion]) -> tuple[CycleExclusion, ...]:
    """One entry per (knee, cycle) — the last one named wins — in knee and cycle order."""
    keyed = {(e.knee or "", e.cycle): e for e in exclusions}
    return tuple(keyed[k] for k in sorted(keyed))


__all__ = ["BadCycle", "CycleExclusion", "from_records", "normalised", "now_iso", "parse_cli"]
