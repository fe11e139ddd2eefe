"""How teams and runs show themselves in Jupyter.

A :class:`~hybridteam.api.Run` displays its outcomes as a table and its first instance's
timeline inline; a :class:`~hybridteam.model.Team` displays its state diagram. The model
layer knows nothing of drawing, so the team's display is registered with IPython from
here, when hybridteam is imported inside IPython (:func:`enable`).
"""

from __future__ import annotations

import base64
import html
import sys
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
        for o in run.diagnostics[:rows])
    more = f"<p>… {run.n - rows} more instances</p>" if run.n > rows else ""
    first = run.instance(0) if run.n > 1 else run
    fig, _ = timeline_figure(first, 0, None, None)
    from io import BytesIO

    buf = BytesIO()
    fig.savefig(buf, format="png", dpi=80, bbox_inches="tight")
    image = base64.b64encode(buf.getvalue()).decode("ascii")
    return (f"<p><b>{html.escape(repr(run))}</b></p><table><thead><tr>{head}</tr></thead>"
            f"<tbody>{body}</tbody></table>{more}"
            f'<img alt="timeline" src="data:image/png;base64,{image}"/>')


def team_html(team: Team) -> str:
    """The team's state diagram as inline SVG (roles view), with its name."""
    from hybridteam.export.diagram import diagram_graph
    from hybridteam.export.render import render
    from hybridteam.export.roles import roles_view

    svg = render(roles_view(diagram_graph(team)), "svg")
    return f"<p><b>{html.escape(repr(team))}</b></p>{svg}"


def enable() -> None:
    """Register the team display with the running IPython, if there is one."""
    ipython = sys.modules.get("IPython")
    shell = ipython.get_ipython() if ipython is not None else None  # type: ignore[attr-defined]
    if shell is None:
        return
    from hybridteam.model import Team

    shell.display_formatter.formatters["text/html"].for_type(Team, team_html)
