"""A client of any OpenAI-compatible chat endpoint: plain ``POST {base_url}/chat/completions``
(standard library HTTP, no client package). Redirects are not followed (the key is never sent
to another host), one wall-clock deadline bounds the whole request, and the reply's size is
capped. The ``llm`` reader and the code-writing LLM backend both ask through it.

Configuration comes from a :class:`LLMConfig` built by the caller, from the environment
(:meth:`LLMConfig.from_env`) or from a TOML file (:meth:`LLMConfig.from_file`).
"""

from __future__ import annotations

import http.client
import json
import math
import os
import re
import socket
import threading
import time
import tomllib
import urllib.parse
from dataclasses import dataclass, field, replace
from pathlib import Path

from tabletop.errors import ConfigError
from tabletop.reader.errors import LLMError

__all__ = ["ENV_API_KEY", "ENV_BASE_URL", "ENV_MODEL", "LLMConfig", "chat", "redact_url"]

#: The userinfo of a URL (``user:password@``), up to the first ``/``, ``?`` or ``#``.
_USERINFO = re.compile(r"^([A-Za-z][A-Za-z0-9+.-]*://)([^/?#]*)@")


def redact_url(url) -> str:
    """``url`` as shown in a message: its password (or a userinfo without one, which may be a
    token) replaced by ``***`` (``http://user:***@host/v1``); anything else unchanged."""
    text = str(url)

    def hide(m: re.Match) -> str:
        userinfo = m.group(2)
        user, sep, _ = userinfo.partition(":")
        return f"{m.group(1)}{user}:***@" if sep else f"{m.group(1)}***@"

    return _USERINFO.sub(hide, text, count=1)


ENV_BASE_URL = "TABLETOP_LLM_BASE_URL"
ENV_MODEL = "TABLETOP_LLM_MODEL"
ENV_API_KEY = "TABLETOP_LLM_API_KEY"


#: The longest an LLM request may be given [s] (a day; a clock cannot wait for 1e308 s).
MAX_TIMEOUT_S = 86400.0


@dataclass(frozen=True)
class LLMConfig:
    """Where the chat endpoint is and how to ask it."""

    base_url: str
    """Endpoint root, e.g. ``http://127.0.0.1:8000/v1`` (``/chat/completions`` is appended)."""
    model: str
    """Model name the endpoint serves."""
    api_key: str | None = field(default=None, repr=False)
    """Sent as ``Authorization: Bearer ...`` when given."""
    timeout_s: float = 60.0
    """Wall-clock limit [s] of one whole request (connect, send, every read of the reply)."""
    temperature: float = 0.0
    max_tokens: int = 800
    max_reply_bytes: int = 4_000_000
    """Largest reply [bytes] read; a longer one is an error."""

    def __post_init__(self) -> None:
        _check_types(self)
        if not re.match(r"^https?://[^/\s]+", self.base_url or ""):
            raise ConfigError(
                f"LLM base_url must be an http(s) URL such as http://127.0.0.1:8000/v1, "
                f"got {redact_url(self.base_url)!r}"
            )
        if any(c.isspace() or not c.isprintable() for c in self.base_url):
            raise ConfigError(
                f"LLM base_url {redact_url(self.base_url)!r} holds a space or a control character; "
                "a URL "
                "has neither (e.g. http://127.0.0.1:8000/v1)"
            )
        try:
            parts = urllib.parse.urlsplit(self.base_url)
        except ValueError as e:  # an unclosed IPv6 bracket
            raise ConfigError(
                f"LLM base_url {redact_url(self.base_url)!r} is not a URL: {e}"
            ) from None
        try:
            port = parts.port
        except ValueError:  # a port out of range, or not a number
            port = -1
        if port is not None and not 1 <= port <= 65535:
            raise ConfigError(
                f"LLM base_url {redact_url(self.base_url)!r}: the port must be a number in "
                "1-65535, e.g. "
                "http://127.0.0.1:8000/v1"
            )
        if not self.model or not self.model.strip():
            raise ConfigError("LLM model must be a non-empty name")
        if (
            not 0 < self.timeout_s <= MAX_TIMEOUT_S
            or self.max_tokens < 1
            or not 0 <= self.temperature <= 2
            or self.max_reply_bytes < 1
        ):
            raise ConfigError(
                f"LLM timeout_s must be in (0, {MAX_TIMEOUT_S:g}] s, max_tokens >= 1, "
                "temperature in [0, 2], max_reply_bytes >= 1; got "
                f"{self.timeout_s}, {self.max_tokens}, {self.temperature}, {self.max_reply_bytes}"
            )

    @classmethod
    def from_env(cls, env=None, **overrides) -> LLMConfig:
        """From ``TABLETOP_LLM_BASE_URL``, ``TABLETOP_LLM_MODEL``, ``TABLETOP_LLM_API_KEY``;
        keyword ``overrides`` that are not None win."""
        env = os.environ if env is None else env
        values = {
            "base_url": env.get(ENV_BASE_URL),
            "model": env.get(ENV_MODEL),
            "api_key": env.get(ENV_API_KEY),
        }
        values.update({k: v for k, v in overrides.items() if v is not None})
        missing = [k for k in ("base_url", "model") if not values.get(k)]
        if missing:
            raise ConfigError(
                f"the llm backend needs {' and '.join(missing)}: set {ENV_BASE_URL} and "
                f"{ENV_MODEL} (and {ENV_API_KEY} if the endpoint wants a key), pass "
                "--llm-url/--llm-model, or --llm-config FILE"
            )
        return cls(**values)

    @classmethod
    def from_file(cls, path, env=None) -> LLMConfig:
        """From the ``[llm]`` table of a TOML file: ``base_url``, ``model``, optional
        ``api_key_env`` (the name of the environment variable holding the key; a key is never
        written in a file), ``timeout_s``, ``temperature``, ``max_tokens``,
        ``max_reply_bytes``."""
        env = os.environ if env is None else env
        p = Path(path)
        if not p.is_file():
            from tabletop.paths import input_file_problem

            problem = input_file_problem(path) or "does not exist"
            raise ConfigError(f"LLM config {str(path)!r} {problem}")
        try:
            doc = tomllib.loads(p.read_text())
        except tomllib.TOMLDecodeError as e:
            raise ConfigError(f"LLM config {str(p)!r} is not valid TOML: {e}") from None
        except UnicodeDecodeError:
            raise ConfigError(f"LLM config {str(p)!r} is not text (not UTF-8)") from None
        if "llm" not in doc:
            raise ConfigError(
                f"LLM config {str(p)!r}: needs an [llm] table (base_url, model, ...); it has "
                f"{sorted(doc) or 'no tables'}"
            )
        table = doc["llm"]
        if not isinstance(table, dict):
            raise ConfigError(
                f"LLM config {str(p)!r}: 'llm' is a {type(table).__name__} ({table!r:.40}), not "
                "a table: write [llm] and its keys below it (base_url, model, ...)"
            )
        known = {
            "base_url",
            "model",
            "api_key_env",
            "timeout_s",
            "temperature",
            "max_tokens",
            "max_reply_bytes",
        }
        unknown = sorted(set(table) - known)
        if unknown:
            raise ConfigError(
                f"LLM config {str(p)!r}: unknown keys {unknown}; valid: {sorted(known)}"
            )
        values = {k: v for k, v in table.items() if k != "api_key_env"}
        key_env = table.get("api_key_env", ENV_API_KEY)
        if not isinstance(key_env, str) or not key_env:
            raise ConfigError(
                f"LLM config {str(p)!r}: api_key_env must be the name of an environment "
                f"variable (a string), got {key_env!r:.40}"
            )
        values["api_key"] = env.get(key_env)
        if "api_key_env" in table and not values["api_key"]:  # named, so the endpoint wants one
            raise ConfigError(
                f"LLM config {str(p)!r}: api_key_env names {key_env!r}, which is not set (or "
                f"empty): set it to the endpoint's key, or leave api_key_env out for an "
                "endpoint that takes no key"
            )
        try:
            return cls(**values)
        except TypeError as e:
            raise ConfigError(f"LLM config {str(p)!r}: {e}") from None
        except ConfigError as e:
            raise ConfigError(f"LLM config {str(p)!r}: {e}") from None

    def with_overrides(self, **overrides) -> LLMConfig:
        return replace(self, **{k: v for k, v in overrides.items() if v is not None})


#: Each setting's valid types and how the error names them.
_FIELD_TYPES = {
    "base_url": ((str,), "a string (an http(s) URL)"),
    "model": ((str,), "a string (the model's name)"),
    "api_key": ((str, type(None)), "a string or none"),
    "timeout_s": ((int, float), "a number of seconds"),
    "temperature": ((int, float), "a number in [0, 2]"),
    "max_tokens": ((int,), "an integer >= 1"),
    "max_reply_bytes": ((int,), "an integer >= 1"),
}


def _check_types(config: LLMConfig) -> None:
    """Every setting of ``config`` has its type (booleans are not numbers; numbers finite):
    :class:`ConfigError` naming the field, its valid form and its value."""
    for name, (types, valid) in _FIELD_TYPES.items():
        v = getattr(config, name)
        ok = isinstance(v, types) and not isinstance(v, bool)
        if ok and isinstance(v, float) and not math.isfinite(v):
            raise ConfigError(f"LLM {name} must be finite ({valid}), got {v}")
        if not ok:
            shown = "(hidden)" if name == "api_key" else f"{v!r:.40}"
            raise ConfigError(f"LLM {name} must be {valid}, got {type(v).__name__} {shown}")


def _shut(sock: socket.socket) -> None:
    """End whatever read or write is waiting on ``sock``."""
    try:
        sock.shutdown(socket.SHUT_RDWR)
    except OSError:
        pass  # already closed


def _post(url: str, body: bytes, headers: dict, config: LLMConfig) -> tuple[int, bytes]:
    """(status, body) of one POST, within ``config.timeout_s`` of wall-clock time in all and
    at most ``config.max_reply_bytes`` read. Redirects are not followed."""
    shown = redact_url(url)  # what messages show: never a password
    parts = urllib.parse.urlsplit(url)
    cls = http.client.HTTPSConnection if parts.scheme == "https" else http.client.HTTPConnection
    path = parts.path + (f"?{parts.query}" if parts.query else "")
    deadline = time.monotonic() + config.timeout_s
    conn = cls(parts.hostname, parts.port, timeout=config.timeout_s)
    timer = None
    try:
        conn.connect()
        # A server that trickles a byte now and then satisfies any per-read timeout: at the
        # deadline the socket is shut, which ends whatever read is waiting.
        timer = threading.Timer(max(0.0, deadline - time.monotonic()), _shut, (conn.sock,))
        timer.start()
        conn.request("POST", path, body, headers)
        resp = conn.getresponse()
        if 300 <= resp.status < 400:
            where = resp.getheader("Location", "(no Location)")
            raise LLMError(
                f"{shown}: HTTP {resp.status} redirects to {redact_url(where)}; redirects are not "
                "followed (the key would go with them): set base_url to the endpoint itself"
            )
        cap = config.max_reply_bytes
        declared = resp.getheader("Content-Length", "")
        if declared.isdigit() and int(declared) > cap:
            raise LLMError(f"{shown}: the reply is {declared} bytes, over the cap of {cap} bytes")
        raw = bytearray()
        while chunk := resp.read1(65536):
            raw += chunk
            if len(raw) > cap:
                raise LLMError(
                    f"{shown}: the reply is over the cap of {cap} bytes (max_reply_bytes)"
                )
        if time.monotonic() >= deadline:
            raise TimeoutError
        return resp.status, bytes(raw)
    except (http.client.HTTPException, TimeoutError, OSError) as e:
        if time.monotonic() >= deadline or isinstance(e, TimeoutError):
            raise LLMError(f"{shown}: no complete reply within {config.timeout_s:g} s") from None
        raise LLMError(f"cannot reach the LLM endpoint {shown}: {e}") from None
    finally:
        if timer is not None:
            timer.cancel()
        conn.close()


def _reply_content(url: str, raw: bytes) -> str:
    """``choices[0].message.content`` of a chat completion, or an :class:`LLMError` naming
    what is wrong with the reply."""
    try:
        data = json.loads(raw)
    except (ValueError, RecursionError):
        raise LLMError(
            f"{url}: the reply is not an OpenAI-style chat completion (not JSON): {raw[:200]!r}"
        ) from None
    where = "the reply"
    for key in ("choices", 0, "message", "content"):
        if key == 0:
            ok = isinstance(data, list) and len(data) > 0
        else:
            ok = isinstance(data, dict) and key in data
        if not ok:
            raise LLMError(
                f"{url}: the reply is not an OpenAI-style chat completion "
                f"(choices[0].message.content): {where} has no {key!r}: {raw[:200]!r}"
            )
        data = data[key]
        where = f"{where}[{key!r}]"
    if not isinstance(data, str):
        raise LLMError(f"{url}: the reply's message content is not text but {type(data).__name__}")
    return data


def chat(messages: list[dict], config: LLMConfig, response_format: dict | None = None) -> str:
    """The assistant's reply text to ``messages`` (:class:`LLMError` on any failure);
    ``response_format`` asks for structured output (OpenAI's ``json_schema`` form)."""
    url = config.base_url.rstrip("/") + "/chat/completions"
    request = {
        "model": config.model,
        "messages": messages,
        "temperature": config.temperature,
        "max_tokens": config.max_tokens,
    }
    if response_format is not None:
        request["response_format"] = response_format
    body = json.dumps(request).encode()
    headers = {"Content-Type": "application/json", "Accept": "application/json"}
    if config.api_key:
        headers["Authorization"] = f"Bearer {config.api_key}"
    status, raw = _post(url, body, headers, config)
    if not 200 <= status < 300:
        detail = raw[:300].decode("utf-8", "replace")
        reason = http.client.responses.get(status, "")
        raise LLMError(f"{redact_url(url)}: HTTP {status} {reason}: {detail}")
    return _reply_content(redact_url(url), raw)
