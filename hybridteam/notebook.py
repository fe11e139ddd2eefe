"""How teams and runs show themselves in Jupyter.

A :class:`~hybridteam.api.Run` displays its outcomes as a table and its first instance's
timeline inline; a :class:`~hybridteam.model.Team` displays its state diagram. Both reach
this module through their own ``_repr_html_`` methods, which Jupyter calls; nothing is
registered with IPython, and nothing here is imported until a notebook shows an object.
"""

from __future__ import annotations

import base64
import html
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from hybridteam.api import Run
    from hybridteam.model import Team


def run_html(run: Run, rows: int = 20) -> str:
    """An outcome table (at most ``rows`` instances) and the timeline of instance 0."""
    from hybridteam.export.timeline import timeline_figure

    head = "".join(f"<th>{h}</th>" for h in ("instance", "outcome", "t", "message"))
    body = "".join(
        f"<tr><td>{o['instance']}</td><td>{html.escape(o['outcome'])}</td>"
        f"<td>{o['t']:g}</td><td>{html.escape(o['message'])}</td></tr>"
        for o in run.diagnostics[:rows]
    )
    more = f"<p>… {run.n - rows} more instances</p>" if run.n > rows else ""
    first = run.instance(0) if run.n > 1 else run
    fig, _ = timeline_figure(first, 0, None, None)
    from io import BytesIO

    buf = BytesIO()
    fig.savefig(buf, format="png", dpi=80, bbox_inches="tight")
    image = base64.b64encode(buf.getvalue()).decode("ascii")
    return (
        f"<p><b>{html.escape(repr(run))}</b></p><table><thead><tr>{head}</tr></thead>"
        f"<tbody>{body}</tbody></table>{more}"
        f'<img alt="timeline" src="data:image/png;base64,{image}"/>'
    )


def team_html(team: Team) -> str:
    """The team's state diagram as inline SVG (roles view), with its name."""
    from hybridteam.export.diagram import diagram_graph
    from hybridteam.export.render import render
    from hybridteam.export.roles import roles_view

    svg = render(roles_view(diagram_graph(team)), "svg")
    assert isinstance(svg, str)  # (svg is a text format)
    return f"<p><b>{html.escape(repr(team))}</b></p>{svg}"
