"""A chat client for any OpenAI-compatible endpoint, with an on-disk response cache.

The client speaks the chat-completions API through the official ``openai`` package
(``pip install 'kinder-bench[llm]'``), so the same code runs against a hosted model or a local
server (llama.cpp's ``llama-server``, vLLM, Ollama): the model name, base URL and API key come from
the arguments or the usual environment variables (``OPENAI_BASE_URL``, ``OPENAI_API_KEY``; a local
server that wants no key is sent the fixed string ``NO_KEY``, because the ``openai`` package
refuses an empty key).

**Cache.** Every response is stored under ``cache_dir`` keyed by the SHA-256 of the full request
(model, messages including images, sampling parameters, seed), one JSON file per request written
atomically (temporary file + rename), holding the request and the response (text, token usage,
finish reason). Modes: ``use`` (read the cache, ask the endpoint on a miss and store the
answer), ``only`` (never open a connection; a miss raises :class:`CacheMiss` naming the request)
and ``off`` (always ask, store nothing). A request with an image is keyed by the image's bytes,
so replaying it needs the same rendering.

**Retries.** Rate limits (429), timeouts, connection errors and server errors (5xx) are retried
with exponential backoff (``backoff · 2^attempt`` seconds, or the server's ``Retry-After`` when it
sends one) up to ``max_retries`` times and never past the caller's deadline; other errors (a bad
request, a wrong key, an unknown model) raise at once as :class:`ChatError`.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import time
from pathlib import Path
from typing import Any, Literal

from kinder_bench.evaluation.results import write_json

CacheMode = Literal["use", "only", "off"]
CACHE_MODES: tuple[str, ...] = ("use", "only", "off")

#: The key sent to local servers that check none (the ``openai`` client refuses an empty key).
NO_KEY = "no-key"


class ChatError(RuntimeError):
    """The endpoint could not answer (after the retries that apply)."""


class CacheMiss(ChatError):
    """Cache-only mode and the request is not in the cache."""


@dataclasses.dataclass(frozen=True)
class ChatResponse:
    """One answer and how it was obtained."""

    text: str
    usage: dict[str, int]
    """``prompt_tokens``, ``completion_tokens``, ``total_tokens`` as the endpoint reported them
    (empty when it reported none)."""
    finish_reason: str | None
    key: str
    """The request's cache key (SHA-256 hex of the canonical request)."""
    cached: bool
    """Whether the answer came from the cache."""
    attempts: int
    """HTTP requests made (0 when cached)."""
    latency: float
    """Seconds spent obtaining the answer (cache read or requests, backoff included)."""


def request_key(request: dict[str, Any]) -> str:
    """The cache key of a request: SHA-256 of its canonical JSON."""
    blob = json.dumps(request, sort_keys=True, separators=(",", ":"), ensure_ascii=False)
    return hashlib.sha256(blob.encode()).hexdigest()


def describe_request(request: dict[str, Any], limit: int = 160) -> str:
    """A short human description of a request (model and the start of the last message)."""
    messages = request.get("messages", [])
    text = ""
    if messages:
        content = messages[-1].get("content", "")
        if isinstance(content, list):
            text = " ".join(str(p.get("text", "<image>")) for p in content)
        else:
            text = str(content)
    text = " ".join(text.split())
    if len(text) > limit:
        text = text[:limit] + "…"
    return f"model={request.get('model')!r}, {len(messages)} message(s), last: {text!r}"


class ChatClient:
    """Chat completions with caching and retries (see the module docstring).

    Args:
        model: The model name sent to the endpoint.
        base_url: The endpoint (e.g. ``http://127.0.0.1:8080/v1``); None: ``OPENAI_BASE_URL`` or
            OpenAI's.
        api_key: The key; None: the environment variable ``api_key_env``, else ``NO_KEY``.
        api_key_env: Where to read the key when ``api_key`` is None.
        cache_dir: The response cache.
        cache_mode: ``use``, ``only`` or ``off``.
        max_retries: Retries after the first request on transient errors.
        backoff: Seconds before the first retry (doubled each time).
        request_timeout: Seconds one HTTP request may take.
    """

    def __init__(
        self,
        model: str,
        base_url: str | None = None,
        api_key: str | None = None,
        api_key_env: str = "OPENAI_API_KEY",
        cache_dir: str | Path = "runs/fm_cache",
        cache_mode: str = "use",
        max_retries: int = 6,
        backoff: float = 2.0,
        request_timeout: float = 600.0,
    ) -> None:
        if not model:
            raise ValueError("ChatClient: model must be a non-empty model name")
        if cache_mode not in CACHE_MODES:
            raise ValueError(
                f"ChatClient: cache_mode must be one of {CACHE_MODES}, got {cache_mode!r}"
            )
        if max_retries < 0 or backoff < 0 or request_timeout <= 0:
            raise ValueError(
                "ChatClient: need max_retries >= 0, backoff >= 0 and request_timeout > 0; got "
                f"{max_retries}, {backoff}, {request_timeout}"
            )
        self.model = model
        self.base_url = base_url or os.environ.get("OPENAI_BASE_URL") or None
        self._api_key = api_key or os.environ.get(api_key_env) or NO_KEY
        self.cache_dir = Path(cache_dir)
        self.cache_mode = cache_mode
        self.max_retries = max_retries
        self.backoff = backoff
        self.request_timeout = request_timeout
        self._client: Any = None

    def make_request(
        self,
        messages: list[dict[str, Any]],
        temperature: float | None = None,
        seed: int | None = None,
        max_tokens: int | None = None,
    ) -> dict[str, Any]:
        """The request body (what the cache key covers); unset sampling parameters are left out."""
        request: dict[str, Any] = {"model": self.model, "messages": messages}
        if temperature is not None:
            request["temperature"] = float(temperature)
        if seed is not None:
            request["seed"] = int(seed)
        if max_tokens is not None:
            request["max_completion_tokens"] = int(max_tokens)
        return request

    def cache_path(self, key: str) -> Path:
        """Where the response of the request with this key is cached."""
        return self.cache_dir / key[:2] / f"{key}.json"

    def complete(self, request: dict[str, Any], deadline: float | None = None) -> ChatResponse:
        """The answer to ``request`` (from :meth:`make_request`), from the cache or the endpoint.

        ``deadline`` is a ``time.monotonic()`` value no request or backoff may run past.
        """
        start = time.monotonic()
        key = request_key(request)
        path = self.cache_path(key)
        if self.cache_mode != "off" and path.exists():
            try:
                resp = json.loads(path.read_text())["response"]
            except (json.JSONDecodeError, KeyError, TypeError) as e:
                raise ChatError(
                    f"the cached response {path} is not a cache entry ({e}); delete it to ask again"
                ) from e
            return ChatResponse(
                text=resp["text"],
                usage={k: int(v) for k, v in resp.get("usage", {}).items()},
                finish_reason=resp.get("finish_reason"),
                key=key,
                cached=True,
                attempts=0,
                latency=time.monotonic() - start,
            )
        if self.cache_mode == "only":
            raise CacheMiss(
                f"cache-only mode: no cached response for request {key} "
                f"({describe_request(request)}) in {self.cache_dir}; run once with "
                f"cache_mode=use and an endpoint to fill the cache"
            )
        text, usage, finish, attempts = self._ask(request, deadline)
        if self.cache_mode == "use":
            path.parent.mkdir(parents=True, exist_ok=True)
            write_json(
                path,
                {
                    "request": request,
                    "response": {"text": text, "usage": usage, "finish_reason": finish},
                },
            )
        return ChatResponse(text, usage, finish, key, False, attempts, time.monotonic() - start)

    def _openai(self) -> Any:
        if self._client is None:
            try:
                import openai
            except ImportError as e:
                raise ChatError(
                    "the foundation-model planners need the openai package: "
                    "pip install 'kinder-bench[llm]'"
                ) from e
            self._client = openai.OpenAI(
                api_key=self._api_key, base_url=self.base_url, max_retries=0
            )
        return self._client

    def _ask(
        self, request: dict[str, Any], deadline: float | None
    ) -> tuple[str, dict[str, int], str | None, int]:
        import openai

        client = self._openai()
        transient = (
            openai.RateLimitError,
            openai.APITimeoutError,
            openai.APIConnectionError,
            openai.InternalServerError,
        )
        attempt = 0
        while True:
            attempt += 1
            timeout = self.request_timeout
            if deadline is not None:
                timeout = min(timeout, deadline - time.monotonic())
                if timeout <= 0:
                    raise ChatError(
                        f"the episode's model-call deadline passed after {attempt - 1} attempt(s) "
                        f"({describe_request(request)})"
                    )
            try:
                completion = client.chat.completions.create(**request, timeout=timeout)
            except transient as e:
                if attempt > self.max_retries:
                    raise ChatError(
                        f"{type(e).__name__} after {attempt} attempt(s) at "
                        f"{self.base_url or 'the OpenAI API'}: {e}"
                    ) from e
                wait = self._retry_after(e) or self.backoff * 2 ** (attempt - 1)
                if deadline is not None and time.monotonic() + wait > deadline:
                    raise ChatError(
                        f"{type(e).__name__} and no time left to retry before the episode's "
                        f"deadline (attempt {attempt}): {e}"
                    ) from e
                time.sleep(wait)
                continue
            except openai.APIError as e:
                raise ChatError(
                    f"{type(e).__name__} from {self.base_url or 'the OpenAI API'} "
                    f"(not retried): {e}"
                ) from e
            if not completion.choices:
                raise ChatError(f"the endpoint returned no choices ({describe_request(request)})")
            choice = completion.choices[0]
            text = choice.message.content or ""
            usage: dict[str, int] = {}
            if completion.usage is not None:
                usage = {
                    "prompt_tokens": int(completion.usage.prompt_tokens or 0),
                    "completion_tokens": int(completion.usage.completion_tokens or 0),
                    "total_tokens": int(completion.usage.total_tokens or 0),
                }
            return text, usage, choice.finish_reason, attempt

    @staticmethod
    def _retry_after(error: Exception) -> float | None:
        response = getattr(error, "response", None)
        headers = getattr(response, "headers", None)
        if headers is None:
            return None
        value = headers.get("retry-after")
        try:
            return max(0.0, float(value)) if value is not None else None
        except ValueError:
            return None
