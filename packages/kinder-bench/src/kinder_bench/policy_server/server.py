"""A synchronous policy server speaking openpi's WebSocket protocol (see the package docstring).

Any object with ``infer(observation) -> dict`` (returning at least ``actions``) and a ``metadata``
dict is a :class:`Policy`. :class:`PolicyServer` makes a fresh policy per connection from a
factory, so per-episode state (observation history, action queue) never leaks between episodes,
and calls the policy's ``close()``, when it has one, when the connection ends. A factory that
raises (e.g. a busy :class:`~.agent_policy.AgentService`) is reported to the client like a failed
inference: the traceback as a text frame, then close code 1011.
"""

from __future__ import annotations

import http
import threading
import time
import traceback
from collections.abc import Callable
from typing import Any, Protocol

from websockets.exceptions import ConnectionClosed
from websockets.frames import CloseCode
from websockets.http11 import Request, Response
from websockets.sync.server import Server, ServerConnection, serve

from kinder_bench.policy_server import wire


class Policy(Protocol):
    """What the server serves: one instance per connection (episode)."""

    metadata: dict[str, Any]

    def infer(self, observation: dict[str, Any]) -> dict[str, Any]:
        """The reply to one observation; must hold ``actions`` (horizon × action dim)."""
        ...


class PolicyServer:
    """Serves policies made by ``factory`` on ``host:port`` (port 0 picks a free port).

    Use as a context manager (the server runs in a background thread) or call
    :meth:`serve_forever`. Only loopback is bound by default.
    """

    def __init__(
        self, factory: Callable[[], Policy], host: str = "127.0.0.1", port: int = 8000
    ) -> None:
        self.factory = factory
        self._server: Server = serve(
            self._handle,
            host,
            port,
            process_request=self._health,
            compression=None,
            max_size=None,
        )
        self.host, self.port = self._server.socket.getsockname()[:2]
        self._thread: threading.Thread | None = None

    @property
    def url(self) -> str:
        return f"ws://{self.host}:{self.port}"

    @staticmethod
    def _health(connection: ServerConnection, request: Request) -> Response | None:
        if request.path == "/healthz":
            return connection.respond(http.HTTPStatus.OK, "OK\n")
        return None

    def _handle(self, connection: ServerConnection) -> None:
        try:
            policy = self.factory()
        except Exception:  # e.g. busy: tell the client why, as openpi reports failures
            connection.send(traceback.format_exc())
            connection.close(CloseCode.INTERNAL_ERROR, "internal server error")
            return
        try:
            self._serve(connection, policy)
        finally:
            close = getattr(policy, "close", None)
            if callable(close):
                close()

    def _serve(self, connection: ServerConnection, policy: Policy) -> None:
        connection.send(wire.packb(dict(policy.metadata)))
        previous_total: float | None = None
        while True:
            try:
                message = connection.recv()
            except ConnectionClosed:
                return
            start = time.perf_counter()
            try:
                if not isinstance(message, bytes):
                    raise ValueError("expected a binary msgpack frame, got a text frame")
                observation = wire.unpackb(message)
                if not isinstance(observation, dict):
                    raise ValueError(f"expected an observation dict, got {type(observation)}")
                t0 = time.perf_counter()
                reply = dict(policy.infer(observation))
                infer_ms = (time.perf_counter() - t0) * 1000.0
                reply["server_timing"] = {"infer_ms": infer_ms}
                if previous_total is not None:
                    reply["server_timing"]["prev_total_ms"] = previous_total
                connection.send(wire.packb(reply))
            except ConnectionClosed:
                return
            except Exception:
                connection.send(traceback.format_exc())
                connection.close(CloseCode.INTERNAL_ERROR, "internal server error")
                return
            previous_total = (time.perf_counter() - start) * 1000.0

    def serve_forever(self) -> None:
        """Serve until interrupted."""
        self._server.serve_forever()

    def __enter__(self) -> PolicyServer:
        self._thread = threading.Thread(target=self._server.serve_forever, daemon=True)
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Stop serving and close open connections."""
        self._server.shutdown()
        if self._thread is not None:
            self._thread.join(timeout=5)
