"""Injection: what hybridteam writes never carries markup, directives or terminal control
sequences that came from a file it read.

A run folder, a trace and a team file are files anyone can hand over. The report escapes
every value of ``summary.json`` and shows every figure as an ``<img>`` (a hostile
``modes.svg`` is inert); ``summary.json`` of the wrong shape is refused at its line;
message names are identifiers; Mermaid and PlantUML text made from names cannot open a
tag or a directive; messages and warnings reach the terminal with control characters
escaped; ``requirements_from:`` does not print back a file that is not a requirements
document. The page is checked with a real HTML parser (and, where Chromium is installed,
loaded in it); the fuzz targets throw random hostile names at the report and the sequence
chart.
"""

from __future__ import annotations

import base64
import html.parser
import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hybridteam.cli import main
from hybridteam.export.sequence import sequence_chart
from hybridteam.trace import Trace

PING = """\
team: ping
agents:
  a:
    plant: {kind: flow, state: {x: 0.0}}
    initial: A
    modes:
      A:
        flow: {x: 1}
        transitions:
          - {to: B, after: 0.5, do: [{send: ping}]}
      B: {flow: {x: 0}}
  b:
    plant: {kind: flow, state: {x: 0.0}}
    modes:
      W: {flow: {x: 0}}
simulation: {duration: 1, sample_period: 0.25}
"""

SCRIPT = "<script>document.title='INJECTED'</script>"
HOSTILE_SVG = (
    "<svg xmlns='http://www.w3.org/2000/svg' width='40' height='20' "
    "onload=\"document.title='INJECTED'\">"
    + SCRIPT
    + "<a href='javascript:alert(1)'><text y='15'>hi</text></a></svg>\n"
)


class Page(html.parser.HTMLParser):
    """What a browser would act on in a page: script elements, event-handler attributes,
    javascript: URLs; and the page's text and images."""

    def __init__(self, text: str) -> None:
        super().__init__(convert_charrefs=True)
        self.scripts: list[str] = []
        self.handlers: list[tuple[str, str]] = []
        self.js_urls: list[str] = []
        self.images: list[str] = []
        self.tags: list[str] = []
        self.text: list[str] = []
        self.feed(text)
        self.close()

    def handle_starttag(self, tag, attrs):
        self.tags.append(tag)
        if tag == "script":
            self.scripts.append(tag)
        for name, value in attrs:
            if name.lower().startswith("on"):
                self.handlers.append((tag, name))
            if value and re.sub(r"[\s\x00-\x1f]", "", value).lower().startswith("javascript:"):
                self.js_urls.append(value)
        if tag == "img":
            self.images.append(dict(attrs)["src"])

    handle_startendtag = handle_starttag

    def handle_data(self, data):
        self.text.append(data)

    def inert(self) -> bool:
        return not (self.scripts or self.handlers or self.js_urls)


@pytest.fixture(scope="module")
def run_folder(tmp_path_factory) -> Path:
    """A finished run of the ping team (no views: each test adds the files it needs)."""
    folder = tmp_path_factory.mktemp("ping")
    (folder / "team.yaml").write_text(PING)
    assert (
        main(
            [
                "run",
                str(folder / "team.yaml"),
                "-o",
                str(folder / "run"),
                "--progress",
                "none",
                "--no-views",
                "--quiet",
            ]
        )
        == 0
    )
    return folder / "run"


def hostile_folder(run_folder: Path, tmp_path: Path) -> Path:
    """The run folder as an attacker hands it over: every string of ``summary.json`` that
    its format allows to be a string is markup, and ``modes.svg`` scripts."""
    folder = tmp_path / "run"
    shutil.copytree(run_folder, folder)
    summary = json.loads((folder / "summary.json").read_text())
    row = summary["instances"][0]
    row["outcome"] = SCRIPT
    row["message"] = "<img src=x onerror=\"document.title='INJECTED'\">"
    row["<b onmouseover=alert(1)>"] = ["<script>x</script>", "javascript:alert(1)"]
    row["requirements"] = {
        SCRIPT: {"satisfied": False, "robustness": -1.0, "violated_at": 0.5, "failed": SCRIPT}
    }
    summary["outcomes"] = {SCRIPT: 1}
    (folder / "summary.json").write_text(json.dumps(summary))
    (folder / "modes.svg").write_text(HOSTILE_SVG)
    return folder


def test_a_hostile_run_folder_gives_an_inert_page(run_folder, tmp_path, capsys):
    folder = hostile_folder(run_folder, tmp_path)
    assert main(["report", str(folder), "--no-animation"]) == 0
    page = Page((folder / "report.html").read_text(encoding="utf-8"))
    assert page.inert(), (page.scripts, page.handlers, page.js_urls)
    assert "svg" not in page.tags  # no file's markup is inlined, ours neither
    # every injected string is shown as text, not dropped
    text = "".join(page.text)
    for shown in (
        SCRIPT,
        "<img src=x onerror=",
        "<b onmouseover=alert(1)>",
        "<script>x</script> / javascript:alert(1)",
    ):
        assert shown in text
    # the diagram is the folder's file, byte for byte, as an image
    svgs = [
        base64.b64decode(src.split(",", 1)[1])
        for src in page.images
        if src.startswith("data:image/svg+xml;base64,")
    ]
    assert HOSTILE_SVG.encode() in svgs and len(svgs) == 3  # diagram, timeline, trajectories


# summary.json as one JSON line per key, so each bad field's line and column are known
GOOD = {
    "team": "ping",
    "n": 1,
    "seed": 0,
    "duration": 1.0,
    "outcomes": {"ok": 1},
    "instances": [
        {
            "instance": 0,
            "outcome": "ok",
            "requirements": {"r": {"satisfied": True, "robustness": 1.0}},
        }
    ],
}


def summary_text(**changes) -> str:
    data = dict(GOOD, **changes)
    return (
        "{\n" + ",\n".join(f"  {json.dumps(k)}: {json.dumps(v)}" for k, v in data.items()) + "\n}\n"
    )


@pytest.mark.parametrize(
    "changes, where, message",
    [
        ({"seed": SCRIPT}, "4:11", "seed: Input should be a valid integer"),
        ({"n": "1"}, "3:8", "n: Input should be a valid integer"),
        ({"instances": {"0": {}}}, "7:16", "instances: Input should be a valid list"),
        (
            {
                "instances": [
                    {"instance": 0, "outcome": "ok", "requirements": {"r": {"satisfied": "yes"}}}
                ]
            },
            "7:86",
            "instances[0].requirements.r.satisfied: Input should be a valid boolean",
        ),
        ({"instances": [{"instance": 0}]}, "7:17", "instances[0].outcome: Field required"),
    ],
)
def test_a_summary_of_the_wrong_shape_is_refused_at_its_line(
    run_folder, tmp_path, capsys, changes, where, message
):
    folder = tmp_path / "run"
    shutil.copytree(run_folder, folder)
    (folder / "summary.json").write_text(summary_text(**changes))
    assert main(["report", str(folder), "--no-animation"]) == 2
    err = capsys.readouterr().err
    assert (
        err == f"hybridteam: error: {folder}/summary.json:{where}: not a run summary: {message}\n"
    )
    assert not (folder / "report.html").exists()


def test_the_summary_text_helper_is_a_valid_summary(run_folder, tmp_path, capsys):
    """The control of the case above: the unchanged text is read, and the page written."""
    folder = tmp_path / "run"
    shutil.copytree(run_folder, folder)
    (folder / "summary.json").write_text(summary_text())
    assert main(["report", str(folder), "--no-animation"]) == 0


@pytest.mark.parametrize(
    "name, kind", [("modes.svg", "an SVG image (<svg> markup)"), ("run.gif", "a GIF image")]
)
def test_a_folder_image_that_is_another_file_is_not_copied_in(
    run_folder, tmp_path, capsys, name, kind
):
    """``modes.svg`` or ``run.gif`` linked to a private file: refused, its text nowhere."""
    folder = tmp_path / "run"
    shutil.copytree(run_folder, folder)
    secret = tmp_path / "secret.txt"
    secret.write_text("DB_PASSWORD: hunter2\n")
    (folder / name).symlink_to(secret)
    assert main(["report", str(folder)]) == 2
    err = capsys.readouterr().err
    assert (
        err == f"hybridteam: error: {folder / name}: not {kind}; refusing to copy it "
        "into the report\n"
    )
    assert not (folder / "report.html").exists()


@pytest.mark.parametrize("name", ["modes.svg", "summary.json"])
def test_a_folder_file_past_the_size_limit_is_refused_unread(
    run_folder, tmp_path, capsys, monkeypatch, name
):
    """A ``modes.svg`` or ``summary.json`` of gigabytes was read whole into memory: the
    files of a run folder are read up to the traces' limit (HYBRIDTEAM_MAX_TRACE_MB)."""
    folder = tmp_path / "run"
    shutil.copytree(run_folder, folder)
    if name == "modes.svg":
        (folder / name).write_text(
            '<svg xmlns="http://www.w3.org/2000/svg">' + " " * 3_000_000 + "</svg>"
        )
    else:  # the same summary, padded with spaces after its JSON
        (folder / name).write_text((folder / name).read_text() + " " * 3_000_000)
    size = (folder / name).stat().st_size
    monkeypatch.setenv("HYBRIDTEAM_MAX_TRACE_MB", "2")
    assert main(["report", str(folder), "--no-animation"]) == 2
    assert capsys.readouterr().err == (
        f"hybridteam: error: {folder / name}: file is {size / 1e6:.1f} MB; files of a run "
        "folder are read up to 2 MB (set HYBRIDTEAM_MAX_TRACE_MB to read larger ones)\n"
    )
    assert not (folder / "report.html").exists()
    monkeypatch.setenv("HYBRIDTEAM_MAX_TRACE_MB", "4")  # the control: within the limit
    assert main(["report", str(folder), "--no-animation"]) == 0


def test_a_graphviz_diagram_whose_title_quotes_markup_is_still_an_image(run_folder, tmp_path):
    """Graphviz opens its SVG with comments naming the graph, which may hold ``-->``: the
    check that a ``modes.svg`` is an SVG must not refuse it (it is an image anyway)."""
    folder = tmp_path / "run"
    shutil.copytree(run_folder, folder)
    svg = (
        '<?xml version="1.0" encoding="UTF-8" standalone="no"?>\n<!DOCTYPE svg PUBLIC '
        '"-//W3C//DTD SVG 1.1//EN"\n "http://www.w3.org/Graphics/SVG/1.1/DTD/svg11.dtd">'
        "\n<!-- Generated by graphviz -->\n<!-- Title: a --> <b> Pages: 1 -->\n"
        '<svg width="8pt" height="8pt" xmlns="http://www.w3.org/2000/svg"></svg>\n'
    )
    (folder / "modes.svg").write_text(svg)
    assert main(["report", str(folder), "--no-animation"]) == 0
    page = Page((folder / "report.html").read_text(encoding="utf-8"))
    assert "data:image/svg+xml;base64," + base64.b64encode(svg.encode()).decode() in page.images


# --- message names are identifiers, located -------------------------------------------


@pytest.mark.parametrize(
    "yaml_name, shown",
    [
        ('"<script>alert(1)</script>"', "'<script>alert(1)</script>'"),
        ("\"%%{init: {'theme': 'dark'}}%%\"", "\"%%{init: {'theme': 'dark'}}%%\""),
        ('"<img src=x onerror=alert(1)>"', "'<img src=x onerror=alert(1)>'"),
    ],
)
def test_a_message_name_that_is_not_an_identifier_is_refused(tmp_path, capsys, yaml_name, shown):
    team = tmp_path / "team.yaml"
    team.write_text(PING.replace("{send: ping}", "{send: " + yaml_name + "}"))
    assert main(["validate", str(team)]) == 2
    assert capsys.readouterr().err == (
        f"{team}:10:45: agents.a.modes.A.transitions[0].do[0].send: message name {shown} is "
        "not valid: use letters, digits and _, not starting with a digit\n"
    )


@pytest.mark.parametrize(
    "old, new, where, what",
    [
        (
            "after: 0.5,",
            'after: 0.5, on: "go\\n",',
            "10:37",
            "agents.a.modes.A.transitions[0].on: message or event name 'go\\n'",
        ),
        (
            "{send: ping}",
            '{send: ping, socket: "%%{x}%%"}',
            "10:59",
            "agents.a.modes.A.transitions[0].do[0].socket: socket name '%%{x}%%'",
        ),
        (
            "{send: ping}",
            '{raise: "a<b"}',
            "10:46",
            "agents.a.modes.A.transitions[0].do[0].raise: event name 'a<b'",
        ),
        (
            "{send: ping}",
            '{raise: "a..b"}',
            "10:46",  # dotted event names join names
            "agents.a.modes.A.transitions[0].do[0].raise: event name 'a..b'",
        ),
    ],
)
def test_other_names_in_actions_are_identifiers(tmp_path, capsys, old, new, where, what):
    """A trailing newline included: ``$`` in the name pattern used to let ``go\\n`` by."""
    team = tmp_path / "team.yaml"
    team.write_text(PING.replace(old, new))
    assert main(["validate", str(team)]) == 2
    dots = " (names may be joined by dots: error.io)" if "event name" in what else ""
    assert capsys.readouterr().err == (
        f"{team}:{where}: {what} is not valid: use letters, "
        f"digits and _, not starting with a digit{dots}\n"
    )


PROTOCOL = """\
kind: protocol
protocol: p
messages:
  hello: {fields: [x]}
region:
  roles: [go]
  initial: Going
  modes:
    Going: {role: go}
"""


@pytest.mark.parametrize(
    "old, new, where, what",
    [
        ("roles: [go]", 'roles: ["<b>go"]', "6:10", "region.roles: role name '<b>go'"),
        ("    Going:", '    "Going<br>":', "9:5", "region.modes: mode name 'Going<br>'"),
        ("fields: [x]", 'fields: ["x%%{"]', "4:19", "messages.hello.fields: field name 'x%%{'"),
        ("  hello:", '  "hello<i>":', "4:3", "messages: message name 'hello<i>'"),
    ],
)
def test_names_a_protocol_declares_are_identifiers(tmp_path, capsys, old, new, where, what):
    """Roles, region modes and message fields were not checked at all before."""
    protocol = tmp_path / "p.yaml"
    protocol.write_text(PROTOCOL.replace(old, new))
    assert main(["validate", str(protocol)]) == 2
    assert capsys.readouterr().err == (
        f"{protocol}:{where}: {what} is not valid: use "
        "letters, digits and _, not starting with a digit\n"
    )


def test_the_protocol_of_the_case_above_is_valid(tmp_path, capsys):
    protocol = tmp_path / "p.yaml"
    protocol.write_text(PROTOCOL)
    assert main(["validate", str(protocol)]) == 0


# --- diagrams: what a trace or a team names is inert text -----------------------------

MERMAID_TAG = re.compile(r"<[A-Za-z/!?]")
CONTROL = re.compile(r"[\x00-\x08\x0b-\x1f\x7f-\x9f]")  # what a terminal acts on


def hostile_trace(run_folder: Path, kind: str, name: str) -> Trace:
    """The run's trace with every message's ``type`` (or the team's name) set to ``name``,
    as a trace file handed over could have it."""
    data = json.loads((run_folder / "trace.json").read_text())
    if kind == "type":
        data["messages"]["type"] = [name] * len(data["messages"]["type"])
    else:
        data["meta"]["team"] = name
    return Trace.from_dict(data)


def mermaid_is_ours(text: str) -> None:
    """A sequence chart's Mermaid: our statements only, no directive, no tag, nothing a
    terminal it is printed on would act on."""
    assert not CONTROL.search(text), text
    assert "%%" not in text  # a sequence chart writes no comment, so none is ours
    assert not MERMAID_TAG.search(text), text
    lines = text.splitlines()
    assert lines[0] == "sequenceDiagram"
    for line in lines[1:]:
        assert re.match(
            r"    (participant \w+( as [^\n]*)?|\w+(->>|-x)\w+: .*|Note over .*)$", line
        ), line


def plantuml_is_ours(text: str) -> None:
    assert not CONTROL.search(text), text
    assert not re.search(r"<[A-Za-z/!?&$]|\[\[", text), text
    lines = text.splitlines()
    assert lines[:2] == ["@startuml", "hide footbox"] and lines[-1] == "@enduml"
    assert not any(ln.startswith(("!", "@")) for ln in lines[2:-1])


@pytest.mark.parametrize(
    "name",
    [
        "%%{init: {'theme': 'dark'}}%%",
        "%%%{init: {'securityLevel': 'loose'}}%%%",
        "<img src=x onerror=alert(1)>",
        "</pre><script>alert(1)</script>",
        "a;b#lt;c\nd",
        "\x1b]0;PWNED\x07\x1b[31mred",
    ],
)
def test_a_trace_s_message_names_are_inert_in_the_sequence_chart(run_folder, name):
    trace = hostile_trace(run_folder, "type", name)
    text = sequence_chart(trace, "mermaid")
    mermaid_is_ours(text)
    assert len(re.findall(r"\w+->>\w+: ", text)) == 1  # the one ping, still there
    plantuml_is_ours(sequence_chart(trace, "plantuml"))


def test_plantuml_text_opens_no_creole_tag_or_link(run_folder):
    trace = hostile_trace(run_folder, "type", "<img:/etc/passwd> [[javascript:alert(1)]]")
    text = sequence_chart(trace, "plantuml")
    plantuml_is_ours(text)
    assert "< img:/etc/passwd> [ [javascript:alert(1)]]" in text  # shown, made inert


def test_a_team_name_is_inert_in_state_diagram_text(tmp_path, capsys):
    """The team's name is free text; in Mermaid it is a comment, where a ``%%{`` would
    still be read as a directive (``%%%`` once slipped through as ``%%``)."""
    team = tmp_path / "team.yaml"
    team.write_text(
        PING.replace("team: ping", "team: \"%%%{init: {'theme': 'dark'}}%%% <script>x\"")
    )
    assert main(["diagram", str(team), "-f", "mermaid"]) == 0
    text = capsys.readouterr().out
    lines = text.splitlines()
    assert lines[1] == "    %% team %{init∶ {'theme'∶ 'dark'}}% < script>x"
    assert "%%{" not in text and not MERMAID_TAG.search(text)
    assert main(["diagram", str(team), "-f", "plantuml"]) == 0
    assert "title %%%{init: {'theme': 'dark'}}%%% < script>x" in capsys.readouterr().out


# --- the terminal: control characters are shown, not run ------------------------------


def test_an_error_quoting_a_name_escapes_its_control_characters(tmp_path, capsys):
    team = tmp_path / "team.yaml"
    team.write_text(PING.replace("  b:\n", '  b:\n    initial: "Q\\e]0;PWNED\\a\\e[31mX"\n'))
    assert main(["validate", str(team)]) == 2
    err = capsys.readouterr().err
    assert (
        err == f"{team}:13:14: agents.b.initial: unknown initial mode "
        "'Q\\x1b]0;PWNED\\x07\\x1b[31mX'\n"
    )
    assert not CONTROL.search(err)


def test_a_team_name_with_control_characters_is_refused(tmp_path, capsys):
    team = tmp_path / "team.yaml"
    team.write_text(PING.replace("team: ping", 'team: "t\\e[2J\\rx"'))
    assert main(["validate", str(team)]) == 2
    assert capsys.readouterr().err == (
        f"{team}:1:7: team: team name 't\\x1b[2J\\rx' has "
        "control characters or lone surrogates; write it as "
        "plain text\n"
    )


def test_a_file_name_with_control_characters_is_shown_escaped(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["validate", "\x1b]0;PWNED\x07.yaml"]) == 2
    assert capsys.readouterr().err == (
        "\\x1b]0;PWNED\\x07.yaml: cannot read file: No such file or directory\n"
    )


def test_a_bad_argument_is_shown_escaped(tmp_path, capsys):
    with pytest.raises(SystemExit) as stop:
        main(["timeline", "t.json", "\x1b]0;PWNED\x07"])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert err.splitlines()[-1] == ("hybridteam: error: unrecognized arguments: \\x1b]0;PWNED\\x07")
    assert not CONTROL.search(err)


def test_validate_shows_a_file_name_s_control_characters_escaped(tmp_path, capsys, monkeypatch):
    """``hybridteam validate *.yaml`` in a folder handed over: a file's name is not run."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "\x1b[31mt.yaml").write_text(PING)
    assert main(["validate", "\x1b[31mt.yaml"]) == 0
    assert capsys.readouterr().out == "\\x1b[31mt.yaml: ok (team)\n"


def test_a_library_warning_quoting_a_name_is_escaped(run_folder, tmp_path):
    """A trace's team name with ESC and BEL titles the plot; matplotlib warns that the font
    has no such glyph, quoting the character: the warning shows it escaped."""
    data = json.loads((run_folder / "trace.json").read_text())
    data["meta"]["team"] = "t\x1b]0;PWNED\x07"
    trace = tmp_path / "trace.json"
    trace.write_text(json.dumps(data))
    # a process of its own: in-process, pytest would record the warning instead
    done = subprocess.run(
        [sys.executable, "-m", "hybridteam.cli", "plot", str(trace), "-o", str(tmp_path / "p.png")],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    err = done.stderr
    assert "Glyph 27 (\\x1b) missing from font" in err  # the warning is there, escaped
    assert not CONTROL.search(err)


# --- requirements_from: a file that is not a requirements document --------------------


def test_requirements_from_a_private_file_does_not_print_it(tmp_path, capsys):
    secret = tmp_path / "secret.txt"
    secret.write_text("DB_PASSWORD: hunter2\nAPI_TOKEN: s3cr3t\n")
    (tmp_path / "reqs.yaml").symlink_to(secret)
    team = tmp_path / "team.yaml"
    team.write_text(PING.replace("agents:", "requirements_from: [reqs.yaml]\nagents:", 1))
    assert main(["validate", str(team)]) == 2
    err = capsys.readouterr().err
    assert err == (
        f"{team}:2:21: requirements_from[0]: '{tmp_path / 'reqs.yaml'}' is not a "
        "requirements document (expected 'kind: requirements' and a "
        "'requirements:' mapping of named formulas)\n"
    )


def test_requirements_from_a_requirements_document_still_reads_it(tmp_path, capsys):
    """The control: a real requirements file is read (and its own errors located in it)."""
    (tmp_path / "reqs.yaml").write_text(
        "kind: requirements\nrequirements:\n  calm: always(x <= 2)\n  oops: 1\n"
    )
    team = tmp_path / "team.yaml"
    team.write_text(PING.replace("agents:", "requirements_from: [reqs.yaml]\nagents:", 1))
    assert main(["validate", str(team)]) == 2
    assert f"{tmp_path / 'reqs.yaml'}:4:9: requirements.oops" in capsys.readouterr().err


# --- fuzz: random hostile names through the report and the sequence chart ------------

HOSTILE_PARTS = [
    "<",
    ">",
    "</",
    "<script>",
    "</script>",
    "<img src=x onerror=alert(1)>",
    "<svg onload=alert(1)>",
    "javascript:",
    "%%",
    "%%{",
    "}%%",
    "%{init: {}}%",
    "&lt;",
    "#lt;",
    "'",
    '"',
    ";",
    ":",
    "#",
    "\n",
    "\r",
    "\x1b",
    "[[",
    "]]",
    "`",
    "{",
    "}",
    "=",
    "on",
    "a",
    " ",
]
HOSTILE = st.lists(
    st.sampled_from(HOSTILE_PARTS) | st.text(max_size=3), min_size=1, max_size=8
).map("".join)
FUZZ = settings(
    max_examples=60,
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)


@FUZZ
@given(names=st.lists(HOSTILE, min_size=3, max_size=3))
def test_fuzz_sequence_chart_is_ours(run_folder, names):
    data = json.loads((run_folder / "trace.json").read_text())
    data["messages"]["type"] = [names[0]] * len(data["messages"]["type"])
    data["messages"]["reason"] = [names[1]] * len(data["messages"]["reason"])
    data["meta"]["team"] = names[2]
    trace = Trace.from_dict(data)
    mermaid_is_ours(sequence_chart(trace, "mermaid"))
    plantuml_is_ours(sequence_chart(trace, "plantuml"))


@FUZZ
@given(names=st.lists(HOSTILE, min_size=6, max_size=6))
def test_fuzz_report_is_inert(run_folder, tmp_path_factory, monkeypatch, names):
    """The report of a folder whose every string is hostile (summary and trace): no script
    element, no event handler, no javascript: URL; every name shown as text. The figures
    are drawn as blanks here (they are images whatever they show, and drawing them would
    make the fuzz slow)."""
    from hybridteam.export import report

    def blank(trace, path, **kwargs):
        Path(path).write_text("<svg xmlns='http://www.w3.org/2000/svg'/>")

    monkeypatch.setattr("hybridteam.export.timeline.write_timeline", blank)
    monkeypatch.setattr("hybridteam.export.trajectories.write_trajectories", blank)
    data = json.loads((run_folder / "trace.json").read_text())
    data["meta"]["team"] = names[0]
    data["messages"]["type"] = [names[1]] * len(data["messages"]["type"])
    trace = Trace.from_dict(data)
    summary = json.loads((run_folder / "summary.json").read_text())
    summary["instances"][0].update({"outcome": names[2], names[3]: [names[4], 1.5]})
    summary["instances"][0]["requirements"] = {
        names[5]: {"satisfied": False, "violated_at": 0.5, "failed": names[4]}
    }
    summary["outcomes"] = {names[2]: 1}
    out = tmp_path_factory.mktemp("fuzz") / "report.html"
    report.write_report(run_folder, trace, summary, out, animation=False)
    page = Page(out.read_text(encoding="utf-8"))
    assert page.inert(), (page.scripts, page.handlers, page.js_urls)
    assert set(page.tags) <= {
        "html",
        "head",
        "meta",
        "title",
        "style",
        "body",
        "h1",
        "h2",
        "section",
        "p",
        "table",
        "tr",
        "th",
        "td",
        "code",
        "div",
        "img",
        "pre",
    }
    text = "".join(page.text)
    for name in names[2:6]:
        assert name.replace("\r\n", "\n").replace("\r", "\n") in text.replace("\r\n", "\n")


# --- a real browser: nothing from the folder runs ------------------------------------

CHROMIUM = shutil.which("chromium") or (
    "/usr/bin/chromium" if Path("/usr/bin/chromium").exists() else None
)


@pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed")
def test_no_script_of_a_hostile_folder_runs_in_chromium(run_folder, tmp_path, capsys):
    folder = hostile_folder(run_folder, tmp_path)
    assert main(["report", str(folder), "--no-animation"]) == 0
    dom = subprocess.run(
        [
            CHROMIUM,
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            f"--user-data-dir={tmp_path / 'profile'}",
            "--dump-dom",
            (folder / "report.html").as_uri(),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert dom.returncode == 0, dom.stderr[-2000:]
    assert "<title>ping — hybridteam run</title>" in dom.stdout  # the title we wrote
    assert "INJECTED" not in dom.stdout.split("</title>")[0]


# --- a study folder read back into report.md --------------------------------------------


def _study_folder(tmp_path, name, rows):
    from hybridteam.sweep.store import FORMAT

    out = tmp_path / "study"
    out.mkdir()
    (out / "study.json").write_text(
        json.dumps(
            {
                "format": FORMAT,
                "status": "complete",
                "name": name,
                "team": "t`](javascript:alert(1))",
                "runs": 4,
                "chunks": 1,
                "chunk": 4,
                "seed": 1,
                "success": ["ok<img src=x onerror=alert(1)>"],
                "versions": {"<script>alert(2)</script>": "1"},
            }
        )
    )
    (out / "results.csv").write_text(rows)
    return out


def test_a_study_report_carries_no_markup_from_the_folder(tmp_path, capsys):
    """``report`` of a study folder wrote study.json's values and the folder's results.md
    into report.md as they were: a Markdown renderer passes raw HTML through and turns
    ``[x](javascript:…)`` into a link. Every value is now inert text."""
    out = _study_folder(
        tmp_path,
        "<script>alert(1)</script>",
        (
            "factor,value,runs,ok,success_rate\n"
            "p,<script>alert(3)</script>,2,1,0.5\n"
            "p,[x](javascript:alert(4)),2,2,1.0\n"
        ),
    )
    (out / "results.md").write_text("<script>alert(5)</script>\n")
    assert main(["report", str(out)]) == 0
    report = (out / "report.md").read_text(encoding="utf-8")
    ours = r"^!\[success rate against p\]\(plots/success_p\.png\)$"  # the plot's image
    assert len(re.findall(ours, report, flags=re.M)) == 1
    report = re.sub(ours, "", report, flags=re.M)
    assert "<" not in report  # no tag of any kind
    assert not re.search(r"(?<!\\)\]\(", report)  # no link: every ']' before '(' escaped
    assert "alert(5)" not in report  # the folder's results.md is not copied in
    assert "# &lt;script&gt;alert(1)&lt;/script&gt;" in report
    assert "| p | \\[x\\](javascript:alert(4)) | 2 | 2 | 1 |" in report


def test_a_results_file_without_its_columns_is_one_line(tmp_path, capsys):
    out = _study_folder(tmp_path, "s", "a,b\n1,2\n")
    assert main(["report", str(out)]) == 2
    err = capsys.readouterr().err
    assert (
        err.strip().endswith("results.csv: cannot read (no 'factor' column: not a study's results)")
        and len(err.strip().splitlines()) == 1
    )
