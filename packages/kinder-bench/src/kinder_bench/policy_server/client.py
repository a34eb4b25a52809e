"""The client side of the policy protocol (see the package docstring)."""

from __future__ import annotations

import contextlib
from typing import Any

from websockets.exceptions import ConnectionClosed, InvalidHandshake, InvalidURI
from websockets.sync.client import ClientConnection, connect

from kinder_bench.policy_server import wire


class PolicyServerError(RuntimeError):
    """The policy server could not be reached, failed, timed out or answered malformed data."""


class PolicyClient:
    """One connection to a policy server: :attr:`metadata` from the server, then :meth:`infer`.

    Args:
        url: ``ws://HOST:PORT``.
        timeout: Seconds to wait for the connection and for each reply.
        api_key: Sent as ``Authorization: Api-Key ...`` when given (as openpi's client does).
    """

    def __init__(self, url: str, timeout: float = 30.0, api_key: str | None = None) -> None:
        self.url = url
        self.timeout = timeout
        headers = {"Authorization": f"Api-Key {api_key}"} if api_key else None
        self._stack = contextlib.ExitStack()  # websockets wants connect() used as a context
        try:
            self._conn: ClientConnection = self._stack.enter_context(
                connect(
                    url,
                    open_timeout=timeout,
                    additional_headers=headers,
                    compression=None,
                    max_size=None,
                )
            )
        except (OSError, InvalidHandshake, InvalidURI, TimeoutError) as e:
            raise PolicyServerError(f"cannot connect to the policy server at {url}: {e}") from e
        first = self._receive("the server's metadata")
        if not isinstance(first, dict):
            self.close()
            raise PolicyServerError(f"{url}: expected a metadata dict first, got {type(first)}")
        self.metadata: dict[str, Any] = first

    def _receive(self, what: str) -> Any:
        try:
            message = self._conn.recv(timeout=self.timeout)
        except TimeoutError as e:
            self.close()
            raise PolicyServerError(
                f"{self.url}: no reply within {self.timeout:g} s waiting for {what}"
            ) from e
        except ConnectionClosed as e:
            raise PolicyServerError(
                f"{self.url}: the server closed the connection while we waited for {what} ({e})"
            ) from e
        if isinstance(message, str):  # openpi sends a server-side traceback as text
            self.close()
            last = message.strip().splitlines()[-1] if message.strip() else "(empty)"
            raise PolicyServerError(f"{self.url}: the server failed: {last}")
        try:
            return wire.unpackb(message)
        except ValueError as e:
            self.close()
            raise PolicyServerError(f"{self.url}: malformed reply to {what}: {e}") from e

    def infer(self, observation: dict[str, Any]) -> dict[str, Any]:
        """Send one observation and return the reply, which holds ``actions``."""
        try:
            self._conn.send(wire.packb(observation))
        except ConnectionClosed as e:
            raise PolicyServerError(f"{self.url}: the connection is closed ({e})") from e
        reply = self._receive("an action chunk")
        if not isinstance(reply, dict) or "actions" not in reply:
            raise PolicyServerError(
                f"{self.url}: expected a dict with 'actions', got "
                f"{sorted(reply) if isinstance(reply, dict) else type(reply).__name__}"
            )
        return reply

    def close(self) -> None:
        self._stack.close()

    def __enter__(self) -> PolicyClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
