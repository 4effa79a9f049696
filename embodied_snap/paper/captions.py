"""Captions of the HTML report (`snakemake --report`): the static caption of each figure
(report/<name>.rst), then the ledger's numbers for the paper sections it names and its lineage
(`esnap audit`: the evidence sets and groups that fed it). Written into results/report/ by the
ledger job; the figure rules point their report() captions there."""

from __future__ import annotations

from pathlib import Path

from ..lineage.audit import audit
from .ledger import _fed_by, count_line
from .sections import section_of


def _rst_escape(s: str) -> str:
    return s.replace("*", r"\\*").replace("`", r"\\`").replace("|", r"\\|")


def figure_caption(static: str, figure: str, rows: list[dict], root=".") -> str:
    secs = section_of(static)
    mine = [r for r in rows if r["section"] in secs]
    out = [static.rstrip(), ""]
    if mine:
        out += [f"**Ledger, section{'s' if len(secs) > 1 else ''} {', '.join(secs)}**: {count_line(mine)}.", ""]
        for r in mine:
            extra = f" (see {r['explained_in']})" if r.get("explained_in") else ""
            out.append(f"- ``{r['claim_id']}``: ours {r['ours'] or '-'}, paper {r['paper'] or '-'} {r['unit']}, "
                       f"{r['status']}{extra}")
        out.append("")
    rep = audit(figure, root, check_disk=False)
    out += [f"**Lineage** (``esnap audit {figure}``): fed by {rep['n_groups_fed']} raw groups: "
            f"{_rst_escape(_fed_by(rep)) or 'none'}; {len(rep['jobs'])} jobs.", ""]
    return "\n".join(out)


def write_figure_captions(figures: list[str], static_dir, out_dir, rows: list[dict], root=".") -> None:
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    for f in figures:
        name = Path(f).stem
        static = (Path(static_dir) / f"{name}.rst").read_text()
        (out_dir / f"{name}.rst").write_text(figure_caption(static, f, rows, root))
