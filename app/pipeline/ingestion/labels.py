"""Recognise role, segment, side and step height from labels and file names (es, en, pt).

A label is lower-cased, stripped of accents (``calibração`` → ``calibracao``) and split on anything
that is not a letter or digit; a word matches a token, or two adjacent tokens joined
(``de pie`` → ``depie``, ``em pé`` → ``empe``, ``step up`` → ``stepup``).  Two different roles (or
segments) in one label are refused as ambiguous.

Vocabulary (canonical value ← words):

* roles: ``mag_calibration`` ← calibracion, calibration, calibracao, calib, cal, mag, magcal, ocho, figure8;
  ``standing`` ← standing, stand, depie, parado, bipedestacion, empe, empé, upright;
  ``lying`` ← laydown, lying, lie, supine, supino, recostado, acostado, tumbado, deitado, decubito;
  ``task`` ← step, stepup, escalon, grada, degrau, task, tarea, tarefa, subida;
  ``continuous`` (the whole protocol in one recording, :mod:`.split`) ← continuous, continuo, continua,
  protocol, protocolo;
* segments: ``thigh`` ← muslo, thigh, coxa, femur;  ``shank`` ← pierna, shank, canela, perna, tibia, shin;
* side: ``right`` ← right, derecha, derecho, direita, direito;  ``left`` ← left, izquierda, izquierdo, esquerda,
  esquerdo;
* step height: a ``H`` token (thesis: the 34 cm step) → 0.34 m; ``17cm`` / ``34cm`` tokens → that height.
"""

from __future__ import annotations

import re
import unicodedata

from app.pipeline.ingestion.model import Recognition

ROLE_WORDS = {
    "mag_calibration": ("calibracion", "calibration", "calibracao", "calib", "cal", "mag", "magcal", "ocho",
                        "figure8", "calibracionsensor"),
    "standing": ("standing", "stand", "depie", "parado", "bipedestacion", "empe", "upright"),
    "lying": ("laydown", "lying", "lie", "supine", "supino", "recostado", "acostado", "tumbado", "deitado",
              "decubito", "layingdown", "laying"),
    "task": ("step", "stepup", "escalon", "grada", "degrau", "task", "tarea", "tarefa", "subida"),
    # the whole protocol in one recording, split by .split
    "continuous": ("continuous", "continuo", "continua", "protocol", "protocolo", "fullprotocol"),
}
SEGMENT_WORDS = {
    "thigh": ("muslo", "thigh", "coxa", "femur"),
    "shank": ("pierna", "shank", "canela", "perna", "tibia", "shin"),
}
SIDE_WORDS = {
    "right": ("right", "derecha", "derecho", "direita", "direito"),
    "left": ("left", "izquierda", "izquierdo", "esquerda", "esquerdo"),
}
HIGH_STEP_M = 0.34
LOW_STEP_M = 0.17


def fold(text: str) -> str:
    """Lower case without accents: ``"Calibração"`` → ``"calibracao"``."""
    s = unicodedata.normalize("NFKD", text.lower())
    return "".join(c for c in s if not unicodedata.combining(c))


def tokens(text: str) -> list[str]:
    """Folded alphanumeric tokens of a label."""
    return [t for t in re.split(r"[^a-z0-9]+", fold(text)) if t]


class AmbiguousLabel(ValueError):
    """A label naming more than one value of ``what`` (``"role"``, ``"segment"``, ``"side"``...): ``found`` maps
    each value to the word that named it.  ``str()`` is the English sentence; :meth:`fragment` the translatable
    ``word.label_ambiguous`` fragment of the ingestion catalogue."""

    def __init__(self, label: str, what: str, found: dict[str, str]) -> None:
        self.label, self.what, self.found = label, what, dict(found)
        super().__init__(f"the label {label!r} names more than one {what}: "
                         + ", ".join(f"{v} ({w!r})" for v, w in found.items()))

    def fragment(self) -> dict:
        """``{"code": "word.label_ambiguous", "params": ...}``: the sentence in every language."""
        return {"code": "word.label_ambiguous", "params": {
            "label": self.label, "what": {"code": f"word.{self.what}"},
            "found": ", ".join(f"{v} ('{w}')" for v, w in self.found.items())}}


def _candidates(toks: list[str]) -> list[str]:
    return toks + [a + b for a, b in zip(toks, toks[1:])]


def _find(text: str, vocabulary: dict[str, tuple[str, ...]], what: str,
          method: str) -> Recognition | None:
    found: dict[str, str] = {}
    for cand in _candidates(tokens(text)):
        for value, words in vocabulary.items():
            if cand in words and value not in found:
                found[value] = cand
    if len(found) > 1:
        raise AmbiguousLabel(text, what, found)
    if not found:
        return None
    value, word = next(iter(found.items()))
    return Recognition(value, method, word)


def recognise_role(text: str, method: str = "file name") -> Recognition | None:
    """Role of a recording from its label (``None`` if no word matches; ``ValueError`` if two do)."""
    return _find(text, ROLE_WORDS, "role", method)


def recognise_segment(text: str, method: str = "file name") -> Recognition | None:
    """Segment (thigh/shank) from a label."""
    return _find(text, SEGMENT_WORDS, "segment", method)


def recognise_side(text: str, method: str = "file name") -> Recognition | None:
    """Side (right/left) from a label."""
    return _find(text, SIDE_WORDS, "side", method)


def recognise_step_height(text: str, method: str = "file name") -> Recognition | None:
    """Step height in m from a label: a ``H`` token (34 cm, thesis naming) or ``NNcm``."""
    for t in tokens(text):
        m = re.fullmatch(r"(\d{1,3})cm", t)
        if m:
            return Recognition(int(m.group(1)) / 100.0, method, t)
    if "h" in tokens(text):
        return Recognition(HIGH_STEP_M, method, "-H suffix (thesis: the 34 cm step)")
    return None


# {calibracion-sensor|standing|laydown|step}-{muslo|pierna}-{ID}-{ddmmyyyy}-{n}[-H]
THESIS_NAME = re.compile(
    r"^(?P<role>[^-]+(?:-sensor)?)-(?P<segment>[^-]+)-(?P<id>[^-]+)-(?P<date>\d{8})-(?P<trial>\d+)(?P<high>-h)?$",
    re.IGNORECASE)


def parse_thesis_name(stem: str) -> dict[str, Recognition] | None:
    """Facts in a thesis-style name (seed 004 §8.6), or ``None`` if the name does not follow it."""
    m = THESIS_NAME.match(fold(stem))
    if not m:
        return None
    d = m.group("date")
    out = {
        "patient_id": Recognition(stem.split("-")[2 if not m.group("role").endswith("-sensor") else 3],
                                  "file name", "ID field"),
        "date": Recognition(f"{d[4:]}-{d[2:4]}-{d[:2]}", "file name", d),
        "trial": Recognition(int(m.group("trial")), "file name", m.group("trial")),
    }
    if m.group("high"):
        out["step_height_m"] = Recognition(HIGH_STEP_M, "file name", "-H suffix (thesis: the 34 cm step)")
    return out
