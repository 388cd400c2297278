"""HTML pieces of the verification reports: the style sheet, number formatting, tables, pictures, pages.

Every study renders its own section with these; :mod:`verification.report` puts the sections together.
"""

from __future__ import annotations

import html
import math
from pathlib import Path
from typing import Any, Iterable

CSS = """
body { font-family: sans-serif; max-width: 1150px; margin: 2em auto; color: #222; line-height: 1.4; }
table { border-collapse: collapse; margin: 0.6em 0 1.2em; font-size: 0.86em; }
th, td { border: 1px solid #bbb; padding: 3px 7px; text-align: right; }
th { background: #eee; } td:first-child, th:first-child { text-align: left; }
.pass { color: #0a0; font-weight: bold; } .fail { color: #c00; font-weight: bold; }
img { max-width: 100%; border: 1px solid #ddd; margin: 4px 0; }
.grid { display: grid; grid-template-columns: 1fr 1fr; gap: 8px; }
code { background: #f4f4f4; padding: 0 3px; }
.note { font-size: 0.9em; color: #444; }
"""


def fmt(x: Any) -> str:
    """Numbers in a compact scientific or fixed form; everything else as text."""
    if isinstance(x, bool):
        return "yes" if x else "no"
    if isinstance(x, int):
        return f"{x:,}"
    if isinstance(x, float):
        if math.isnan(x):
            return "–"
        if x == 0.0:
            return "0"
        if 1e-2 <= abs(x) < 1e4:
            return f"{x:.4g}"
        return f"{x:.2e}"
    if x is None:
        return "–"
    return html.escape(str(x))


def table(headers: Iterable[str], rows: Iterable[Iterable[Any]]) -> str:
    head = "".join(f"<th>{html.escape(h)}</th>" for h in headers)
    body = "".join("<tr>" + "".join(f"<td>{c if isinstance(c, Markup) else fmt(c)}</td>" for c in r) + "</tr>"
                   for r in rows)
    return f"<table><tr>{head}</tr>{body}</table>"


class Markup(str):
    """A string already in HTML."""


def verdict(ok: bool) -> Markup:
    return Markup('<span class="pass">PASS</span>' if ok else '<span class="fail">FAIL</span>')


def img(name: str | None, caption: str = "") -> str:
    if not name:
        return ""
    return f'<figure><img src="{html.escape(name)}" alt="{html.escape(caption)}"><figcaption class="note">' \
           f"{html.escape(caption)}</figcaption></figure>"


def checks_table(checks: list[dict]) -> str:
    """The pass/fail table of a list of checks (dictionaries with name, value, threshold, ok)."""
    return table(["check", "value", "threshold", "verdict"],
                 [[c["name"], c["value"], c["threshold"], verdict(c["ok"])] for c in checks])


def write_page(path: str | Path, title: str, body: list[str]) -> Path:
    """A whole HTML page (the style sheet, ``title`` as its heading, then ``body``) written to ``path``."""
    out = Path(path)
    parts = [f"<!doctype html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
             f"<style>{CSS}</style></head><body><h1>{html.escape(title)}</h1>", *body, "</body></html>"]
    out.write_text("\n".join(parts), encoding="utf-8")
    return out


__all__ = ["CSS", "Markup", "checks_table", "fmt", "img", "table", "verdict", "write_page"]
