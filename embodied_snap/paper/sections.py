"""Paper sections as the captions name them: what the report's categories and the ledger's
per-figure numbers are keyed by. Standard library only: the workflow definition imports it."""

from __future__ import annotations

import re


def section_of(caption: str) -> list[str]:
    """The paper sections a caption names: '(paper section III-A/B)' -> ['III-A', 'III-B'],
    '(paper sections V-A, V-B)' -> ['V-A', 'V-B']."""
    m = re.search(r"paper sections? ([^)]*)\)", caption)
    out = []
    for num, subs in re.findall(r"\b([IVX]+)((?:-[A-Z](?:/[A-Z])*)?)", m.group(1) if m else ""):
        out += [f"{num}-{x}" for x in subs.lstrip("-").split("/")] if subs else [num]
    return out


def category(caption: str) -> str:
    """The report category of an item: the first paper section its caption names."""
    secs = section_of(caption)
    return f"Section {secs[0]}" if secs else "Data and evidence (Table I)"


def section_key(s: str):
    """Paper order: III-A < III-B < IV-A < ... < V-C, then anything else (Table I) by name."""
    m = re.fullmatch(r"([IVX]+)(?:-([A-Z]))?", s)
    roman = {"I": 1, "II": 2, "III": 3, "IV": 4, "V": 5, "VI": 6}
    return (0, roman.get(m.group(1), 9), m.group(2) or "") if m else (1, 0, s)
