"""A scripted local OpenAI-compatible chat server, and oracle answers from bilevel planning.

:class:`ChatServer` is a real HTTP server (stdlib ``http.server``) on a loopback port, in a thread:
``POST /v1/chat/completions`` answers with ``responder(request) -> str`` in the chat-completions
format (usage: ``ceil(characters / 4)`` tokens each way). ``fail_first`` lists HTTP status codes
returned, in order, before any real answer (to exercise retries). Every request body is kept in
``requests``. The tests use it as the model, and it dry-runs a benchmark set-up without a model.

:func:`oracle_answers` and :func:`table_responder` script it with the bilevel planner's plans:
for each episode of a run seed, the answer is BP's plan (the one the ``bilevel_planning`` agent
finds first in that episode) written in the answer syntax with exact parameters, keyed by the
episode's initial-state table, which the responder finds in the prompt.
"""

from __future__ import annotations

import json
import threading
from collections.abc import Callable
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from types import TracebackType
from typing import Any

Responder = Callable[[dict[str, Any]], str]


def _prompt_text(request: dict[str, Any]) -> str:
    parts: list[str] = []
    for m in request["messages"]:
        content = m["content"]
        if isinstance(content, list):
            parts.extend(p.get("text", "") for p in content if p.get("type") == "text")
        else:
            parts.append(content)
    return "\n".join(parts)


class ChatServer:
    """The test server (a context manager; ``base_url`` is valid inside it)."""

    def __init__(self, responder: Responder, fail_first: tuple[int, ...] = ()) -> None:
        self.responder = responder
        self.fail_first = list(fail_first)
        self.requests: list[dict[str, Any]] = []
        self._lock = threading.Lock()
        server = self

        class Handler(BaseHTTPRequestHandler):
            def log_message(self, format: str, *args: Any) -> None:
                del format, args

            def _send(self, status: int, body: dict[str, Any]) -> None:
                data = json.dumps(body).encode()
                self.send_response(status)
                self.send_header("Content-Type", "application/json")
                self.send_header("Content-Length", str(len(data)))
                if status == 429:
                    self.send_header("Retry-After", "0")
                self.end_headers()
                self.wfile.write(data)

            def do_POST(self) -> None:
                length = int(self.headers.get("Content-Length", "0"))
                request = json.loads(self.rfile.read(length))
                if self.path.rstrip("/") != "/v1/chat/completions":
                    self._send(404, {"error": {"message": f"no route {self.path}"}})
                    return
                with server._lock:
                    server.requests.append(request)
                    status = server.fail_first.pop(0) if server.fail_first else 200
                if status != 200:
                    self._send(status, {"error": {"message": f"scripted {status}"}})
                    return
                text = server.responder(request)
                prompt_tokens = -(-len(_prompt_text(request)) // 4)
                completion_tokens = -(-len(text) // 4)
                self._send(
                    200,
                    {
                        "id": f"chatcmpl-{len(server.requests)}",
                        "object": "chat.completion",
                        "created": 0,
                        "model": request["model"],
                        "choices": [
                            {
                                "index": 0,
                                "message": {"role": "assistant", "content": text},
                                "finish_reason": "stop",
                            }
                        ],
                        "usage": {
                            "prompt_tokens": prompt_tokens,
                            "completion_tokens": completion_tokens,
                            "total_tokens": prompt_tokens + completion_tokens,
                        },
                    },
                )

        self._httpd = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self._thread = threading.Thread(target=self._httpd.serve_forever, daemon=True)

    @property
    def base_url(self) -> str:
        host, port = self._httpd.server_address[:2]
        return f"http://{host!s}:{port}/v1"

    def __enter__(self) -> ChatServer:
        self._thread.start()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self._httpd.shutdown()
        self._httpd.server_close()
        self._thread.join()


def prompt_text(request: dict[str, Any]) -> str:
    """The text parts of a request's messages."""
    return _prompt_text(request)


def oracle_answers(env_id: str, run_seed: int, episodes: int) -> dict[str, str]:
    """Initial-state table → BP's plan as an answer, for episodes ``0..episodes-1`` of
    ``run_seed`` (episodes where BP finds no plan get an answer with an empty plan)."""
    from kinder_bench.baselines.bilevel_planning import plan_episode
    from kinder_bench.baselines.fm_planning.prompts import format_call, format_state, plan_calls
    from kinder_bench.evaluation.runner import agent_seed, episode_seeds
    from kinder_core import make_object_centric

    env = make_object_centric(env_id)
    answers: dict[str, str] = {}
    for i, env_seed in enumerate(episode_seeds(run_seed, episodes)):
        x0, _ = env.reset(seed=env_seed)
        plan, _ = plan_episode(env, x0, seed=agent_seed(run_seed, i))
        lines = [] if plan is None else [format_call(c, x0) for c in plan_calls(plan.skills)]
        answers[format_state(x0)] = "Scripted from bilevel planning.\nPlan:\n" + "\n".join(lines)
    return answers


def table_responder(answers: dict[str, str]) -> Responder:
    """A responder answering with the entry whose initial-state table the prompt holds (after
    its in-context examples, which hold other tables)."""

    def respond(request: dict[str, Any]) -> str:
        tail = _prompt_text(request).rsplit("from an initial state described below.", 1)[-1]
        hits = [a for table, a in answers.items() if table in tail]
        if len(hits) != 1:
            raise LookupError(
                f"the prompt holds {len(hits)} of the {len(answers)} scripted initial states"
            )
        return hits[0]

    return respond
