"""``kinder serve``: one of our agents behind the openpi-compatible policy server.

``kinder serve --agent dp --arg checkpoint=runs/dp/Motion2D-p0 --env Motion2D-p0 --port 8000``
serves a trained DP checkpoint; ``kinder bench run --agent vla --arg url=ws://HOST:8000 --env
Motion2D-p0 --workers 1`` then evaluates it out of process, the way π0.5 is evaluated. See
:mod:`kinder_bench.policy_server.agent_policy` for the protocol extension (full observation,
episode id, seed) and why one action is answered per request.
"""

from __future__ import annotations

from typing import Annotated

import typer

from kinder_bench.cli.common import fail, load_imports, parse_agent_args, user_errors

ArgOpt = Annotated[
    list[str] | None,
    typer.Option("--arg", help="Agent argument KEY=VALUE (see `kinder agents`). Repeatable."),
]
ImportOpt = Annotated[
    list[str] | None,
    typer.Option("--import", help="Module to import first (extra envs or agents). Repeatable."),
]


def serve_cmd(
    agent: Annotated[str, typer.Option(help="The agent to serve, e.g. dp or dpes.")],
    env: Annotated[str, typer.Option("--env", "-e", help="The env it acts in.")],
    args: ArgOpt = None,
    host: Annotated[
        str, typer.Option(help="Interface to bind (0.0.0.0: every interface).")
    ] = "127.0.0.1",
    port: Annotated[int, typer.Option(help="TCP port (0: a free one).")] = 8000,
    seed: Annotated[int, typer.Option(help="Agent seed when a request carries none.")] = 0,
    busy_timeout: Annotated[
        float, typer.Option(help="Seconds a second client waits for the current episode.")
    ] = 5.0,
    imports: ImportOpt = None,
) -> None:
    """Serve an agent (DP, DPES, ...) over openpi's WebSocket protocol, one episode at a time,
    until interrupted; evaluate it with `kinder bench run --agent vla --arg url=ws://HOST:PORT`."""
    from kinder_bench.policy_server.agent_policy import AgentService

    load_imports(imports)
    agent_args = parse_agent_args(args, [agent])[agent]
    with user_errors():
        service = AgentService(agent, agent_args, env, seed=seed, busy_timeout=busy_timeout)
    try:
        server = service.server(host, port)
    except OSError as e:
        fail(f"cannot listen on {host}:{port}: {e}")
    typer.echo(
        f"serving {agent} on {service.env_id} at {server.url} (one episode at a time; "
        f"Ctrl-C stops)",
        err=True,
    )
    try:
        server.serve_forever()
    except KeyboardInterrupt:
        pass
    finally:
        server.close()
