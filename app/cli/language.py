"""The language of ``chakamo``'s own words: ``--lang``, read before the command line is parsed, and argparse's.

The rule is the one of every command: the messages speak ``--lang`` when it is given, English otherwise
(:func:`app.cli.admin._say`).  argparse builds its usage errors and the frame of its ``--help`` pages from
English msgids passed through ``gettext`` (``argparse._``); :data:`ARGPARSE` maps each msgid a user can cause to
a ``cli.argparse_*`` sentence of the CLI catalogue, and :data:`HELP` the help texts of ours that have one (:data:`app.web.messages.CATALOGUE`, the one table of the
CLI's words), and :class:`Parser` speaks them while it parses: ``chakamo process --bogus --lang es`` answers
``chakamo: error: argumentos no reconocidos: --bogus``.  The English entries are argparse's own msgids, so a
command line without ``--lang`` (or with ``--lang en``) reads exactly as argparse writes it.

The catalogue (and the web framework it sits beside, ~0.4 s of imports) is read only when a sentence is needed:
on an error, a ``--help`` page, or a start-up line; a command line that parses costs nothing more.
"""

from __future__ import annotations

import argparse
import functools
from collections.abc import Iterator, Sequence
from contextlib import contextmanager

from app.choices import LANGUAGE_NAMES

#: argparse's msgids (Python 3.11+) a command line can bring out -> their sentence of the CLI catalogue.  A msgid
#: not listed (argparse's messages to programmers, e.g. a conflicting option) stays as argparse writes it.
ARGPARSE = {
    "usage: ": "cli.argparse_usage",
    "positional arguments": "cli.argparse_positionals",
    "options": "cli.argparse_options",
    "show this help message and exit": "cli.argparse_help",
    "%(prog)s: error: %(message)s\n": "cli.argparse_error",
    "argument %(argument_name)s: %(message)s": "cli.argparse_argument",
    "unrecognized arguments: %s": "cli.argparse_unrecognized",
    "the following arguments are required: %s": "cli.argparse_required",
    "one of the arguments %s is required": "cli.argparse_one_of",
    "not allowed with argument %s": "cli.argparse_not_allowed",
    "ignored explicit argument %r": "cli.argparse_ignored",
    "expected one argument": "cli.argparse_expected_one",
    "expected at most one argument": "cli.argparse_expected_at_most_one",
    "expected at least one argument": "cli.argparse_expected_at_least_one",
    "expected %s argument": "cli.argparse_expected_n",
    "expected %s arguments": "cli.argparse_expected_n",
    "ambiguous option: %(option)s could match %(matches)s": "cli.argparse_ambiguous",
    "invalid %(type)s value: %(value)r": "cli.argparse_invalid_value",
    "invalid choice: %(value)r (choose from %(choices)s)": "cli.argparse_invalid_choice",
    "unknown parser %(parser_name)r (choices: %(choices)s)": "cli.argparse_invalid_choice_command",
}
#: the English texts of ``chakamo``'s ``--help`` pages that have a sentence in the catalogue (translated, as
#: argparse's msgids, when a help page is printed)
HELP = {
    "Clinical 3D knee kinematics from two IMUs.": "cli.description",
    "show program's version number and exit": "cli.version_help",
    "simulate a session with known truth, process it, print the accuracy": "cli.help_demo",
    "process one recorded session folder into results.json": "cli.help_process",
    "serve the live 3D femur-tibia animation of a processed session": "cli.help_view",
    "foot-mounted pedestrian dead reckoning of one walk": "cli.help_walk",
    "Markovian Kalman filters on a multi-segment research CSV": "cli.help_markov",
    "run the web application (embedded default: SQLite, local files)": "cli.help_serve",
    "manage clinics (tenants)": "cli.help_clinics",
    "manage user accounts": "cli.help_users",
    "manage API tokens": "cli.help_tokens",
    "correct or erase a patient (operator)": "cli.help_patients",
    "correct or erase a session (operator)": "cli.help_sessions",
    "list (dry run) or erase the sessions past the retention period": "cli.help_retention",
    "upgrade the database schema to this release and exit": "cli.help_migrate",
    "run a Celery worker for the processing jobs (CHAKAMO_JOB_BACKEND=celery)": "cli.help_worker",
    "queue every session since a date for processing with a filter": "cli.help_reprocess",
    "language of the messages (default: English)": "cli.help_lang_messages",
}

_current: list[str] = []   # the language of the parse in progress (a stack: a subparser parses inside its parent)


def requested(argv: Sequence[str]) -> str | None:
    """The language the command line asks for, read as argparse will read it: the last ``--lang X`` /
    ``--lang=X`` wins, and so does an abbreviation argparse accepts (``--lan es``, ``--la=pt``: at least
    ``--la``, since ``--l`` may be another option's).  None when it names none of es/en/pt: argparse then
    refuses the value itself, in English."""
    found = None
    for i, arg in enumerate(argv):
        if arg == "--":
            break
        name, eq, value = arg.partition("=")
        if len(name) < 4 or not "--lang".startswith(name):
            continue
        if not eq:
            value = argv[i + 1] if i + 1 < len(argv) else None
        found = value
    return found if found in LANGUAGE_NAMES else None


def say(code: str, lang: str | None = None, **params) -> str:
    """Sentence ``code`` of the CLI catalogue in ``lang`` (default: the language of the parse in progress, else
    English)."""
    from app.web.messages import render

    return render(code, lang or (_current[-1] if _current else "en"), **params)


def error_line(prog: str, message: str, lang: str | None) -> str:
    """``PROG: error: MESSAGE`` and a newline, as argparse ends a usage error, in ``lang``."""
    msgid = "%(prog)s: error: %(message)s\n"
    template = msgid if lang in (None, "en") else say(ARGPARSE[msgid], lang)
    return template % {"prog": prog, "message": message}


def _gettext(message: str) -> str:
    code = ARGPARSE.get(message) or HELP.get(message)
    return message if code is None or not _current or _current[-1] == "en" else say(code)


def _ngettext(singular: str, plural: str, n: int) -> str:
    return _gettext(singular if n == 1 else plural)


@contextmanager
def _speaking(lang: str | None) -> Iterator[None]:
    """argparse's msgids in ``lang`` (English: untouched) while the block runs: ``argparse._`` and
    ``argparse.ngettext``, the names argparse calls them through, are swapped for the block and restored after it
    (process-wide: ``chakamo`` parses once, on its main thread, before any other thread starts)."""
    if lang in (None, "en"):
        yield
        return
    saved = argparse._, argparse.ngettext
    _current.append(lang)
    argparse._, argparse.ngettext = _gettext, _ngettext
    try:
        yield
    finally:
        _current.pop()
        if not _current:
            argparse._, argparse.ngettext = saved


class Parser(argparse.ArgumentParser):
    """An :class:`argparse.ArgumentParser` whose own sentences (usage errors, the ``--help`` frame, the type
    errors of our converters) speak ``lang`` (``--lang`` read from the command line by :func:`requested`).  Its
    sub-commands' parsers are of this class too, with its ``lang``."""

    def __init__(self, *args, lang: str | None = None, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.lang = lang

    def add_subparsers(self, **kwargs):
        kwargs.setdefault("parser_class", functools.partial(Parser, lang=self.lang))
        return super().add_subparsers(**kwargs)

    def parse_args(self, args=None, namespace=None):
        with _speaking(self.lang):
            return super().parse_args(args, namespace)

    def parse_known_args(self, args=None, namespace=None):
        with _speaking(self.lang):
            return super().parse_known_args(args, namespace)

    def format_help(self) -> str:
        with _speaking(self.lang):
            # the titles and help texts were set, in English, when the parser was built
            self.description = _gettext(self.description) if self.description else self.description
            for group in self._action_groups:
                group.title = _gettext(group.title) if group.title else group.title
            for action in self._actions:
                for each in (action, *(action._get_subactions() if action.choices is not None and
                                       hasattr(action, "_get_subactions") else ())):
                    if isinstance(each.help, str):
                        each.help = _gettext(each.help)
            return super().format_help()

    def format_usage(self) -> str:
        with _speaking(self.lang):
            return super().format_usage()

    def error(self, message: str):
        with _speaking(self.lang):
            super().error(message)


__all__ = ["ARGPARSE", "HELP", "Parser", "error_line", "requested", "say"]
