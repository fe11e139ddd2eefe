"""Team datagrams over ROS 2 topics: the ``ros2`` transport of a live team.

An optional extra (``pip install 'hybridteam[ros]'``): nothing here imports rclpy until a
transport is built, so the rest of the live runtime works without it, and building one
without it is one :class:`ImportError` saying what to install.

**Topics.** Socket ``S`` of team ``T`` is the topic ``<namespace>/T/S`` (namespace
``/hybridteam`` by default), so every agent of a team publishes and subscribes to the same
topic per socket, as every agent of a UDP team shares a port. ROS names allow only letters,
digits and single underscores, not starting with a digit: every other run of characters in a
team's or an agent's name becomes one ``_`` (``"Experiment 2: ladder"`` becomes
``Experiment_2_ladder``), a leading digit gets a ``_`` before it. Two teams whose names fold
to the same topic are told apart by the wire format, which carries the team's identity in
every datagram and drops the other team's, as on a shared UDP port.

**Message type.** ``std_msgs/msg/UInt8MultiArray``, its layout left empty: the datagram is
the wire format's bytes, unchanged. Not ``ByteMultiArray``: both carry the same octets on the
wire, but rclpy holds a ``byte[]`` field as a list of one-byte ``bytes`` objects (one Python
object made and checked per byte, each way), a ``uint8[]`` field as one ``array.array``
filled from the datagram in one copy.

**Quality of service** (:func:`socket_qos`), both sockets best-effort, volatile, keep-last:

- Keep the last 64 on both. Best-effort has no resending, so a reader's history only
  holds what arrived before the executor takes it; and that history is the topic's,
  shared by every sender and kind: an instant's stream samples and world poses from every
  teammate at once (``data``), a role-assignment round with every teammate answering
  (``control``). A history of 8 on ``data`` overwrote the oldest of such a burst as soon
  as the executor was held up a moment: experiment 2 launched at time scale 4 lost 1 to
  2 % of the world process's datagrams so (none with 64), where a UDP socket's buffer
  keeps hundreds. A stream sample lost is what the model's streams expect; a reading
  that carried an event is not superseded by the next.
- Best-effort on ``control`` too: control messages get their reliability from the team's
  own acknowledged layer (acks, retries, duplicate suppression, the timeout that calls the
  operator), exactly as over UDP. DDS-reliable delivery underneath would retry on its own
  schedule, hide the losses the protocol was written (and verified) to survive, and hand
  over a datagram after the team has given up on it: the live team would no longer be the
  model ``verify`` checked, and a scripted drop could not replay a counterexample.
- Volatile on both: an agent that joins late must not be handed datagrams sent before it
  started, about a past it did not take part in.

**Own datagrams.** DDS hands a node its own publications; each delivery says which
publisher sent it (its gid), and the transport drops those of its own publishers, so two
agents in one process, each with its own transport, still hear each other.

**Storms.** A datagram larger than a UDP datagram (:data:`MAX_DATAGRAM`), or arriving while
:data:`MAX_WAITING` wait to be taken, is dropped and counted (``dropped``), as a UDP socket
would: anyone on the domain can publish on the team's topics, and the runtime must keep
running whatever they send; what is not dropped here the wire format checks.

**Threads and shutdown.** Each transport has its own node, under the node namespace
``<namespace>/<team>`` and named after the agent (``ros2 node list`` shows
``/hybridteam/T/scout1``), spun by a ``SingleThreadedExecutor`` in one background thread.
A delivery is stamped with ``time.monotonic()`` in that thread, as it arrives, and wakes
:meth:`Ros2Transport.wait`. Unless a context is handed in, a transport initialises rclpy in
a context of its own (on ``domain_id``, else ``ROS_DOMAIN_ID``, else 0) and shuts it down
on :meth:`~Ros2Transport.close`, which is idempotent and leaves no thread behind. rclpy
installs its SIGINT handler (which shuts every context down) only for its default context,
never used here: Ctrl-C stays a ``KeyboardInterrupt`` of the live runtime's, the transport
still open while the runtime completes its trace.
"""

from __future__ import annotations

import logging
import re
import threading
import time
from collections.abc import Sequence
from types import SimpleNamespace
from typing import Any

__all__ = [
    "DEFAULT_NAMESPACE",
    "MAX_DATAGRAM",
    "MAX_WAITING",
    "SOCKET_DEPTH",
    "Ros2Transport",
    "SpunNode",
    "ros_modules",
    "ros_name",
    "socket_qos",
]

log = logging.getLogger(__name__)

DEFAULT_NAMESPACE = "/hybridteam"


#: Keep-last history of each team socket, on its writers and readers: deep enough that a
#: burst from every teammate at once is not overwritten before the executor takes it.
#: Both are best-effort and volatile (see the module's docstring for why).
SOCKET_DEPTH: dict[str, int] = {"data": 64, "control": 64}


#: The largest datagram carried, in bytes: a UDP datagram's payload, so that the team runs
#: alike over either transport (ROS would carry megabytes from anyone on the topic).
MAX_DATAGRAM = 65507

#: Datagrams kept for :meth:`Ros2Transport.receive` at most; more are dropped and counted,
#: as a full socket buffer drops them, so a storm cannot grow the process without bound.
MAX_WAITING = 4096


def socket_qos(socket: str, ros: SimpleNamespace) -> Any:
    """The ``rclpy.qos.QoSProfile`` of a team socket: best-effort, volatile, keep-last
    :data:`SOCKET_DEPTH`."""
    q = ros.qos
    return q.QoSProfile(
        history=q.HistoryPolicy.KEEP_LAST,
        depth=SOCKET_DEPTH[socket],
        reliability=q.ReliabilityPolicy.BEST_EFFORT,
        durability=q.DurabilityPolicy.VOLATILE,
    )


def ros_modules() -> SimpleNamespace:
    """rclpy and the message types used here, or an ImportError saying how to get them."""
    try:
        import rclpy
        import rclpy.qos
        from rclpy.duration import Duration
        from rclpy.executors import SingleThreadedExecutor
        from std_msgs.msg import UInt8MultiArray
    except ImportError:
        raise ImportError(
            "the ros2 transport and plant need rclpy: pip install 'hybridteam[ros]'"
        ) from None
    return SimpleNamespace(
        rclpy=rclpy,
        qos=rclpy.qos,
        Duration=Duration,
        Executor=SingleThreadedExecutor,
        Datagram=UInt8MultiArray,
    )


_NOT_IN_NAME = re.compile(r"[^A-Za-z0-9]+")
_NAMESPACE = re.compile(r"(/[A-Za-z_]([A-Za-z0-9]|_(?!_))*)+/?")


def ros_name(name: str) -> str:
    """``name`` as one token of a ROS name: letters, digits and single underscores, not
    starting with a digit (``"Experiment 2: ladder"`` -> ``Experiment_2_ladder``)."""
    token = "_".join(part for part in _NOT_IN_NAME.split(name) if part)
    if not token:
        raise ValueError(f"{name!r} has no letter or digit to name a ROS topic or node with")
    return f"_{token}" if token[0].isdigit() else token


class SpunNode:
    """One rclpy node spun by a ``SingleThreadedExecutor`` in a background thread.

    Callbacks run in that thread. With ``context=None`` this initialises rclpy in a
    context of its own (``domain_id``, else ``ROS_DOMAIN_ID``) and shuts it down on
    :meth:`close`; a context handed in is left running (its owner shuts it down).
    """

    def __init__(
        self, name: str, namespace: str, *, domain_id: int | None = None, context: Any = None
    ) -> None:
        if domain_id is not None and (
            isinstance(domain_id, bool)
            or not isinstance(domain_id, int)
            or not 0 <= domain_id <= 232
        ):
            raise ValueError(f"ROS domain id must be an integer in 0..232, got {domain_id!r}")
        self.ros = ros = ros_modules()
        self._owns_context = context is None
        if context is None:
            context = ros.rclpy.Context()
            # no args: our command line is not ROS's to read; and rclpy installs no
            # signal handler for a context not its default one, so Ctrl-C stays ours
            ros.rclpy.init(args=[], context=context, domain_id=domain_id)
        self.context = context
        self._closed = False
        self._lock = threading.Lock()
        try:
            self.node = ros.rclpy.create_node(
                name, namespace=namespace, context=context, start_parameter_services=False
            )
        except Exception:
            self._shutdown_context()
            raise
        self.executor = ros.Executor(context=context)
        self.executor.add_node(self.node)
        self._thread = threading.Thread(
            target=self._spin, name=f"ros2 {namespace}/{name}", daemon=True
        )
        self._thread.start()

    def _spin(self) -> None:
        try:
            self.executor.spin()
        except Exception:  # a callback's error must not die silently in this thread
            log.exception("ros2 executor of %s stopped", self.node.get_fully_qualified_name())

    def _shutdown_context(self) -> None:
        if self._owns_context:
            self.context.try_shutdown()

    @property
    def closed(self) -> bool:
        return self._closed

    def close(self) -> None:
        """Stop the executor, join its thread, destroy the node, shut an own context down.
        Idempotent."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
        self.executor.shutdown()
        self._thread.join()
        self.node.destroy_node()
        self._shutdown_context()


class Ros2Transport:
    """A team's datagrams on ROS 2 topics, one topic per socket (the live ``Transport``).

    ``send`` publishes on the socket's topic; every datagram another publisher sends on
    any of ``sockets`` is kept, with its arrival time, until :meth:`receive` takes it.
    """

    def __init__(
        self,
        team: str,
        agent: str,
        sockets: Sequence[str],
        *,
        domain_id: int | None = None,
        namespace: str = DEFAULT_NAMESPACE,
        context: Any = None,
        max_waiting: int = MAX_WAITING,
    ) -> None:
        unknown = [s for s in sockets if s not in SOCKET_DEPTH]
        if unknown or not sockets:
            raise ValueError(
                f"ros2 transport: unknown socket {unknown[0]!r}; the team's "
                f"sockets are {', '.join(SOCKET_DEPTH)}"
                if unknown
                else "ros2 transport: no socket to carry"
            )
        if not _NAMESPACE.fullmatch(namespace):
            raise ValueError(
                f"ros2 transport: namespace {namespace!r} is not a ROS namespace "
                "(/name/name..., each name letters, digits and single "
                "underscores, not starting with a digit)"
            )
        self.team, self.agent = team, agent
        self.topics = {s: f"{namespace.rstrip('/')}/{ros_name(team)}/{s}" for s in sockets}
        self._spun = SpunNode(
            ros_name(agent),
            f"{namespace.rstrip('/')}/{ros_name(team)}",
            domain_id=domain_id,
            context=context,
        )
        self._Datagram = self._spun.ros.Datagram
        self._waiting: list[tuple[bytes, float]] = []
        self._max_waiting = max_waiting
        #: datagrams dropped here, by reason: larger than a UDP datagram, or arriving while
        #: ``max_waiting`` were waiting (a storm the runtime does not drain in time)
        self.dropped = {"oversized": 0, "overflow": 0}
        self._lock = threading.Lock()
        self._arrived = threading.Event()
        node, ros = self._spun.node, self._spun.ros
        try:
            self._publishers = {
                s: node.create_publisher(self._Datagram, topic, socket_qos(s, ros))
                for s, topic in self.topics.items()
            }
            self._own = self._own_gids()
            self._subscriptions = {
                s: node.create_subscription(
                    self._Datagram, topic, self._on_datagram, socket_qos(s, ros)
                )
                for s, topic in self.topics.items()
            }
        except Exception:
            self._spun.close()
            raise
        log.info(
            "ros2 transport of %s on %s",
            node.get_fully_qualified_name(),
            ", ".join(self.topics.values()),
        )

    def _own_gids(self) -> frozenset[bytes]:
        """The gids of this node's publishers, which the deliveries of its own datagrams
        carry (local entities are in the graph as soon as they are made)."""
        node = self._spun.node
        gids = {
            bytes(info.endpoint_gid)
            for topic in self.topics.values()
            for info in node.get_publishers_info_by_topic(topic)
            if info.node_name == node.get_name() and info.node_namespace == node.get_namespace()
        }
        if len(gids) < len(self.topics):
            raise RuntimeError(
                f"ros2 transport: cannot tell this node's own publishers on "
                f"{', '.join(self.topics.values())} from others'"
            )
        return frozenset(gids)

    def _on_datagram(self, msg: Any, info: dict) -> None:
        arrived = time.monotonic()
        gid = info.get("publisher_gid")
        if gid is not None and gid["data"] in self._own:
            return
        if len(msg.data) > MAX_DATAGRAM:
            self.dropped["oversized"] += 1
            return
        with self._lock:
            if len(self._waiting) >= self._max_waiting:
                self.dropped["overflow"] += 1
                return
            self._waiting.append((bytes(msg.data), arrived))
            self._arrived.set()

    def send(self, payload: bytes, socket: str) -> None:
        """Publish one datagram on ``socket``'s topic."""
        if self._spun.closed:
            raise RuntimeError("ros2 transport: send after close")
        try:
            publisher = self._publishers[socket]
        except KeyError:
            raise ValueError(
                f"ros2 transport: no socket {socket!r}; this transport carries "
                f"{', '.join(self._publishers)}"
            ) from None
        if len(payload) > MAX_DATAGRAM:
            raise ValueError(
                f"ros2 transport: a datagram of {len(payload)} bytes; at most "
                f"{MAX_DATAGRAM}, as over UDP"
            )
        msg = self._Datagram()
        msg.data = payload
        publisher.publish(msg)

    def receive(self) -> list[tuple[bytes, float]]:
        """Every datagram waiting, oldest first, each with its arrival (``time.monotonic``).
        Never blocks."""
        with self._lock:
            out, self._waiting = self._waiting, []
            self._arrived.clear()
        return out

    def wait(self, timeout: float) -> bool:
        """Block until a datagram is waiting or ``timeout`` seconds pass; whether one is."""
        return self._arrived.wait(max(timeout, 0.0))

    def peers(self, socket: str) -> int:
        """How many other transports on ``socket`` this one is matched with both ways (its
        writer with their readers, its reader with their writers). Discovery is asynchronous
        and each side matches on its own; until a reader has matched a writer it drops that
        writer's datagrams, so a launcher waits for this before its agents start talking."""
        return (
            min(
                self._publishers[socket].get_subscription_count(),
                self._subscriptions[socket].get_publisher_count(),
            )
            - 1
        )  # less our own

    def close(self) -> None:
        """Stop receiving, destroy the node, shut an own rclpy context down. Idempotent."""
        self._spun.close()

    def __enter__(self) -> Ros2Transport:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
