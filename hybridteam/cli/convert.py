"""``hybridteam convert``: an agent's behaviour to an SCXML chart, and a chart back.

``convert TEAM.yaml --agent NAME -o NAME.scxml`` writes the agent's mode tree, transitions,
actions and variables (:mod:`hybridteam.export.scxml`); ``convert CHART.scxml --into
TEAM.yaml [--agent NAME] -o NEW.yaml`` puts a chart's behaviour into that agent of a team
(its plant, robot model and parameters stay); ``convert CHART.scxml -o TEAM.yaml`` writes
the chart alone as a team of one agent without a plant. The input is validated first, the
output written atomically; bad input or arguments exit with status 2 and write nothing.
"""

from __future__ import annotations

import sys
from pathlib import Path

from hybridteam.cli.common import EXIT_OK, EXIT_USAGE, UsageError, print_errors


def register(sub) -> dict:
    """Add the ``convert`` subcommand; returns its handler by name."""
    c = sub.add_parser(
        "convert", help="an agent's behaviour to SCXML, or an SCXML chart to a team file"
    )
    c.add_argument("source", metavar="TEAM.yaml|CHART.scxml")
    c.add_argument(
        "-o",
        "--output",
        required=True,
        metavar="FILE",
        help="the .scxml chart or the .yaml team file to write",
    )
    c.add_argument(
        "--agent",
        default=None,
        metavar="NAME",
        help="the agent to convert (or, with --into, to replace); default: the "
        "team's only agent, or the chart's name",
    )
    c.add_argument(
        "--into",
        default=None,
        metavar="TEAM.yaml",
        help="with a chart: the team whose agent takes its behaviour",
    )
    return {"convert": convert}


def convert(args) -> int:
    from hybridteam.io.filekind import InputErrors

    source, out = Path(args.source), Path(args.output)
    chart = source.suffix.lower() == ".scxml"
    if out.suffix.lower() != (".yaml" if chart else ".scxml"):
        raise UsageError(
            f"output '{out}' must end in {'.yaml' if chart else '.scxml'} "
            f"(converting {'a chart to a team' if chart else 'a team to a chart'})"
        )
    if args.into is not None and not chart:
        raise UsageError(
            "--into takes a chart's behaviour into a team: the source must be an .scxml chart"
        )
    try:
        text = _from_chart(source, args) if chart else _to_chart(source, args)
    except InputErrors as exc:
        print_errors(exc)
        return EXIT_USAGE
    from hybridteam.trace import write_atomic

    write_atomic(out, text)
    print(f"wrote {out}", file=sys.stderr)
    return EXIT_OK


def _to_chart(source: Path, args) -> str:
    from hybridteam.export.scxml import NotExpressible, agent_chart
    from hybridteam.io.loader import load_team

    team = load_team(source)
    names = [a.name for a in team.agents]
    name = args.agent or (names[0] if len(names) == 1 else None)
    if name is None:
        raise UsageError(
            f"team '{team.name}' has {len(names)} agents ({', '.join(names)}); "
            "choose one with --agent"
        )
    if name not in names:
        raise UsageError(f"no agent '{name}' in team '{team.name}' (agents: {', '.join(names)})")
    try:
        return agent_chart(team.agent(name), team.priority_rule)
    except NotExpressible as exc:
        raise UsageError(f"cannot write an SCXML chart: {exc}") from None


def _from_chart(source: Path, args) -> str:
    import yaml

    from hybridteam.io.filekind import Document, read_document
    from hybridteam.io.loader import load_team_file
    from hybridteam.io.scxml import merge_chart, read_chart

    if args.into is None:
        load_team_file(source)  # the chart alone, as a team of one agent without a plant
        return yaml.safe_dump(read_document(source).data, sort_keys=False, allow_unicode=True)
    load_team_file(args.into)  # the team as it is: its own errors are its file's
    team = read_document(args.into)
    agents = list(team.data["agents"])
    chart_name = read_chart(source).data["team"]
    name = args.agent or (
        chart_name if chart_name in agents else agents[0] if len(agents) == 1 else None
    )
    if name is None or name not in agents:
        raise UsageError(
            f"choose the agent of '{args.into}' that takes the chart with "
            f"--agent (agents: {', '.join(map(str, agents))})"
        )
    chart = read_chart(source, name)
    data = merge_chart(team.data, name, chart.data["agents"][name])
    # what is wrong now comes from the chart (the team loaded without it): located there
    _check(Document(chart.filename, data, chart.positions))
    return yaml.safe_dump(data, sort_keys=False, allow_unicode=True)


def _check(doc) -> None:
    """The merged team must load as it is (its plant, parameters and protocols with the
    chart's modes), before anything is written."""
    from hybridteam.io.loader import FILE_KINDS

    next(k for k in FILE_KINDS if k.name == "team").load(doc)
