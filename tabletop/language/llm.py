"""An LLM backend: any OpenAI-compatible chat endpoint writes the robot code.

The request is a plain ``POST {base_url}/chat/completions`` (standard library HTTP, no client
package) with the few-shot prompt of :mod:`tabletop.language.prompts`. The reply's code (the
first fenced block, or the whole reply) is returned as is; the caller runs it through the
sandbox like the offline parser's code.

Configuration comes from a :class:`LLMConfig` built by the caller, from the environment
(:meth:`LLMConfig.from_env`) or from a TOML file (:meth:`LLMConfig.from_file`).
"""

from __future__ import annotations

import json
import os
import re
import tomllib
import urllib.error
import urllib.request
from dataclasses import dataclass, field, replace
from pathlib import Path

from tabletop.errors import ConfigError
from tabletop.language.errors import LLMError
from tabletop.language.prompts import prompt_messages

__all__ = [
    "ENV_API_KEY",
    "ENV_BASE_URL",
    "ENV_MODEL",
    "LLMConfig",
    "chat",
    "extract_code",
    "llm_code",
]

ENV_BASE_URL = "TABLETOP_LLM_BASE_URL"
ENV_MODEL = "TABLETOP_LLM_MODEL"
ENV_API_KEY = "TABLETOP_LLM_API_KEY"


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
    """Time limit [s] of one request."""
    temperature: float = 0.0
    max_tokens: int = 800

    def __post_init__(self) -> None:
        if not re.match(r"^https?://[^/\s]+", self.base_url or ""):
            raise ConfigError(
                f"LLM base_url must be an http(s) URL such as http://127.0.0.1:8000/v1, "
                f"got {self.base_url!r}"
            )
        if not self.model or not self.model.strip():
            raise ConfigError("LLM model must be a non-empty name")
        if not self.timeout_s > 0 or self.max_tokens < 1 or not 0 <= self.temperature <= 2:
            raise ConfigError(
                "LLM timeout_s must be > 0 [s], max_tokens >= 1, temperature in [0, 2]; got "
                f"{self.timeout_s}, {self.max_tokens}, {self.temperature}"
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
        written in a file), ``timeout_s``, ``temperature``, ``max_tokens``."""
        env = os.environ if env is None else env
        p = Path(path)
        if not p.is_file():
            raise ConfigError(f"LLM config {str(p)!r} does not exist")
        try:
            table = tomllib.loads(p.read_text())["llm"]
        except (tomllib.TOMLDecodeError, KeyError) as e:
            raise ConfigError(f"LLM config {str(p)!r}: needs an [llm] table ({e})") from None
        known = {"base_url", "model", "api_key_env", "timeout_s", "temperature", "max_tokens"}
        unknown = sorted(set(table) - known)
        if unknown:
            raise ConfigError(
                f"LLM config {str(p)!r}: unknown keys {unknown}; valid: {sorted(known)}"
            )
        values = {k: v for k, v in table.items() if k != "api_key_env"}
        key_env = table.get("api_key_env", ENV_API_KEY)
        values["api_key"] = env.get(key_env)
        try:
            return cls(**values)
        except TypeError as e:
            raise ConfigError(f"LLM config {str(p)!r}: {e}") from None

    def with_overrides(self, **overrides) -> LLMConfig:
        return replace(self, **{k: v for k, v in overrides.items() if v is not None})


def chat(messages: list[dict], config: LLMConfig) -> str:
    """The assistant's reply text to ``messages`` (:class:`LLMError` on any failure)."""
    url = config.base_url.rstrip("/") + "/chat/completions"
    body = json.dumps(
        {
            "model": config.model,
            "messages": messages,
            "temperature": config.temperature,
            "max_tokens": config.max_tokens,
        }
    ).encode()
    headers = {"Content-Type": "application/json", "Accept": "application/json"}
    if config.api_key:
        headers["Authorization"] = f"Bearer {config.api_key}"
    req = urllib.request.Request(url, data=body, headers=headers, method="POST")
    try:
        with urllib.request.urlopen(req, timeout=config.timeout_s) as resp:
            raw = resp.read()
    except urllib.error.HTTPError as e:
        detail = e.read()[:300].decode("utf-8", "replace")
        raise LLMError(f"{url}: HTTP {e.code} {e.reason}: {detail}") from None
    except (urllib.error.URLError, TimeoutError, OSError) as e:
        reason = getattr(e, "reason", e)
        raise LLMError(f"cannot reach the LLM endpoint {url}: {reason}") from None
    try:
        data = json.loads(raw)
        content = data["choices"][0]["message"]["content"]
    except (ValueError, KeyError, IndexError, TypeError):
        raise LLMError(
            f"{url}: the reply is not an OpenAI-style chat completion "
            f"(choices[0].message.content): {raw[:200]!r}"
        ) from None
    if not isinstance(content, str):
        raise LLMError(f"{url}: the reply's message content is not text")
    return content


_FENCE = re.compile(r"```[ \t]*(?:python|py)?[ \t]*\n(.*?)```", re.DOTALL | re.IGNORECASE)


def extract_code(reply: str) -> str:
    """The code in a reply: its first fenced block, else the whole reply."""
    m = _FENCE.search(reply)
    code = m.group(1) if m else reply
    return code.strip("\n") + "\n"


def llm_code(instruction: str, config: LLMConfig) -> str:
    """Robot code for ``instruction`` from the endpoint (not yet checked by the sandbox)."""
    if not isinstance(instruction, str) or not instruction.strip():
        raise ConfigError("the instruction is empty")
    code = extract_code(chat(prompt_messages(instruction), config))
    if not code.strip():
        raise LLMError(f"{config.base_url}: the model replied with no code")
    return code
