"""Password strength (OWASP ASVS 4.0 V2.1, NIST SP 800-63B §5.1.1.2): what a new password must not be.

:func:`check_password_strength` raises :class:`WeakPassword` (a ``ValueError`` with a stable ``code`` and its
``params``; the sentences in Spanish, English and Portuguese are :mod:`app.web.messages`) when the password

1. has fewer than :data:`MIN_PASSWORD_LENGTH` (12) characters — ``password.too_short``;
2. is a pattern (``password.pattern``): fewer than :data:`MIN_DISTINCT` different characters (``aaaaaaaaaaaa``,
   ``121212121212``), one short unit repeated (``abcabcabcabc``), or a run of a keyboard row, the alphabet or
   the digits, forwards or backwards (``qwertyuiop12`` once its digits are stripped, ``123456789012``);
3. is a common password (``password.common``), on either of two lists that ship with the installed software
   (nothing is fetched):

   a. after lower-casing, removing accents, cutting the digits and symbols at both ends and undoing leet-speak
      (``0→o, 1→i, 3→e, 4→a, 5→s, 7→t, @→a, $→s``), its letters are one or two words of :data:`COMMON_FILE`
      (``Password2024!``, ``P4ssw0rd1234``, ``adminadmin123``) — ``app/web/data/common_passwords.txt``, curated
      for this product: the passwords people choose most in English, Spanish and Portuguese, and this
      product's own words;
   b. the password (lower case, without accents), its letters and digits alone (any script), or its letters
      as in (a) — whole, never split into words, and a reduced form only while it keeps at least half of the
      password's characters (``&(]B7U+}@*Ll`` is not ``bull``, ``кот-собака-лампа-1234`` not ``1234``) — is
      one of the 30 000 passwords of real breach dumps that the ``zxcvbn`` package ranks (:func:`breached_passwords`: ``leavemealone``, ``Jamesbond007!``, ``1234-5665-4321``,
      ``I see dead people``), more than the top 10 000 ASVS 2.1.7 names.  That list is English-centric,
      hence (a) for Spanish and Portuguese;
4. contains the user's own email name, email domain or a part of their name of at least 4 characters
   (``password.personal``): the first thing an attacker who knows the account tries.

Rule 3b is membership in the ranked list, not zxcvbn's score (its estimate of the guesses a password needs):
a listed password is refused whatever its rank, anything else is left to the other rules.  Membership is
predictable — a password is refused only when it is on the list give or take its decoration (case, accents,
symbols, a few digits: at most half of it), the refusal gives a reason the user
can act on ("one of the most common passwords"), and it is the blocklist NIST asks for — and fast: the whole
check takes ~20 µs, zxcvbn's score 1.5–3 ms.  The score moves with each of zxcvbn's heuristics and word lists
(English words, names, film titles), rates a Spanish or Portuguese phrase differently from an English one of
the same strength, and explains itself in English only.  The list is imported at the first check
(:func:`breached_passwords`, cached): importing ``zxcvbn.frequency_lists`` runs the package's ``__init__``,
which builds dictionaries of all its lists (~16 ms, ~40 ms the first time after installing; +16 MB), a cost
``chakamo``'s start-up and its commands that set no password do not pay.

Not checked: composition rules (upper case, digits, symbols), which NIST advises against; a long passphrase
of ordinary words passes.  No network: no breach service is asked (clinics are often offline).
"""

from __future__ import annotations

import functools
import re
import unicodedata
from pathlib import Path

MIN_PASSWORD_LENGTH = 12
#: fewer different characters than this is a pattern, whatever the length
MIN_DISTINCT = 5
COMMON_FILE = Path(__file__).resolve().parent / "data" / "common_passwords.txt"
#: runs a password must not be a piece of (also backwards)
SEQUENCES = ("abcdefghijklmnopqrstuvwxyz", "01234567890123456789", "qwertyuiopasdfghjklzxcvbnm", "qwertyuiop",
             "asdfghjkl", "zxcvbnm", "1qaz2wsx3edc4rfv5tgb", "qazwsxedcrfvtgbyhnujmikolp", "qwertzuiop", "azertyuiop")
_LEET = str.maketrans({"0": "o", "1": "i", "3": "e", "4": "a", "5": "s", "7": "t", "@": "a", "$": "s"})


class WeakPassword(ValueError):
    """A password the rules refuse: ``code`` (``password.too_short|pattern|common|personal``) and ``params``."""

    def __init__(self, code: str, message: str, **params) -> None:
        super().__init__(message)
        self.code, self.params = code, params


@functools.cache
def common_words() -> frozenset[str]:
    """The words of :data:`COMMON_FILE` (comment lines skipped)."""
    lines = COMMON_FILE.read_text(encoding="utf-8").splitlines()
    return frozenset(w.strip() for w in lines if w.strip() and not w.startswith("#"))


@functools.cache
def breached_passwords() -> frozenset[str]:
    """The passwords of real breach dumps that ``zxcvbn`` ships, ranked by how often they were seen (its
    ``FREQUENCY_LISTS["passwords"]``: 30 000, lower case, at least 4 characters), imported at the first call
    (the module docstring says why)."""
    from zxcvbn.frequency_lists import FREQUENCY_LISTS

    return frozenset(FREQUENCY_LISTS["passwords"])


def _fold(text: str) -> str:
    """Lower case without accents (``Contraseña`` → ``contrasena``)."""
    decomposed = unicodedata.normalize("NFKD", text.lower())
    return "".join(c for c in decomposed if not unicodedata.combining(c))


def _is_pattern(pw: str) -> bool:
    if len(set(pw)) < MIN_DISTINCT:
        return True
    for unit in range(1, len(pw) // 2 + 1):  # one unit repeated (the last repetition may be cut)
        if len(pw) % unit == 0 and pw == pw[:unit] * (len(pw) // unit):
            return True
    core = re.sub(r"^[^a-z]+|[^a-z]+$", "", pw) if re.search(r"[a-z]", pw) else pw
    candidates = {pw, core} if len(core) >= 6 else {pw}
    return any(c in seq or c in seq[::-1] for c in candidates for seq in SEQUENCES)


def _letters_core(pw: str) -> str:
    """The letters of ``pw`` once the digits and symbols at both ends are cut and leet-speak undone."""
    middle = re.sub(r"^[^a-z]+|[^a-z]+$", "", pw)
    return re.sub(r"[^a-z]", "", middle.translate(_LEET))


def _is_common(pw: str) -> bool:
    words = common_words()
    cores = {_letters_core(pw), re.sub(r"[^a-z]", "", pw)}
    for core in cores:
        if not core:
            continue
        if core in words or any(core[:i] in words and core[i:] in words for i in range(3, len(core) - 2)):
            return True
    # rule 3b: a reduced form counts only while it keeps half the password (module docstring)
    forms = cores | {pw, re.sub(r"[\W_]", "", pw)}
    return not breached_passwords().isdisjoint(f for f in forms if f and 2 * len(f) >= len(pw))


def _personal_parts(email: str, name: str) -> set[str]:
    local, _, domain = _fold(email).partition("@")
    parts = set(re.split(r"[^a-z0-9]+", local)) | {re.sub(r"[^a-z0-9]", "", local)}
    parts |= {label for label in domain.split(".")[:-1]}
    parts |= set(re.split(r"[^a-z0-9]+", _fold(name)))
    return {p for p in parts if len(p) >= 4}


def check_password_strength(password: str, *, email: str = "", name: str = "") -> None:
    """Raise :class:`WeakPassword` when ``password`` breaks a rule of the module docstring (checked in its order);
    ``email`` and ``name`` are the account's, for rule 4."""
    if len(password) < MIN_PASSWORD_LENGTH:
        raise WeakPassword("password.too_short", f"the password must have at least {MIN_PASSWORD_LENGTH} "
                           "characters; choose a longer one (a phrase of several words is easy to remember)",
                           min=MIN_PASSWORD_LENGTH)
    pw = _fold(password)
    if _is_pattern(pw):
        raise WeakPassword("password.pattern", "the password is a simple pattern (a repeated character or group, "
                           "or a run of the keyboard, the alphabet or the digits); choose one that is hard to guess")
    if _is_common(pw):
        raise WeakPassword("password.common", "the password is one of the most common passwords (or one with a few "
                           "digits or symbols added); choose one that is hard to guess")
    flat = re.sub(r"[^a-z0-9]", "", pw)
    if any(part in flat for part in _personal_parts(email, name)):
        raise WeakPassword("password.personal", "the password contains your email or your name; choose one that "
                           "does not")


__all__ = ["COMMON_FILE", "MIN_DISTINCT", "MIN_PASSWORD_LENGTH", "SEQUENCES", "WeakPassword", "breached_passwords",
           "check_password_strength", "common_words"]
