"""The crate job reads only what it declares: a result file that no record hashed yet and that the
job does not declare (a job still running beside it) is listed without a sha256, never opened."""

import json
import sys

from embodied_snap.paper.crate import build

OPENED: list[str] | None = None


def _watch(event, args):
    if event == "open" and OPENED is not None:
        OPENED.append(str(args[0]))


def test_an_undeclared_file_without_record_is_listed_unread(tmp_path):
    global OPENED
    (tmp_path / "results/figs").mkdir(parents=True)
    (tmp_path / "results/figs/late.pdf").write_text("written by a job still running")
    (tmp_path / "results/figures").mkdir()
    (tmp_path / "results/figures/fig.pdf").write_text("declared")
    sys.addaudithook(_watch)  # hooks cannot be removed: it records only while OPENED is a list
    OPENED = []
    try:
        crate = build(tmp_path, may_read=lambda p: p.startswith("results/figures/"))
    finally:
        seen, OPENED = OPENED, None
    props = {e.id: e.properties() for e in crate.get_entities()}
    assert "sha256" not in props["results/figs/late.pdf"]
    assert "sha256" in props["results/figures/fig.pdf"]
    assert not any(p.endswith("late.pdf") for p in seen), seen
    assert json.dumps(props["results/figs/late.pdf"])  # listed all the same
