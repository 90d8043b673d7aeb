"""An LLM backend: any OpenAI-compatible chat endpoint writes the robot code, the paper's way.

The request goes through the endpoint client of :mod:`tabletop.reader.llm_client` with the
few-shot prompt of :mod:`tabletop.language.prompts`. The reply's code (the first fenced
block, or the whole reply) is returned as is; the caller runs it through the sandbox like the
offline reader's code. The ``llm`` reader (:mod:`tabletop.reader.llm`) asks the same endpoint
for the typed plan instead.
"""

from __future__ import annotations

import re

from tabletop.errors import ConfigError
from tabletop.language.errors import LLMError
from tabletop.language.prompts import prompt_messages
from tabletop.reader.llm_client import (
    ENV_API_KEY,
    ENV_BASE_URL,
    ENV_MODEL,
    LLMConfig,
    chat,
    redact_url,
)

__all__ = [
    "ENV_API_KEY",
    "ENV_BASE_URL",
    "ENV_MODEL",
    "LLMConfig",
    "chat",
    "extract_code",
    "llm_code",
]

_FENCE = re.compile(r"```[ \t]*(?:python|py)?[ \t]*\n(.*?)```", re.DOTALL | re.IGNORECASE)


def extract_code(reply: str) -> str:
    """The code in a reply: its first fenced block, else the whole reply."""
    m = _FENCE.search(reply)
    code = m.group(1) if m else reply
    return code.strip("\n") + "\n"


def llm_code(instruction: str, config: LLMConfig, robot: str = "arm") -> str:
    """Robot code for ``instruction`` from the endpoint (not yet checked by the sandbox), with
    the prompt of ``robot`` ("arm" or "mobile")."""
    if not isinstance(instruction, str) or not instruction.strip():
        raise ConfigError("the instruction is empty")
    code = extract_code(chat(prompt_messages(instruction, robot), config))
    if not code.strip():
        raise LLMError(f"{redact_url(config.base_url)}: the model replied with no code")
    return code
