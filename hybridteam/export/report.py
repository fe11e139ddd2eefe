"""One self-contained HTML page for a run folder: what a reader opens first.

Everything is inline — figures and the animation as data URIs, no script, no font or
stylesheet from elsewhere — so the page opens from a mail attachment or an offline laptop
exactly as it was written. Sections: the summary (outcome per instance, with the
statistics world components report), the requirement verdicts when the team states
requirements, the state diagram, the timeline, the trajectories,
the animation, and the message sequence chart as Mermaid source (rendering Mermaid needs a
JavaScript library, which an offline page cannot fetch; the source is readable, and pastes
into any Mermaid viewer).

A run folder is a file anyone can hand over, so nothing read from it reaches the page as
markup: every value of ``summary.json`` and the trace is escaped, and every figure —
the folder's ``modes.svg`` as much as the views drawn now — is an ``<img>`` of a data
URI, never inline SVG. A browser runs no script and fetches nothing for an image, so
whatever markup a hostile ``modes.svg`` carries is inert by construction, with no
sanitizer to get wrong. A file that is not the image it is named as (``modes.svg`` or
``run.gif`` linked to a private file) is refused rather than copied into the page.
"""

from __future__ import annotations

import base64
import html
import os
import re
import tempfile
from pathlib import Path
from typing import Any

from hybridteam.trace import Trace, write_atomic

SECTIONS = ("summary", "diagram", "timeline", "trajectories", "animation", "sequence")

_STYLE = """
body { font-family: DejaVu Sans, Helvetica, Arial, sans-serif; margin: 2em auto;
       max-width: 1150px; color: #222; }
h1 { font-size: 1.6em; } h2 { font-size: 1.2em; border-bottom: 1px solid #ccc; }
table { border-collapse: collapse; font-size: 0.9em; }
td, th { border: 1px solid #ddd; padding: 0.25em 0.6em; text-align: left; vertical-align: top; }
th { background: #f3f3f3; }
.figure svg, .figure img { max-width: 100%; height: auto; }
pre { background: #f7f7f7; padding: 0.8em; overflow-x: auto; font-size: 0.85em; }
.ok { color: #1a7f37; } .bad { color: #b3261e; }
"""


# an SVG document starts with markup and opens its <svg> element within its prolog (XML
# declaration, doctype, comments such as Graphviz's title, which may quote a team name)
_SVG_START, _SVG_ELEMENT = re.compile(rb"(\xef\xbb\xbf)?\s*<"), re.compile(rb"<svg[\s/>]")
_GIF_START = (b"GIF87a", b"GIF89a")


class NotAnImage(ValueError):
    """A file of the run folder is not the image its name says (the message names it)."""


def _image(path: Path, kind: str) -> bytes:
    """The bytes of the folder's image ``path`` (``svg`` or ``gif``), checked to be one: a
    regular file of a bounded size (not a FIFO, not ``/dev/zero``), then its markup."""
    from hybridteam.io.files import MAX_TRACE_MB, read_regular
    from hybridteam.io.yamlpos import SourceError

    try:
        data = read_regular(
            path,
            str(path),
            limit_mb=MAX_TRACE_MB,
            env="HYBRIDTEAM_MAX_TRACE_MB",
            what="files of a run folder",
        )
    except SourceError as exc:
        raise NotAnImage(str(exc)) from None
    ok = (
        (_SVG_START.match(data) and _SVG_ELEMENT.search(data, 0, 8192))
        if kind == "svg"
        else data[:6] in _GIF_START
    )
    if not ok:
        what = "an SVG image (<svg> markup)" if kind == "svg" else "a GIF image"
        raise NotAnImage(f"{path}: not {what}; refusing to copy it into the report")
    return data


def _figure(data: bytes, kind: str, alt: str) -> str:
    """An image as an ``<img>`` of a data URI: inert whatever the file holds."""
    mime = {"svg": "svg+xml", "gif": "gif"}[kind]
    uri = f"data:image/{mime};base64," + base64.b64encode(data).decode("ascii")
    return f"<div class='figure'><img alt='{html.escape(alt)}' src='{uri}'></div>"


def _cell(value: Any) -> str:
    """A value read back from ``summary.json``, as text of the page (always escaped)."""
    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, list):
        return " / ".join(_cell(v) for v in value)
    return html.escape(str(value))


def _summary(summary: dict[str, Any]) -> str:
    rows = summary.get("instances", [])
    keys = [k for k in (rows[0] if rows else {}) if k not in ("instance", "requirements")]
    head = "".join(f"<th>{html.escape(k)}</th>" for k in ["instance", *keys])
    body = []
    for row in rows:
        cls = "ok" if row.get("outcome") in ("ok", "success") else "bad"
        cells = [f"<td>{_cell(row.get('instance', ''))}</td>"]
        cells += [
            f"<td class='{cls}'>{_cell(row[k])}</td>"
            if k == "outcome"
            else f"<td>{_cell(row.get(k, ''))}</td>"
            for k in keys
        ]
        body.append("<tr>" + "".join(cells) + "</tr>")
    tally = ", ".join(f"{k}: {v}" for k, v in (summary.get("outcomes") or {}).items())
    facts = (
        f"<p>{_cell(summary.get('n', len(rows)))} instance(s), seed "
        f"{_cell(summary.get('seed'))}, {_cell(summary.get('duration'))} s simulated "
        f"at most — {html.escape(tally)}</p>"
    )
    return facts + f"<table><tr>{head}</tr>{''.join(body)}</table>"


def _requirements(summary: dict[str, Any]) -> str:
    """The requirement verdicts (a section only when the team states requirements): one
    row per instance and requirement, a violation with its time and failing part."""
    rows = [r for r in summary.get("instances", []) if r.get("requirements")]
    if not rows:
        return ""
    body = []
    for row in rows:
        for name, v in row["requirements"].items():
            held = bool(v["satisfied"])
            what = (
                "holds"
                if held
                else f"violated at t = {_cell(v.get('violated_at'))} by "
                f"<code>{html.escape(str(v.get('failed')))}</code>"
            )
            body.append(
                f"<tr><td>{_cell(row.get('instance', ''))}</td><td>{html.escape(name)}</td>"
                f"<td class='{'ok' if held else 'bad'}'>{what}</td>"
                f"<td>{_cell(v.get('robustness'))}</td></tr>"
            )
    return (
        "<section id='requirements'><h2>Requirements</h2><table><tr><th>instance</th>"
        "<th>requirement</th><th>verdict</th><th>robustness</th></tr>"
        + "".join(body)
        + "</table></section>"
    )


def write_report(
    folder: str | os.PathLike,
    trace: Trace,
    summary: dict[str, Any],
    output: str | os.PathLike | None = None,
    instance: int = 0,
    animation: bool = True,
) -> Path:
    """Write ``report.html`` (or ``output``) for the run folder ``folder`` from its trace
    and summary (``trace.json``, ``summary.json``, as ``hybridteam run`` writes them). The
    state diagram and an animation already in the folder are used; the other views are
    drawn now, for ``instance``. ``animation=False`` leaves the animation out (drawing it
    is most of the page's time) and says so in its section. Raises :class:`NotAnImage` for
    a folder's ``modes.svg`` or ``run.gif`` that is not that image (nothing is written)."""
    from hybridteam.export.animate import write_animation
    from hybridteam.export.sequence import sequence_chart
    from hybridteam.export.timeline import write_timeline
    from hybridteam.export.trajectories import write_trajectories

    folder = Path(folder)
    team = html.escape(str(trace.meta.get("team", folder.name)))
    parts = [
        f"<h1>{team}</h1>",
        f"<section id='summary'><h2>Summary</h2>{_summary(summary)}</section>",
        _requirements(summary),
    ]
    with tempfile.TemporaryDirectory() as tmp:
        scratch = Path(tmp)
        diagram = folder / "modes.svg"
        parts.append(
            "<section id='diagram'><h2>State diagram</h2>"
            + (
                _figure(_image(diagram, "svg"), "svg", "state diagram")
                if diagram.is_file()
                else "<p>(no modes.svg in the folder: run without --no-views)</p>"
            )
            + "</section>"
        )
        write_timeline(trace, scratch / "timeline.svg", instance=instance)
        parts.append(
            "<section id='timeline'><h2>Timeline</h2>"
            + _figure((scratch / "timeline.svg").read_bytes(), "svg", "mode timeline")
            + "</section>"
        )
        write_trajectories(trace, scratch / "trajectories.svg", instance=instance)
        parts.append(
            "<section id='trajectories'><h2>Trajectories</h2>"
            + _figure((scratch / "trajectories.svg").read_bytes(), "svg", "trajectories")
            + "</section>"
        )
        if animation:
            gif = folder / "run.gif"
            data = (
                _image(gif, "gif")
                if gif.is_file()
                else write_animation(
                    trace, scratch / "run.gif", instance=instance, fps=10, dpi=80
                ).read_bytes()
            )
            parts.append(
                "<section id='animation'><h2>Animation</h2>"
                + _figure(data, "gif", "animation of the run")
                + "</section>"
            )
        else:  # say so, or a reader looks for it
            parts.append(
                "<section id='animation'><h2>Animation</h2><p>Skipped "
                "(<code>--no-animation</code>); <code>hybridteam animate "
                "trace.json</code> draws it.</p></section>"
            )
    chart = sequence_chart(trace, "mermaid", instance=instance, sockets=("control",))
    parts.append(
        "<section id='sequence'><h2>Message sequence chart</h2><p>Mermaid source "
        "(control messages; paste into a Mermaid viewer to draw it):</p>"
        f"<pre>{html.escape(chart)}</pre></section>"
    )
    page = (
        "<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'>"
        f"<title>{team} — hybridteam run</title><style>{_STYLE}</style></head><body>"
        + "\n".join(parts)
        + "</body></html>\n"
    )
    out = Path(output) if output is not None else folder / "report.html"
    write_atomic(out, page)
    return out
