"""Quality warnings shared by every estimator: one shape for ``results.json`` ``quality.warnings``."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class QualityWarning:
    """A measurement-quality problem: a stable ``code`` for software and a ``message`` for the clinician."""

    code: str
    message: str

    def to_dict(self) -> dict[str, str]:
        return {"code": self.code, "message": self.message}
