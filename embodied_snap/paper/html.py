"""A table as a small standalone HTML page: what the Snakemake report shows a table as (it
renders images and HTML, not CSV)."""

from __future__ import annotations

from html import escape

STYLE = ("body{font-family:sans-serif;font-size:13px;margin:1em}table{border-collapse:collapse}"
         "th,td{border:1px solid #ccc;padding:3px 6px;vertical-align:top;text-align:left}"
         "th{background:#eee}tr.differs td{background:#fff3f0}tr.notproved td{background:#ffe0e0}")


def table(title: str, lead: str, columns, rows: list[dict], row_class=lambda r: "") -> str:
    head = "".join(f"<th>{escape(str(c))}</th>" for c in columns)
    body = "".join(
        f'<tr class="{row_class(r)}">' + "".join(f"<td>{escape(str(r.get(c, '')))}</td>" for c in columns) + "</tr>"
        for r in rows)
    return (f"<!DOCTYPE html><html><head><meta charset=\"utf-8\"><title>{escape(title)}</title>"
            f"<style>{STYLE}</style></head><body><h2>{escape(title)}</h2><p>{escape(lead)}</p>"
            f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table></body></html>\n")
