"""A table as a small standalone HTML page: what the Snakemake report shows a table as (it
renders images and HTML, not CSV)."""

from __future__ import annotations

from html import escape

import pandas as pd

STYLE = ("body{font-family:sans-serif;font-size:13px;margin:1em}table{border-collapse:collapse}"
         "th,td{border:1px solid #ccc;padding:3px 6px;vertical-align:top;text-align:left}"
         "th{background:#eee}td.differs{background:#fff3f0}td.notproved{background:#ffe0e0}")


def table(title: str, lead: str, columns, rows: list[dict], row_class=lambda r: "", anchor=None,
          sections=()) -> str:
    """The page: title, lead and the rows as pandas' HTML table (cells escaped); row_class(r) names
    a row's class (its cells get it: STYLE colours "differs" and "notproved"). anchor: (column,
    prefix): that column's cell links to the page's section `prefix + cell`; sections: (id, heading,
    text) each shown after the table as a preformatted section with that id."""
    cols = [str(c) for c in columns]
    df = pd.DataFrame([[str(r.get(c, "")) for c in columns] for r in rows], columns=cols)
    classes = pd.DataFrame([[row_class(r)] * len(cols) for r in rows], columns=cols)
    st = df.style.hide(axis="index").format(escape="html").format_index(escape="html", axis=1)
    if anchor:
        col, prefix = anchor  # escaped first, then wrapped: the text stays escaped
        st = st.format(lambda v: f'<a href="#{prefix}{v}">{v}</a>', subset=[col], escape="html")
    body = st.set_td_classes(classes).to_html(table_uuid="table", cell_ids=False)
    more = "".join(f'<section id="{escape(i)}"><h3>{escape(h)}</h3><pre>{escape(t)}</pre></section>'
                   for i, h, t in sections)
    return (f"<!DOCTYPE html><html><head><meta charset=\"utf-8\"><title>{escape(title)}</title>"
            f"<style>{STYLE}</style></head><body><h2>{escape(title)}</h2><p>{escape(lead)}</p>"
            f"{body}{more}</body></html>\n")
