"""Quality warnings shared by every estimator: one shape for ``results.json`` ``quality.warnings``.

A warning has a stable ``code`` for software, an English ``message`` for the clinician and ``params``: the
numbers and words of the message by name (``{"angle_deg": 7.26}``), unrounded, so that a report can print
the warning in another language from data (``reports/translations_warnings.json`` names the same fields)
instead of reading the numbers back out of the English sentence.

Decisions: ``params`` is stored as a read-only copy (a ``dict`` subclass whose mutators raise, so
``dataclasses.asdict``, ``copy.deepcopy``, pickling and ``json`` treat it as the plain ``dict`` it holds —
``MagQuality.to_dict`` goes through ``asdict``) and a frozen warning stays frozen; its values are converted
to plain ``int``/``float``/``str`` on construction (numpy scalars included), so :meth:`QualityWarning.to_dict`
is JSON-ready without further work (non-finite floats are kept: the writer of ``results.json`` turns them
into ``null``).  ``params`` takes no part in hashing (a mapping is not hashable) but does in equality.
"""

from __future__ import annotations

import numbers
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, NoReturn

ParamValue = float | int | str


def _plain(name: str, value: object) -> ParamValue:
    if isinstance(value, str):
        return str(value)
    if isinstance(value, numbers.Integral):
        return int(value)
    if isinstance(value, numbers.Real):
        return float(value)
    raise TypeError(f"QualityWarning params[{name!r}] must be a number or a string, got {type(value).__name__} "
                    f"{value!r}; pass the value itself, not a container")


class Params(dict):
    """A read-only ``dict`` of a warning's values: every mutator raises TypeError."""

    __slots__ = ()

    def _read_only(self, *args: Any, **kwargs: Any) -> NoReturn:
        raise TypeError("a QualityWarning's params are read-only; build a new warning with the values you need")

    __setitem__ = __delitem__ = __ior__ = clear = pop = popitem = setdefault = update = _read_only

    def __reduce__(self):  # pickle and deepcopy rebuild it from a plain dict instead of item by item
        return (type(self), (dict(self),))


@dataclass(frozen=True)
class QualityWarning:
    """A measurement-quality problem: a stable ``code`` for software, a ``message`` for the clinician and
    ``params``, the message's values by field name (see the module docstring).

    Raises TypeError when a ``params`` key is not a string or a value is not a number or a string.
    """

    code: str
    message: str
    params: Mapping[str, ParamValue] = field(default_factory=Params, hash=False)

    def __post_init__(self) -> None:
        plain = {}
        for key, value in dict(self.params).items():
            if not isinstance(key, str):
                raise TypeError(f"QualityWarning params keys must be field names (str), got {key!r}")
            plain[key] = _plain(key, value)
        object.__setattr__(self, "params", Params(plain))

    def to_dict(self) -> dict[str, object]:
        """``{"code", "message", "params"}`` with ``params`` a plain ``dict`` of ints, floats and strings."""
        return {"code": self.code, "message": self.message, "params": dict(self.params)}
