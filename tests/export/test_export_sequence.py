"""Message sequence charts: participants, arrow order and direction, lost messages."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

import hybridteam as ht
from hybridteam.export.sequence import latency, sequence_chart
from hybridteam.trace import (
    INTERVAL_COLUMNS,
    MESSAGE_COLUMNS,
    TRANSITION_COLUMNS,
    Table,
    Trace,
)
from tests.conftest import EXAMPLES

MERMAID_ARROW = re.compile(r"^\s*(\w+)(->>|-x)(\w+): (.*)$")
PLANTUML_ARROW = re.compile(r"^(\w+) (->|->x) (\w+) : (.*)$")


def arrows(text: str, pattern: re.Pattern) -> list[tuple[str, str, str, str]]:
    return [m.groups() for ln in text.splitlines() if (m := pattern.match(ln))]


def send_time(label: str) -> float:
    return float(re.search(r"@ (\d+\.\d{3}) s", label).group(1))


@pytest.fixture(scope="module")
def relay_run() -> ht.Run:
    return ht.simulate(ht.load(EXAMPLES / "automata" / "relay.yaml"))


def test_relay_chart_in_mermaid(relay_run):
    text = sequence_chart(relay_run)
    lines = text.splitlines()
    assert lines[0] == "sequenceDiagram"
    assert lines.index("    participant runner") < lines.index("    participant anchor")
    found = arrows(text, MERMAID_ARROW)
    assert [(a, arrow, b) for a, arrow, b, _ in found] == [
        ("runner", "->>", "anchor"),
        ("anchor", "->>", "runner"),
    ]
    assert found[0][3] == "baton @ 5.000 s" and found[1][3].startswith("done @ 8.142 s")
    times = [send_time(label) for *_, label in found]
    assert times == sorted(times)


def test_relay_chart_in_plantuml(relay_run):
    text = sequence_chart(relay_run, "plantuml")
    assert text.startswith("@startuml\n") and text.rstrip().endswith("@enduml")
    assert "participant runner\nparticipant anchor\n" in text
    found = arrows(text, PLANTUML_ARROW)
    assert [(a, b) for a, _, b, _ in found] == [("runner", "anchor"), ("anchor", "runner")]


def synthetic(n: int = 2) -> Trace:
    """A hand-made run of two agents: latencies, a loss, a retransmission, other traffic."""
    rows = [  # instance, seq, sender, receiver, socket, type, t_send, t_recv, status, reason,
        # msg_id
        (0, 3, "b", "a", "control", "ack", 2.6, 2.61, "delivered", "", -1),
        (0, 0, "a", "b", "control", "req", 1.0, 1.03, "delivered", "", -1),
        (0, 1, "a", "b", "control", "req", 2.0, math.nan, "lost", "dropped by link", -1),
        (0, 2, "a", "b", "control", "req", 2.5, 2.55, "delivered", "retransmission", -1),
        (0, 4, "a", "b", "data", "pose", 0.5, 0.5, "delivered", "", -1),
        (1, 0, "b", "a", "control", "other", 0.1, 0.1, "delivered", "", -1),
    ]
    data = {c: [r[k] for r in rows] for k, c in enumerate(MESSAGE_COLUMNS)}
    meta = {
        "team": "synthetic",
        "n": n,
        "seed": 0,
        "duration": 3.0,
        "agents": [{"name": "a", "state": []}, {"name": "b", "state": []}],
    }
    return Trace(
        meta,
        [{"outcome": "ok"}] * n,
        Table(TRANSITION_COLUMNS),
        Table(INTERVAL_COLUMNS),
        Table(MESSAGE_COLUMNS, data),
        np.zeros(0),
        {},
    )


def test_synthetic_chart_marks_loss_retransmission_and_latency():
    text = sequence_chart(synthetic())
    found = arrows(text, MERMAID_ARROW)
    assert [(a, arrow, b) for a, arrow, b, _ in found] == [
        ("a", "->>", "b"),
        ("a", "-x", "b"),
        ("a", "->>", "b"),
        ("b", "->>", "a"),
    ]
    first, lost, again, ack = (label for *_, label in found)
    assert first == "req @ 1.000 s (+30 ms)"
    assert lost.startswith("req @ 2.000 s") and "dropped by link" in lost
    assert "(retransmission)" in again and "(+50 ms)" in again
    assert "(retransmission)" not in first + lost + ack and "(+10 ms)" in ack
    assert "#" not in text.split("\n", 3)[-1]  # Mermaid reads '#' as an entity start


def test_synthetic_chart_in_plantuml():
    text = sequence_chart(synthetic(), "plantuml")
    found = arrows(text, PLANTUML_ARROW)
    assert [arrow for _, arrow, _, _ in found] == ["->", "->x", "->", "->"]
    assert "(retransmission)" in found[2][3] and "(+30 ms)" in found[0][3]


def test_sockets_and_instances_select_messages():
    trace = synthetic()
    everything = arrows(sequence_chart(trace, sockets=None), MERMAID_ARROW)
    assert everything[0][3] == "pose @ 0.500 s" and len(everything) == 5
    other = arrows(sequence_chart(trace, instance=1), MERMAID_ARROW)
    assert [(a, b, label) for a, _, b, label in other] == [("b", "a", "other @ 0.100 s")]
    with pytest.raises(ValueError, match="out of range"):
        sequence_chart(trace, instance=2)


def test_empty_chart_is_still_valid():
    trace = synthetic()
    mermaid = sequence_chart(trace, sockets=("nothing",))
    assert mermaid.splitlines() == [
        "sequenceDiagram",
        "    participant a",
        "    participant b",
        "    Note over a,b: no messages",
    ]
    plantuml = sequence_chart(trace, "plantuml", sockets=("nothing",))
    assert "note over a, b : no messages" in plantuml and plantuml.rstrip().endswith("@enduml")


def test_unknown_format_and_latency_text():
    with pytest.raises(ValueError, match="did you mean 'mermaid'"):
        sequence_chart(synthetic(), "mermaids")
    assert latency(1.0, 1.0) == "" and latency(1.0, math.nan) == ""
    assert latency(0.0, 0.25) == "+250 ms" and latency(0.0, 1.5) == "+1.5 s"
    assert latency(0.0, 0.0004) == "+0.4 ms"


def test_a_lost_retransmission_says_so_once():
    """The network records a resent copy it lost as ``loss (retransmission)``: the label
    names the retransmission and the loss once each, not ``(lost: loss (retransmission))
    (retransmission)``; a lost ack's bracketed note is its type, already named."""
    trace = synthetic()  # rows: an ack, then req at 1.0, 2.0 and 2.5 s, then others
    msgs = trace.messages
    msgs.columns["status"] = np.array(
        ["lost", "delivered", "lost", "lost", "delivered", "delivered"], dtype=object
    )
    msgs.columns["reason"] = np.array(
        ["loss (ack)", "", "dropped by link", "loss (retransmission)", "", ""], dtype=object
    )
    msgs.columns["t_recv"] = np.array([math.nan, 1.03, math.nan, math.nan, 0.5, 0.1])
    labels = [label for *_, label in arrows(sequence_chart(trace), MERMAID_ARROW)]
    assert labels == [
        "req @ 1.000 s (+30 ms)",
        "req @ 2.000 s (lost: dropped by link)",
        "req @ 2.500 s (retransmission, lost: loss)",
        "ack @ 2.600 s (lost: loss)",
    ]
