"""Out-of-process policies over openpi's wire protocol (WebSocket + msgpack-numpy).

* :mod:`.wire`: msgpack with numpy arrays, byte-compatible with openpi's ``msgpack_numpy``.
* :mod:`.server`: :class:`~.server.PolicyServer`, a synchronous server for any
  :class:`~.server.Policy`.
* :mod:`.client`: :class:`~.client.PolicyClient`, the client the ``vla`` agent uses.
* :mod:`.replay`: :class:`~.replay.ReplayPolicy`, a stand-in policy that replays a demonstration.

The protocol, as openpi's ``websocket_policy_server`` speaks it: on connect the server sends one
binary frame with a metadata dict; then each binary frame from the client is one observation dict
and each reply is a dict with ``actions`` (horizon × action dim) and ``server_timing``
(``infer_ms``). A server-side exception is sent as a text frame (the traceback) and the connection
closes with code 1011. ``GET /healthz`` answers 200. We open one connection per episode, so a
policy with per-episode state (an observation history) keeps it per connection.
"""
