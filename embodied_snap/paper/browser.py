"""Open the HTML report (`snakemake --report`) in headless Chromium, offline, and check it as a reader
would see it: every result of every category is shown in turn; an image must decode
(naturalWidth > 0), a table (an HTML result) must render a <table> with rows, and the console must
show no error. The browser is the system's Chromium (Debian package `chromium`), driven through
playwright; playwright's own browser downloads are never used (docs/report.md)."""

from __future__ import annotations

import os
from pathlib import Path

CHROMIUM = os.environ.get("ESNAP_CHROMIUM", "/usr/bin/chromium")


def check_report(html, screenshot=None, show: str | None = None, only=None) -> dict:
    """{results: {path: what was seen}, problems: [one line each]}; a screenshot of `show` (a result
    path; default Fig. 1, else the first image) when `screenshot` is given; `only`: the categories holding these
    result paths (default: every category)."""
    from playwright.sync_api import sync_playwright

    html = Path(html).resolve()
    problems, seen = [], {}
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=["--no-sandbox"])
        page = browser.new_page(viewport={"width": 1400, "height": 900})
        page.on("console", lambda m: m.type == "error" and problems.append(f"console error: {m.text}"))
        page.on("pageerror", lambda e: problems.append(f"page error: {e}"))
        # offline: the report must carry everything it shows
        page.route("**/*", lambda r: r.continue_() if r.request.url.startswith(("file:", "data:", "blob:"))
                   else (problems.append(f"network request: {r.request.url}"), r.abort())[1])
        page.goto(html.as_uri())
        categories = page.evaluate("categories")
        for cat, subs in categories.items():
            paths = [r for rs in subs.values() for r in rs]
            if only is not None and not set(only) & set(paths):
                continue
            page.goto(html.as_uri())  # back to the menu of categories
            page.get_by_text(cat, exact=True).first.click()
            page.locator("a[iconname=eye]").first.wait_for()
            for k, path in enumerate(paths):
                page.locator("a[iconname=eye]").nth(k).click()
                seen[path] = _shown(page, path, problems)
        if screenshot:
            pngs = [r for r in seen if r.endswith(".png")]
            target = show or next((r for r in pngs if "fig1_" in r), pngs[0] if pngs else None)
            if target:
                cat = next(c for c, subs in categories.items() if any(target in rs for rs in subs.values()))
                page.goto(html.as_uri())
                page.get_by_text(cat, exact=True).first.click()
                paths = [r for rs in categories[cat].values() for r in rs]
                page.locator("a[iconname=eye]").nth(paths.index(target)).click()
                page.wait_for_timeout(500)
            page.screenshot(path=str(screenshot))
        browser.close()
    return dict(results=seen, problems=problems)


def _links(frame, path: str, problems: list) -> str:
    """In-page links (the ledger's claim ids to their audits): each must lead to a section of the
    page, and following the last must bring its section into view."""
    hrefs = frame.evaluate("() => [...document.querySelectorAll('a[href^=\"#\"]')]"
                           ".map(a => a.getAttribute('href').slice(1))")
    if not hrefs:
        return ""
    nowhere = frame.evaluate("ids => ids.filter(i => !document.getElementById(i))", hrefs)
    if nowhere:
        problems.append(f"{path}: {len(nowhere)} of {len(hrefs)} links lead nowhere, first #{nowhere[0]}")
        return f", {len(hrefs)} links"
    frame.locator(f'a[href="#{hrefs[-1]}"]').click()
    frame.wait_for_timeout(200)
    top = frame.evaluate("i => document.getElementById(i).getBoundingClientRect().top", hrefs[-1])
    inner = frame.evaluate("() => innerHeight")
    if not 0 <= top < inner:
        problems.append(f"{path}: following #{hrefs[-1]} does not show its section (top {top:.0f} px)")
    return f", {len(hrefs)} links to their sections"


def _shown(page, path: str, problems: list) -> str:
    name = Path(path).name
    if path.endswith((".png", ".jpg", ".jpeg", ".svg")):
        img = page.locator(f'img[src*="filename={name}"]')
        try:
            img.wait_for(timeout=10000)
            page.wait_for_function("i => i.complete", arg=img.element_handle(), timeout=10000)
        except Exception as e:  # noqa: BLE001 -- reported, not raised: every result is checked
            problems.append(f"{path}: not shown ({type(e).__name__})")
            return "missing"
        w = img.evaluate("i => i.naturalWidth")
        decodes = img.evaluate("i => i.decode().then(() => true, () => false)")
        if not w:
            problems.append(f"{path}: the image does not load (naturalWidth 0)")
        elif not decodes:
            problems.append(f"{path}: the image does not decode")
        return f"image {w} px wide"
    if path.endswith((".html", ".htm")):
        frame = page.locator("iframe")
        try:
            frame.wait_for(timeout=10000)
            rows = frame.content_frame.locator("tr")
            rows.first.wait_for(timeout=10000)
            n = rows.count()
        except Exception as e:  # noqa: BLE001
            problems.append(f"{path}: no table rendered ({type(e).__name__})")
            return "missing"
        if n < 2:
            problems.append(f"{path}: the table has no rows")
        return f"table of {n - 1} rows" + _links(frame.element_handle().content_frame(), path, problems)
    return "not checked"
