"""``hybridteam live`` on a LAN's terms, tried on loopback: multicast and broadcast groups
(no process lists another), and addresses read from the team file's ``deploy:`` section,
so that ``hybridteam live TEAM.yaml --agent a`` needs no address flag.

Every process a test starts is stopped by it (test_live's ``processes`` fixture).
"""

from __future__ import annotations

import argparse
import socket

import pytest

import hybridteam as ht
from hybridteam.cli import main
from hybridteam.cli.udp import UdpSettings, add_udp_options, check_udp_flags, udp_settings
from hybridteam.live.transport import TransportError, UdpTransport
from hybridteam.model.deploy import UdpDeploy
from hybridteam.trace import Trace
from tests.live.test_live import (
    TEAM,
    TIMEOUT,
    finish,
    free_port,
    mode_sequences,
    processes,
    simulated,
    wait_running,
)

__all__ = ["processes"]  # (the fixture, imported to be used here)

GROUP = "239.255.71.2"
BROADCAST = "127.255.255.255"


def kernel_allows(mode: str, host: str) -> None:
    """Skip, with the kernel's reason, where it refuses the group on loopback."""
    try:
        UdpTransport((host, 0), mode=mode).close()
    except TransportError as exc:
        pytest.skip(f"the kernel refuses UDP {mode} on loopback here: {exc}")


def shake_hands(tmp_path, processes, team, *args: str) -> None:
    """Granter then requester as two processes given ``args`` (the same for both: neither
    names the other); both end as the simulation does, having heard each other. (Both
    end by the end rule; the long duration only keeps the granter running while the
    requester starts, however loaded the machine.)"""
    clock = ("--time-scale", "4", "--duration", "200")
    granter = processes(
        str(team), "--agent", "granter", *args, *clock, "-o", str(tmp_path / "granter")
    )
    wait_running(granter)
    requester = processes(
        str(team), "--agent", "requester", *args, *clock, "-o", str(tmp_path / "requester")
    )
    finish(requester)
    finish(granter)
    expected = simulated()
    for agent in ("requester", "granter"):
        trace = Trace.load(tmp_path / agent / "trace.json")
        assert mode_sequences(trace) == {agent: expected[agent]}
        assert trace.outcomes[0]["outcome"] == "ok"
        assert trace.meta["live"]["datagrams"]["dropped"] == {}
    assert Trace.load(tmp_path / "granter" / "trace.json").messages["type"].tolist() == [
        "request",
        "done",
    ]


@pytest.mark.parametrize(("mode", "host"), [("multicast", GROUP), ("broadcast", BROADCAST)])
def test_two_processes_shake_hands_over_a_group_without_listing_each_other(
    tmp_path, processes, mode, host
):
    kernel_allows(mode, host)
    shake_hands(tmp_path, processes, TEAM, f"--{mode}", f"{host}:{free_port()}")


def with_deploy(tmp_path, deploy: str):
    path = tmp_path / "team.yaml"
    path.write_text(TEAM.read_text() + "deploy:\n" + deploy)
    return path


def test_the_team_file_s_multicast_group_needs_no_address_flag(tmp_path, processes):
    kernel_allows("multicast", GROUP)
    team = with_deploy(tmp_path, f"  udp: {{multicast: '{GROUP}:{free_port()}'}}\n")
    shake_hands(tmp_path, processes, team)


def test_the_team_file_s_listen_and_peers_need_no_address_flag(tmp_path, processes):
    ports = free_port(), free_port()
    team = with_deploy(
        tmp_path,
        (
            f"  udp: {{peers: ['127.0.0.1:{ports[0]}', '127.0.0.1:{ports[1]}']}}\n"
            f"  requester: {{listen: '127.0.0.1:{ports[0]}'}}\n"
            f"  granter: {{listen: '127.0.0.1:{ports[1]}'}}\n"
        ),
    )
    shake_hands(tmp_path, processes, team)


def test_the_deploy_addresses_are_read_and_simulation_ignores_them(tmp_path):
    team = ht.load(
        with_deploy(
            tmp_path,
            (
                "  udp: {multicast: '239.1.2.3:47000', interface: 0.0.0.0}\n"
                "  requester: {listen: '10.0.0.5:47001', cmd_vel: /r/cmd_vel, odom: /r/odom}\n"
                "  granter: {listen: 'granter.local:47002'}\n"
            ),
        )
    )
    assert team.udp == UdpDeploy(
        "multicast",
        group=("239.1.2.3", 47000),
        interface="0.0.0.0",
        listen={"requester": ("10.0.0.5", 47001), "granter": ("granter.local", 47002)},
    )
    assert list(team.deploy) == ["requester"]  # (the granter's entry names no robot)
    assert mode_sequences(ht.simulate(team)) == simulated()


@pytest.mark.parametrize(
    ("deploy", "line", "where", "message"),
    [
        (
            "  udp: {multicast: '10.0.0.1:47000'}\n",
            26,
            "deploy.udp.multicast",
            "'10.0.0.1' is not a multicast group (224.0.0.0 to 239.255.255.255",
        ),
        (
            "  udp: {peers: ['127.0.0.1:1'], broadcast: '127.255.255.255:2'}\n",
            26,
            "deploy.udp",
            "give exactly one of peers, multicast, broadcast (got peers, broadcast)",
        ),
        (
            "  udp: {broadcast: '192.168.1.255:47000', interface: 0.0.0.0}\n",
            26,
            "deploy.udp.interface",
            "goes with multicast only",
        ),
        (
            "  udp: {multicast: '239.1.1.1:47000', interfce: 0.0.0.0}\n",
            26,
            "deploy.udp.interfce",
            "did you mean 'interface'",
        ),
        (
            "  udp:\n    peers: ['127.0.0.1:1', 'robot2']\n",
            27,
            "deploy.udp.peers[1]",
            "expected an address: must be HOST:PORT with a port from 0 to 65535, got 'robot2'",
        ),
        (
            "  granter: {listen: '127.0.0.1:70000'}\n",
            26,
            "deploy.granter.listen",
            "got '127.0.0.1:70000'",
        ),
        (
            "  granter: {lisen: '127.0.0.1:1'}\n",
            26,
            "deploy.granter.lisen",
            "did you mean 'listen'",
        ),
        (
            "  granter: {listen: '127.0.0.1:1', odom: /r/odom}\n",
            26,
            "deploy.granter",
            "missing 'cmd_vel'",
        ),
        ("  upd: {multicast: '239.1.1.1:47000'}\n", 26, "deploy.upd", "did you mean 'udp'"),
    ],
)
def test_a_bad_deploy_address_is_one_located_error(tmp_path, capsys, deploy, line, where, message):
    team = with_deploy(tmp_path, deploy)
    assert TEAM.read_text().count("\n") == 24  # (deploy: is line 25)
    assert main(["validate", str(team)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith(f"{team}:{line}:") and where in err[0] and message in err[0], err[0]


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (
            ["--multicast", f"{GROUP}:1", "--broadcast", f"{BROADCAST}:1"],
            "give --multicast or --broadcast, not both",
        ),
        (
            ["--multicast", f"{GROUP}:1", "--peer", "127.0.0.1:1"],
            "--multicast: every process shares the group's port; --listen and --peer are for "
            "listing peers instead",
        ),
        (["--multicast", "239.255.71.2"], "--multicast must be HOST:PORT"),
        (["--multicast", "10.0.0.1:47000"], "UDP multicast: '10.0.0.1' is not a multicast group"),
        (
            ["--broadcast", "10.1.2.255:47000"],
            "cannot listen on UDP broadcast 10.1.2.255:47000: Cannot assign requested address",
        ),
        (["--interface", "0.0.0.0"], "--interface is where a multicast group is joined"),
    ],
)
def test_bad_group_flags_are_one_line(tmp_path, processes, args, message):
    proc = processes(str(TEAM), "--agent", "granter", *args, "-o", str(tmp_path / "x"))
    _, err = proc.communicate(timeout=TIMEOUT)
    assert proc.returncode == 2
    lines = err.decode().strip().splitlines()
    assert len(lines) == 1 and message in lines[0], lines
    assert not (tmp_path / "x").exists()


def test_a_group_port_taken_without_sharing_is_one_line(tmp_path, processes):
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as holder:
        holder.bind(("", 0))
        port = holder.getsockname()[1]
        proc = processes(
            str(TEAM),
            "--agent",
            "granter",
            "--multicast",
            f"{GROUP}:{port}",
            "-o",
            str(tmp_path / "x"),
        )
        _, err = proc.communicate(timeout=TIMEOUT)
    assert proc.returncode == 2
    assert err.decode().strip() == (
        f"hybridteam: error: UDP multicast {GROUP}:{port} is "
        "taken (another process listens there without sharing "
        "the port)"
    )
    assert not (tmp_path / "x").exists()


def test_agents_of_one_process_listening_apart_in_the_file_is_one_line(tmp_path, processes):
    team = with_deploy(
        tmp_path, "  requester: {listen: '127.0.0.1:1'}\n  granter: {listen: '127.0.0.1:2'}\n"
    )
    proc = processes(
        str(team), "--agent", "requester", "--agent", "granter", "-o", str(tmp_path / "x")
    )
    _, err = proc.communicate(timeout=TIMEOUT)
    assert proc.returncode == 2
    assert err.decode().strip() == (
        "hybridteam: error: the agents here listen on different addresses in the team "
        "file's deploy: (requester: 127.0.0.1:1, granter: 127.0.0.1:2); give --listen"
    )


def settings(team, agents: list[str], *flags: str) -> UdpSettings:
    """What ``hybridteam live`` would open for ``flags`` (its own parser)."""
    parser = argparse.ArgumentParser()
    add_udp_options(parser)
    args = parser.parse_args(list(flags))
    check_udp_flags(args)
    return udp_settings(args, team, agents)


def test_flags_replace_what_they_name_in_the_file(tmp_path):
    peers = "  udp: {peers: ['10.0.0.1:47000', '10.0.0.2:47000']}\n"
    listen = "  requester: {listen: '10.0.0.1:47000'}\n  granter: {listen: '10.0.0.2:47000'}\n"
    team = ht.load(with_deploy(tmp_path, peers + listen))
    file_peers = (("10.0.0.1", 47000), ("10.0.0.2", 47000))
    assert settings(team, ["granter"]) == UdpSettings("unicast", ("10.0.0.2", 47000), file_peers)
    # --listen replaces the agent's address only; --peer the file's peers only
    assert settings(team, ["granter"], "--listen", "127.0.0.1:5") == UdpSettings(
        "unicast", ("127.0.0.1", 5), file_peers
    )
    assert settings(team, ["granter"], "--peer", "127.0.0.1:6") == UdpSettings(
        "unicast", ("10.0.0.2", 47000), (("127.0.0.1", 6),)
    )
    # a group flag replaces the file's udp as a whole
    assert settings(team, ["granter"], "--broadcast", "127.255.255.255:7") == UdpSettings(
        "broadcast", ("127.255.255.255", 7)
    )
    # the world process (no agent) has no listen in the file: the default
    assert settings(team, []) == UdpSettings("unicast", ("127.0.0.1", 47000), file_peers)
    group = ht.load(
        with_deploy(tmp_path, "  udp: {multicast: '239.1.1.1:9', interface: 0.0.0.0}\n" + listen)
    )
    assert settings(group, ["granter"]) == UdpSettings(
        "multicast", ("239.1.1.1", 9), interface="0.0.0.0"
    )
    assert settings(group, ["granter"], "--interface", "127.0.0.1") == UdpSettings(
        "multicast", ("239.1.1.1", 9), interface="127.0.0.1"
    )
    # --listen leaves the file's group: this process is on its own port, no peer
    assert settings(group, ["granter"], "--listen", "127.0.0.1:5") == UdpSettings(
        "unicast", ("127.0.0.1", 5)
    )
    # nothing anywhere: loopback's default port, no peer
    assert settings(ht.load(TEAM), ["granter"]) == UdpSettings("unicast", ("127.0.0.1", 47000))
