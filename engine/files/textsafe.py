"""
Text that is safe to show: user-supplied names (file, booth, sample, observer names) are
printed literally, whatever characters they hold.

A name can carry terminal control sequences (``\\x1b[2J`` clears the screen), rich console
markup (``[bold]``, ``[/link]``: rich would parse it, and a closing tag without its opening
one raises), or matplotlib mathtext (``$\\frac{$`` makes a plot title raise).  Every text
output of lbscene goes through one of the helpers here:

* :func:`printable` — control characters (C0 except newline and tab, DEL, C1, bidirectional
  overrides) as visible ``\\xNN`` / ``\\uNNNN`` escapes, for plain text output;
* :func:`json_text` — JSON with those characters as ``\\uNNNN`` escapes (the same string
  values, nothing a terminal acts on);
* :data:`PLAIN_TEXT_RC` / :func:`plain_text_plots` — matplotlib settings under which no text
  artist parses mathtext or LaTeX.

Rich consoles of the commands (:mod:`lbscene.commands.console`) render every string without
markup and through :func:`printable`.

Examples
--------
>>> printable("booth\\x1b[2J name")
'booth\\\\x1b[2J name'
>>> printable("a\\nb"), printable("a\\nb", newlines=False)
('a\\nb', 'a\\\\nb')
>>> json_text({"name": "x\\x9b"})
'{"name": "x\\\\u009b"}'
"""

from __future__ import annotations

import contextlib
import json
import re

__all__ = ["printable", "json_text", "PLAIN_TEXT_RC", "plain_text_plots"]

#: Characters a terminal may act on: C0 controls but tab and newline, DEL, C1 controls, and the
#: Unicode bidirectional embeddings/overrides/isolates (which reorder what follows them).
_CONTROL = re.compile("[\x00-\x08\x0b-\x1f\x7f-\x9f\u202a-\u202e\u2066-\u2069]")
_CONTROL_ALL = re.compile("[\x00-\x1f\x7f-\x9f\u202a-\u202e\u2066-\u2069]")
_NAMED = {"\n": "\\n", "\t": "\\t", "\r": "\\r"}


def _escape(m: re.Match) -> str:
    c = m.group(0)
    if c in _NAMED:
        return _NAMED[c]
    n = ord(c)
    return f"\\x{n:02x}" if n < 0x100 else f"\\u{n:04x}"


def printable(text, *, newlines: bool = True) -> str:
    """``text`` with every control character shown as an escape (``\\x1b``, ``\\u202e``).

    Parameters
    ----------
    text
        Anything; ``str(text)`` is shown.
    newlines
        Keep newlines and tabs as they are (several lines of text); ``False`` escapes them too
        (one field of a one-line message, such as a file name in a diagnostic).
    """
    s = text if isinstance(text, str) else str(text)
    return (_CONTROL if newlines else _CONTROL_ALL).sub(_escape, s)


def _json_escape(m: re.Match) -> str:
    return f"\\u{ord(m.group(0)):04x}"


def json_text(obj, **kw) -> str:
    """``json.dumps(obj, ensure_ascii=False, **kw)`` with every control character escaped.

    ``json`` already escapes C0 controls; C1 controls (``\\x9b`` is a one-byte CSI on some
    terminals) and bidirectional overrides are escaped here as ``\\uNNNN``: the decoded
    values are unchanged.
    """
    kw.setdefault("ensure_ascii", False)
    # json escapes C0 controls inside strings itself: the newlines left are its indentation
    return _CONTROL.sub(_json_escape, json.dumps(obj, **kw))


#: matplotlib settings under which text is drawn as it is written: no mathtext (``$…$``), no LaTeX.
PLAIN_TEXT_RC = {"text.usetex": False, "text.parse_math": False}


@contextlib.contextmanager
def plain_text_plots():
    """Context in which matplotlib figures are made *and saved* with :data:`PLAIN_TEXT_RC`
    (tick labels are created when the figure is drawn, so saving must happen inside too)."""
    import matplotlib

    with matplotlib.rc_context(PLAIN_TEXT_RC):
        yield
