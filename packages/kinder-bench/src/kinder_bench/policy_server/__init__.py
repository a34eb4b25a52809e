"""Out-of-process policies over openpi's wire protocol (WebSocket + msgpack-numpy).

* :mod:`.wire`: msgpack with numpy arrays, byte-compatible with openpi's ``msgpack_numpy``.
* :mod:`.server`: :class:`~.server.PolicyServer`, a synchronous server for any
  :class:`~.server.Policy`.
* :mod:`.client`: :class:`~.client.PolicyClient`, the client the ``vla`` agent uses.
* :mod:`.replay`: :class:`~.replay.ReplayPolicy`, a stand-in policy that replays a demonstration.
* :mod:`.agent_policy`: :class:`~.agent_policy.AgentService`, any runner agent (DP, DPES, ...)
  behind the server (``kinder serve``).

The protocol, as openpi's ``websocket_policy_server`` speaks it: on connect the server sends one
binary frame with a metadata dict; then each binary frame from the client is one observation dict
and each reply is a dict with ``actions`` (horizon × action dim) and ``server_timing``
(``infer_ms``). A server-side exception is sent as a text frame (the traceback) and the connection
closes with code 1011. ``GET /healthz`` answers 200. We open one connection per episode, so a
policy with per-episode state (an observation history) keeps it per connection.

Our extension, which openpi policies ignore (their input transforms pick the keys they use): the
``vla`` agent adds ``observation["environment_state"]`` and a top-level ``"kinder"`` entry
(``observation``: the full float64 Box observation; ``episode``: an id that changes with each
episode; ``seed``: the runner's agent seed), which :mod:`.agent_policy` uses to serve our own
agents exactly and to reset their history per episode even on a kept connection.
"""
