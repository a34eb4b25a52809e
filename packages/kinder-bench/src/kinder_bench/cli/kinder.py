"""The root ``kinder`` app: mounts every command group; the console script and
``python -m kinder_bench`` run :func:`main`.

Command groups, one module each, over :mod:`kinder_bench.cli.common`:

* :mod:`~kinder_bench.cli.envs`: ``kinder envs``, ``show``, ``agents``, ``rollout``;
* :mod:`~kinder_bench.cli.bench`: ``kinder bench run`` / ``report``;
* :mod:`~kinder_bench.cli.campaign`: ``kinder bench campaign``, a whole campaign from one file;
* :mod:`~kinder_bench.cli.demo`: ``kinder demo``, the showcase run;
* :mod:`~kinder_bench.cli.demos`: ``kinder demos ...``, demonstration datasets;
* :mod:`~kinder_bench.cli.train`: ``kinder train ...``, the learning baselines' trainers;
* :mod:`~kinder_bench.cli.serve`: ``kinder serve``, an agent behind the policy server;
* :mod:`~kinder_bench.cli.teleop`: ``kinder teleop``, demonstrations by hand.
"""

from __future__ import annotations

import typer

from kinder_bench.cli.bench import bench_app
from kinder_bench.cli.campaign import campaign_cmd
from kinder_bench.cli.demo import demo
from kinder_bench.cli.demos import demos_app
from kinder_bench.cli.envs import agents, envs, rollout, show
from kinder_bench.cli.serve import serve_cmd
from kinder_bench.cli.teleop import teleop_cmd
from kinder_bench.cli.train import train_app

app = typer.Typer(
    name="kinder",
    help="KinDER: physical-reasoning environments and the KinDERBench evaluation runner.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
bench_app.command("campaign")(campaign_cmd)
app.add_typer(bench_app, name="bench")
app.add_typer(train_app, name="train")
app.add_typer(demos_app, name="demos")
app.command("teleop")(teleop_cmd)
app.command("serve")(serve_cmd)
app.command()(envs)
app.command()(agents)
app.command()(show)
app.command()(rollout)
app.command()(demo)


def main() -> None:
    """Entry point of ``kinder`` and ``python -m kinder_bench``."""
    app(prog_name="kinder")


if __name__ == "__main__":
    main()
