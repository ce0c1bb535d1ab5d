"""The JSON documents the reports are written as: each names its kind and the version of that
kind's layout in its first key, ``"schema": "ionav-viz/KIND/VERSION"``. The keys of each kind are
in docs/report-schema.md. A version changes when a key is removed, renamed or changes meaning;
adding a key does not change it.

Readers (``figures``, ``compare``) take a document of any version up to theirs, and one without
``schema`` (written before it existed) by its keys.
"""

from __future__ import annotations

from typing import Any

from ..core.errors import InputError

#: The layout version this ionav-viz writes and reads, for every kind.
SCHEMA_VERSION = 1

#: Each kind, and the command that writes it.
KINDS = {
    "report": "evaluate --json (one outage length, one group)",
    "fleet": "evaluate --json on a fleet (--workers, a folder, a list file)",
    "lengths": "evaluate --outage 10s,30s --json (one report per outage length)",
    "scenarios": "evaluate --scenario all --json (one report per scenario)",
    "by_event": "evaluate --by-event --json (one report per manoeuvre type)",
    "comparison": "compare --json",
    "cross-validation": "cross-validate --json",
}


def tagged(kind: str, body: dict[str, Any]) -> dict[str, Any]:
    """``body`` with ``schema`` as its first key."""
    return {"schema": f"ionav-viz/{kind}/{SCHEMA_VERSION}", **body}


def schema_of(doc: Any, source: object, param: str, hint: str) -> str | None:
    """The kind a document says it is (None: it does not say: an older report, known by its keys).
    One :class:`InputError` naming ``source`` for a ``schema`` that is not this tool's, of a kind
    it does not know, or of a newer version than it reads."""
    if not isinstance(doc, dict) or "schema" not in doc:
        return None
    tag = doc["schema"]
    parts = tag.split("/") if isinstance(tag, str) else []
    if len(parts) != 3 or parts[0] != "ionav-viz" or not parts[2].isdigit():
        raise InputError(f"{source}: schema: {tag!r} is not an ionav-viz report's (ionav-viz/KIND/VERSION)", hint,
                         param=param)
    kind, version = parts[1], int(parts[2])
    if kind not in KINDS:
        raise InputError(f"{source}: schema: unknown kind {kind!r}", f"known: {', '.join(KINDS)}; {hint}", param=param)
    if version > SCHEMA_VERSION:
        raise InputError(f"{source}: written by a newer ionav-viz ({tag}; this one reads version {SCHEMA_VERSION})",
                         "upgrade ionav-viz ('pip install -U ionav-viz'), or write the report again with this one",
                         param=param)
    return kind
