"""The LLM backend against a real HTTP server on 127.0.0.1 that plays an OpenAI-compatible
chat endpoint, and its code going through the sandbox."""

import json
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import ClassVar

import numpy as np
import pytest

from tabletop.errors import ConfigError
from tabletop.language import CodeRejected, LLMError, generate_code, run_code
from tabletop.language.llm import LLMConfig, chat, extract_code, llm_code
from tabletop.language.prompts import EXAMPLES, SYSTEM_PROMPT, prompt_messages, prompt_text
from tabletop.language.run import TracingRobot
from tabletop.robot.api import RobotAPI

REPLIES = {
    "go to the red mug": '```python\nrobot.move_to_object("red mug")\n```\nThat is all.',
    "move 5 cm north twice": "for _ in range(2):\n    robot.move_north(0.05)\n",
    "wipe the disk": "```python\nimport shutil\nshutil.rmtree('/')\n```",
}


class Endpoint(BaseHTTPRequestHandler):
    """Answers POST /v1/chat/completions with a canned reply for the last user message."""

    requests: ClassVar[list] = []
    mode: ClassVar[str] = "ok"

    def do_POST(self):
        body = json.loads(self.rfile.read(int(self.headers["Content-Length"])))
        Endpoint.requests.append((self.path, dict(self.headers), body))
        if Endpoint.mode == "error":
            return self._send(500, b'{"error": "model overloaded"}')
        if Endpoint.mode == "garbage":
            return self._send(200, b"<html>not json</html>")
        if self.path != "/v1/chat/completions":
            return self._send(404, b'{"error": "no such route"}')
        query = body["messages"][-1]["content"].removeprefix("# ")
        content = REPLIES.get(query, "robot.move_north(0.01)")
        reply = {"choices": [{"index": 0, "message": {"role": "assistant", "content": content}}]}
        self._send(200, json.dumps(reply).encode())

    def _send(self, code, payload):
        self.send_response(code)
        self.send_header("Content-Type", "application/json")
        self.send_header("Content-Length", str(len(payload)))
        self.end_headers()
        self.wfile.write(payload)

    def log_message(self, *args):
        pass


@pytest.fixture(scope="module")
def server():
    httpd = ThreadingHTTPServer(("127.0.0.1", 0), Endpoint)
    thread = threading.Thread(target=httpd.serve_forever, daemon=True)
    thread.start()
    yield f"http://127.0.0.1:{httpd.server_address[1]}/v1"
    httpd.shutdown()
    httpd.server_close()


@pytest.fixture(autouse=True)
def fresh():
    Endpoint.requests.clear()
    Endpoint.mode = "ok"


def config(url, **kw):
    return LLMConfig(base_url=url, model="tabletop-test", api_key="k-123", timeout_s=10, **kw)


def test_the_request_carries_the_few_shot_prompt_and_the_key(server):
    code = llm_code("go to the red mug", config(server))
    assert code == 'robot.move_to_object("red mug")\n'  # the fenced block, nothing else
    path, headers, body = Endpoint.requests[-1]
    assert path == "/v1/chat/completions"
    assert headers["Authorization"] == "Bearer k-123"
    assert body["model"] == "tabletop-test" and body["temperature"] == 0.0
    msgs = body["messages"]
    assert msgs[0] == {"role": "system", "content": SYSTEM_PROMPT}
    assert len(msgs) == 2 + 2 * len(EXAMPLES)
    assert [m["role"] for m in msgs[1:-1]] == ["user", "assistant"] * len(EXAMPLES)
    assert msgs[-1] == {"role": "user", "content": "# go to the red mug"}


def test_llm_code_runs_through_the_sandbox(server):
    code = generate_code("move 5 cm north twice", "llm", config(server))
    robot = Recorder()
    tracer = TracingRobot(robot, execute=True)
    run_code(code, tracer)
    np.testing.assert_allclose(tracer.targets, [[0.35, 0.0, 0.3], [0.4, 0.0, 0.3]])
    assert len(robot.moves) == 2


def test_hostile_llm_code_is_refused_and_nothing_moves(server):
    code = llm_code("wipe the disk", config(server))
    robot = Recorder()
    with pytest.raises(CodeRejected, match="import"):
        run_code(code, TracingRobot(robot))
    assert robot.moves == []


def test_endpoint_failures_are_clear_errors(server):
    Endpoint.mode = "error"
    with pytest.raises(LLMError, match="HTTP 500.*model overloaded"):
        llm_code("go to the red mug", config(server))
    Endpoint.mode = "garbage"
    with pytest.raises(LLMError, match="not an OpenAI-style chat completion"):
        llm_code("go to the red mug", config(server))
    Endpoint.mode = "ok"
    with pytest.raises(LLMError, match="HTTP 404"):
        chat(prompt_messages("x"), config(server.removesuffix("/v1") + "/v2"))
    # a port nobody listens on (the server's own port, once it is closed, could be reused)
    import socket

    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    with pytest.raises(LLMError, match=f"cannot reach the LLM endpoint http://127.0.0.1:{port}"):
        llm_code("go to the red mug", config(f"http://127.0.0.1:{port}/v1"))


def test_config_from_env_and_file(tmp_path):
    env = {
        "TABLETOP_LLM_BASE_URL": "http://127.0.0.1:9/v1",
        "TABLETOP_LLM_MODEL": "m",
        "TABLETOP_LLM_API_KEY": "secret",
    }
    c = LLMConfig.from_env(env)
    assert (c.base_url, c.model, c.api_key) == ("http://127.0.0.1:9/v1", "m", "secret")
    assert "secret" not in repr(c)
    assert LLMConfig.from_env(env, model="other").model == "other"
    with pytest.raises(ConfigError, match="TABLETOP_LLM_BASE_URL"):
        LLMConfig.from_env({})
    f = tmp_path / "llm.toml"
    f.write_text('[llm]\nbase_url = "http://localhost:1/v1"\nmodel = "x"\napi_key_env = "MYKEY"\n')
    c = LLMConfig.from_file(f, env={"MYKEY": "from-env"})
    assert (c.base_url, c.model, c.api_key) == ("http://localhost:1/v1", "x", "from-env")
    f.write_text('[llm]\nbase_url = "http://localhost:1/v1"\nmodel = "x"\napi_key = "inline"\n')
    with pytest.raises(ConfigError, match="unknown keys \\['api_key'\\]"):
        LLMConfig.from_file(f)
    # a syntax error is named as such, not as a missing table
    f.write_text('[llm]\nbase_url = "http://localhost:1/v1\n')
    with pytest.raises(ConfigError, match="is not valid TOML"):
        LLMConfig.from_file(f)
    f.write_text('[model]\nname = "x"\n')
    with pytest.raises(ConfigError, match=r"needs an \[llm\] table .* it has \['model'\]"):
        LLMConfig.from_file(f)
    with pytest.raises(ConfigError, match="http"):
        LLMConfig(base_url="localhost:8000", model="m")


def test_extract_code_and_prompt_text():
    assert extract_code("Here:\n```py\nrobot.move_north(0.1)\n```\n") == "robot.move_north(0.1)\n"
    assert extract_code("robot.move_north(0.1)") == "robot.move_north(0.1)\n"
    text = prompt_text("go to the duck")
    assert text.endswith("# go to the duck\n") and "get_major_map" in text
    # every example's code passes the sandbox
    from tabletop.language import check_code

    for _, code in EXAMPLES:
        check_code(code)


class Recorder(RobotAPI):
    """An embodiment that records motions (no map: the snippets here make no map query)."""

    def __init__(self):
        super().__init__(avlmap=None)
        self.moves = []
        self.pos = np.array([0.3, 0.0, 0.3])

    def move_to(self, pos):
        self.moves.append(np.array(pos, float))
        self.pos = np.array(pos, float)

    def current_position(self):
        return self.pos.copy()
