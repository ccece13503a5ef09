"""A node's attachment to the bus: its Zenoh session, liveliness, inbox, and how it learns that a peer failed.

This is the thin edge of every node: the cores (universe simulator, flight software, ground segment) never see
it. Everything a node receives lands in one inbox, in arrival order, so the node's main loop is a plain
single-threaded loop; Zenoh's callback threads only decode and enqueue.

A peer is declared failed when its liveliness token disappears (the process died or lost its link), when it
publishes a failed ``Shutdown``, or when the node waited longer than the timeout for its answer.
"""

from __future__ import annotations

import logging
import queue
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import zenoh

from contracts.bus import Keys
from contracts.clock import Clock, monotonic_ns
from contracts.errors import DecodeError, NodeFailure
from contracts.exitcodes import EXIT_INTERNAL, EXIT_OK, EXIT_PEER
from contracts.hoptrace import ARRIVED, DECODED, PUBLISH, PUBLISHED, TAKEN, HopTrace, message_mark
from contracts.messages import Message, Shutdown, Status, decode, encode
from contracts.shared_blobs import MIN_SHARED_OCTETS, BlobSharer, SharedBlobError, is_reference, open_blob


@dataclass(frozen=True)
class Received:
    """One decoded message and its blob, as taken from the inbox."""

    key: str
    msg: Message
    blob: bytes | memoryview  # a memoryview: mapped from shared memory (``contracts.shared_blobs``)


@dataclass
class Pending:
    """A request published by ``Attachment.ask``, its answer not yet collected."""

    key: str
    msg: Message
    blob: bytes
    reply_kind: type[Message]
    peer: str
    step: int
    shared: bytes | None  # the reference of its blob in shared memory, until answered


DEPARTURE_GRACE_S = 1.0  # longest wait for the Shutdown of a run that ended normally, after a peer left


class PeerStopped(Exception):
    """A peer ended the run normally (a ``Shutdown`` that is not a failure)."""

    def __init__(self, shutdown: Shutdown) -> None:
        self.shutdown = shutdown
        super().__init__(f"{shutdown.node}: {shutdown.reason}")


class RelayedFailure(NodeFailure):
    """Another node announced a failure (its message already names the node at fault and the time)."""

    def __init__(self, shutdown: Shutdown) -> None:
        self.shutdown = shutdown
        self.node = shutdown.node
        self.sim_time_s = shutdown.sim_time_s
        self.why = shutdown.reason
        Exception.__init__(self, shutdown.reason)


class Attachment:
    """A node on the bus: publish, subscribe, watch peers, wait for messages with a timeout."""

    def __init__(self, session: zenoh.Session, keys: Keys, node: str, clock: Clock, log: logging.Logger,
                 share_blobs: bool = False, trace: HopTrace | None = None) -> None:
        """``share_blobs``: hand large blobs to peers through shared memory (``contracts.shared_blobs``; the peers
        must be on this host); blobs shared by peers are taken either way. ``trace``: marks the time of each
        step-numbered message sent and received (``contracts.hoptrace``), written when the node closes."""
        self.session = session
        self.keys = keys
        self.node = node
        self.clock = clock
        self.log = log
        self.decode_errors = 0
        self.sim_time_s: float | None = None  # last simulated time this node reached, for failure messages
        self._inbox: queue.SimpleQueue[tuple[str, Any]] = queue.SimpleQueue()
        self._alive: set[str] = set()
        self._keep: list[Any] = []
        self._publishers: dict[str, zenoh.Publisher] = {}
        self._token: Any = None
        self._sharer = BlobSharer(keys.run_id) if share_blobs else None
        self.trace = trace
        self._watch(keys.shutdown, Shutdown)

    # -- receiving -----------------------------------------------------------------------------------------
    def subscribe(self, key: str, kind: type[Message]) -> None:
        """Decode every sample on ``key`` as ``kind`` into the inbox; count and log what cannot be decoded."""
        self._watch(key, kind)

    def _watch(self, key: str, kind: type[Message]) -> None:
        trace = self.trace
        arrived, decoded = message_mark(ARRIVED, key), message_mark(DECODED, key)

        def on_sample(sample: zenoh.Sample) -> None:
            t_arrived = monotonic_ns() if trace is not None else 0
            data = sample.payload.to_bytes()
            attachment = sample.attachment
            try:
                msg, blob = decode(kind, data)
                if attachment is not None and is_reference(reference := attachment.to_bytes()):
                    if blob:
                        raise DecodeError(f"{kind.__name__}: a blob in the message and one in shared memory")
                    blob = open_blob(self.keys.run_id, reference)
            except (DecodeError, SharedBlobError) as exc:
                self.decode_errors += 1
                self.log.warning("undecodable message on %s (%d so far): %s", key, self.decode_errors, exc)
                return
            if trace is not None and (step := getattr(msg, "step", None)) is not None:
                trace.mark_at(t_arrived, arrived, step)
                trace.mark(decoded, step)
            self._inbox.put(("msg", Received(str(sample.key_expr), msg, blob)))

        self._keep.append(self.session.declare_subscriber(key, on_sample))

    def watch_peers(self) -> None:
        """Track which nodes are alive from their liveliness tokens (including those already up)."""

        def on_token(sample: zenoh.Sample) -> None:
            node = str(sample.key_expr).rsplit("/", 1)[-1]
            if sample.kind == zenoh.SampleKind.PUT:
                self._inbox.put(("up", node))
            else:
                self._inbox.put(("down", node))

        self._keep.append(self.session.liveliness().declare_subscriber(self.keys.alive_all, on_token, history=True))

    def declare_alive(self) -> None:
        """Announce this node; declared after its subscribers so peers never talk to a deaf node."""
        self._token = self.session.liveliness().declare_token(self.keys.alive(self.node))

    # -- sending -------------------------------------------------------------------------------------------
    def publish(self, key: str, msg: Message, blob: bytes = b"", shared: bytes | None = None) -> None:
        """Publish a message reliably, blocking rather than dropping when the link is congested; ``shared``: the
        reference of its blob in shared memory (the blob then stays out of the message)."""
        pub = self._publishers.get(key)
        if pub is None:
            pub = self.session.declare_publisher(
                key, express=True, congestion_control=zenoh.CongestionControl.BLOCK
            )
            self._publishers[key] = pub
        step = getattr(msg, "step", None) if self.trace is not None else None
        if step is not None:
            self.trace.mark(message_mark(PUBLISH, key), step)  # type: ignore[union-attr]
        if shared is None:
            pub.put(encode(msg, blob))
        else:
            pub.put(encode(msg), attachment=shared)
        if step is not None:
            self.trace.mark(message_mark(PUBLISHED, key), step)  # type: ignore[union-attr]

    def status(self, sim_time_s: float, real_time_factor: float | None = None, mode: str | None = None,
               text: str = "") -> None:
        """Tell whoever watches the run how far this node has got."""
        self.publish(self.keys.status(self.node),
                     Status(node=self.node, sim_time_s=sim_time_s, real_time_factor=real_time_factor,
                            mode=mode, text=text))

    def shutdown(self, reason: str, failed: bool) -> None:
        """Tell every node that the run is over, and why."""
        self.publish(self.keys.shutdown, Shutdown(node=self.node, reason=reason, sim_time_s=self.sim_time_s,
                                                  failed=failed))

    # -- waiting -------------------------------------------------------------------------------------------
    def wait_for_peers(self, nodes: Iterable[str], timeout_s: float) -> None:
        """Return once every node in ``nodes`` is alive; raise NodeFailure naming the first missing one."""
        wanted = set(nodes)
        deadline = self.clock.now() + timeout_s
        while not wanted <= self._alive:
            left = deadline - self.clock.now()
            if left <= 0:
                missing = sorted(wanted - self._alive)[0]
                raise NodeFailure(missing, None, f"did not come up within {timeout_s:g} s")
            self._take(left, return_on_up=True)

    def receive(self, timeout_s: float) -> Received | None:
        """Next message, or None after ``timeout_s``; raise NodeFailure if a peer died or failed."""
        return self._take(timeout_s)

    def ask(self, key: str, msg: Message, blob: bytes, reply_kind: type[Message], peer: str) -> Pending:
        """Publish ``msg`` (a message with a ``step``) and return what ``collect`` needs to wait for its answer; a large
        blob goes through shared memory when this node shares blobs, until the answer comes."""
        shared = self._sharer.share(blob) if self._sharer is not None and len(blob) >= MIN_SHARED_OCTETS else None
        pending = Pending(key, msg, blob, reply_kind, peer, getattr(msg, "step"), shared)
        try:
            self.publish(key, msg, blob, shared)
        except BaseException:
            self._release([pending])
            raise
        return pending

    def collect(self, pending: Sequence[Pending], timeout_s: float, resend_s: float = 0.5) -> list[Received]:
        """Wait for the answer to each of ``pending`` (its ``reply_kind`` for the same ``step``), in any order, and
        return them in the order of ``pending``; resend those still unanswered after ``resend_s`` of silence.

        A reply to another step (a late duplicate) is dropped; an answer missing after ``timeout_s`` is its peer's
        failure. Blobs in shared memory are removed once answered, or on failure.
        """
        answers: list[Received | None] = [None] * len(pending)
        deadline = self.clock.now() + timeout_s
        try:
            while None in answers:
                left = deadline - self.clock.now()
                if left <= 0:
                    late = pending[answers.index(None)]
                    raise NodeFailure(late.peer, self.sim_time_s,
                                      f"stopped answering (no reply to step {late.step} within {timeout_s:g} s)")
                got = self._take(min(resend_s, left))
                if got is None:
                    for p, answer in zip(pending, answers):
                        if answer is None:
                            self.publish(p.key, p.msg, p.blob, p.shared)
                    continue
                for i, p in enumerate(pending):
                    if answers[i] is None and isinstance(got.msg, p.reply_kind) and getattr(got.msg, "step") == p.step:
                        answers[i] = got
                        break
        finally:
            self._release(pending)
        return answers  # type: ignore[return-value]

    def exchange(self, key: str, msg: Message, blob: bytes, reply_kind: type[Message], peer: str,
                 timeout_s: float, resend_s: float = 0.5) -> Received:
        """Publish ``msg`` and wait for the ``reply_kind`` answer to the same ``step`` (``ask``, then ``collect``)."""
        return self.collect([self.ask(key, msg, blob, reply_kind, peer)], timeout_s, resend_s)[0]

    def _release(self, pending: Iterable[Pending]) -> None:
        for p in pending:
            if p.shared is not None and self._sharer is not None:
                self._sharer.release(p.shared)
                p.shared = None

    def wait_until_gone(self, nodes: Iterable[str], timeout_s: float) -> None:
        """Wait (at most ``timeout_s``) until ``nodes`` have withdrawn their tokens, ignoring other traffic."""
        deadline = self.clock.now() + timeout_s
        while set(nodes) & self._alive and self.clock.now() < deadline:
            try:
                what, item = self._inbox.get(timeout=max(0.0, deadline - self.clock.now()))
            except queue.Empty:
                return
            if what == "up":
                self._alive.add(item)
            elif what == "down":
                self._alive.discard(item)

    def _take(self, timeout_s: float, return_on_up: bool = False) -> Received | None:
        deadline = self.clock.now() + timeout_s
        while True:
            left = deadline - self.clock.now()
            if left <= 0:
                return None
            try:
                what, item = self._inbox.get(timeout=left)
            except queue.Empty:
                return None
            if what == "up":
                self._alive.add(item)
                if return_on_up:
                    return None
            elif what == "down":
                self._alive.discard(item)
                if item != self.node:
                    self._fail_unless_stopped(item)
            else:
                msg = item.msg
                if isinstance(msg, Shutdown):
                    if msg.node == self.node:
                        continue
                    if msg.failed:
                        raise RelayedFailure(msg)
                    raise PeerStopped(msg)
                if self.trace is not None and (step := getattr(msg, "step", None)) is not None:
                    self.trace.mark(message_mark(TAKEN, item.key), step)
                return item

    def _fail_unless_stopped(self, node: str) -> None:
        """A peer left: if the run was ending, the Shutdown saying so may still be on its way by another route, so
        wait up to ``DEPARTURE_GRACE_S`` for it (keeping whatever else arrives) before calling it a death."""
        end = self.clock.now() + DEPARTURE_GRACE_S
        kept: list[tuple[str, Any]] = []
        try:
            while (left := end - self.clock.now()) > 0:
                try:
                    what, item = self._inbox.get(timeout=left)
                except queue.Empty:
                    break
                if what == "msg" and isinstance(item.msg, Shutdown) and item.msg.node != self.node:
                    if item.msg.failed:
                        raise RelayedFailure(item.msg)
                    raise PeerStopped(item.msg)
                kept.append((what, item))
            raise NodeFailure(node, self.sim_time_s, "died (its bus liveliness token vanished)")
        finally:
            rest: list[tuple[str, Any]] = []
            while True:
                try:
                    rest.append(self._inbox.get_nowait())
                except queue.Empty:
                    break
            for entry in kept + rest:
                self._inbox.put(entry)

    def guarded(self, body: Callable[[], None]) -> tuple[int, bool]:
        """Run a node's main loop and turn how it ended into (exit code, whether ``body`` ran to its end).

        A peer's failure is logged and, unless it was relayed already, announced to every node; a peer's normal
        stop is logged; this node's own error is logged with its traceback and announced as an internal error.
        """
        try:
            body()
        except NodeFailure as failure:
            self.log.error("%s (last simulated time %s s)", failure, self.sim_time_s)
            if not isinstance(failure, RelayedFailure):
                self.shutdown(str(failure), failed=True)
            return EXIT_PEER, False
        except PeerStopped as stop:
            self.log.info("stopped by %s: %s; %d undecodable messages", stop.shutdown.node, stop.shutdown.reason,
                          self.decode_errors)
            return EXIT_OK, False
        except Exception as exc:
            self.log.exception("internal error")
            self.shutdown(f"{self.node} internal error: {exc!r}", failed=True)
            return EXIT_INTERNAL, False
        return EXIT_OK, True

    def mark(self, what: str, step: int) -> None:
        """Mark ``what`` (``contracts.hoptrace.WORK_START``, ...) for ``step`` in the trace, if there is one."""
        if self.trace is not None:
            self.trace.mark(what, step)

    def close(self) -> None:
        """Withdraw the liveliness token first, so peers see a clean departure before the session closes; remove the
        blobs still in shared memory; write the trace."""
        if self._token is not None:
            self._token.undeclare()
            self._token = None
        if self._sharer is not None:
            self._sharer.close()
            self._sharer = None
        if self.trace is not None:
            try:
                self.trace.write()
            except OSError as exc:
                self.log.error("hop trace: %s: %s", self.trace.path, exc)
            self.trace = None
