"""Hardening of the LLM backend against a hostile endpoint (real HTTP servers on 127.0.0.1 and
127.0.0.2): no key across a redirect, one wall-clock deadline, a reply size cap, and a clear
LLMError for every malformed reply."""

from __future__ import annotations

import json
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import ClassVar

import pytest

from tabletop.errors import ConfigError
from tabletop.language import LLMError
from tabletop.language.llm import LLMConfig, chat

MESSAGES = [{"role": "user", "content": "go to the mug"}]


class Hostile(BaseHTTPRequestHandler):
    """Answers every request as ``Hostile.mode`` says; records what it was sent."""

    mode: ClassVar[str] = "ok"
    body: ClassVar[bytes] = b""
    seen: ClassVar[list] = []
    redirect_to: ClassVar[str] = ""

    def do_GET(self):
        Hostile.seen.append((self.command, dict(self.headers)))
        self._send(200, b'{"choices": [{"message": {"content": "robot.move_north(1)"}}]}')

    def do_POST(self):
        Hostile.seen.append((self.command, dict(self.headers)))
        self.rfile.read(int(self.headers["Content-Length"]))
        if Hostile.mode == "redirect":
            self.send_response(302)
            self.send_header("Location", Hostile.redirect_to)
            self.send_header("Content-Length", "0")
            self.end_headers()
        elif Hostile.mode == "trickle":  # headers at once, then a byte every 0.3 s for 8 s
            self.send_response(200)
            self.send_header("Content-Length", "100")
            self.end_headers()
            for _ in range(27):
                self.wfile.write(b" ")
                self.wfile.flush()
                time.sleep(0.3)
        elif Hostile.mode == "unsized":  # no Content-Length: read until the server closes
            self.send_response(200)
            self.send_header("Connection", "close")
            self.end_headers()
            self.close_connection = True
            for _ in range(50):
                self.wfile.write(b"x" * 1000)
        else:
            self._send(200, Hostile.body)

    def _send(self, code, payload):
        self.send_response(code)
        self.send_header("Content-Type", "application/json")
        self.send_header("Content-Length", str(len(payload)))
        self.end_headers()
        self.wfile.write(payload)

    def log_message(self, *args):
        pass


def _serve(host):
    httpd = ThreadingHTTPServer((host, 0), Hostile)
    httpd.daemon_threads = True
    threading.Thread(target=httpd.serve_forever, daemon=True).start()
    return httpd


@pytest.fixture(scope="module")
def servers():
    """The endpoint on 127.0.0.1 and another host, 127.0.0.2, that a redirect names."""
    a, b = _serve("127.0.0.1"), _serve("127.0.0.2")
    yield f"http://127.0.0.1:{a.server_address[1]}/v1", f"http://127.0.0.2:{b.server_address[1]}"
    for s in (a, b):
        s.shutdown()
        s.server_close()


@pytest.fixture(autouse=True)
def fresh():
    Hostile.seen.clear()
    Hostile.mode = "ok"


def config(url, **kw):
    return LLMConfig(base_url=url, model="m", api_key="k-secret", **{"timeout_s": 10, **kw})


def test_no_redirect_is_followed_and_the_key_stays_with_the_endpoint(servers):
    endpoint, other = servers
    Hostile.mode, Hostile.redirect_to = "redirect", f"{other}/steal"
    with pytest.raises(LLMError, match=f"HTTP 302 redirects to {other}/steal"):
        chat(MESSAGES, config(endpoint))
    assert len(Hostile.seen) == 1  # the endpoint only; nothing reached the other host
    assert Hostile.seen[0][1]["Authorization"] == "Bearer k-secret"


def test_a_password_in_the_endpoint_url_is_never_shown(servers):
    # "cannot reach the LLM endpoint http://user:hunter2@...": the password in the error
    from tabletop.reader.llm_client import redact_url

    assert redact_url("http://ann:pw@h:8/v1?x=a@b") == "http://ann:***@h:8/v1?x=a@b"
    assert redact_url("https://tok3n@h/v1") == "https://***@h/v1"
    assert redact_url("http://h/v1") == "http://h/v1"
    unreachable = "http://ann:hunter2@127.0.0.1:9/v1"
    with pytest.raises(LLMError) as e:
        chat(MESSAGES, config(unreachable))
    assert "hunter2" not in str(e.value) and "ann:***@127.0.0.1:9" in str(e.value), e.value
    endpoint = servers[0].replace("http://", "http://ann:hunter2@")
    Hostile.body = b"not json"
    for mode in ("ok", "redirect"):
        Hostile.mode, Hostile.redirect_to = mode, servers[1].replace("http://", "http://b:s3@")
        with pytest.raises(LLMError) as e:
            chat(MESSAGES, config(endpoint))
        assert "hunter2" not in str(e.value) and "s3@" not in str(e.value), e.value
        assert "ann:***@" in str(e.value), e.value
    with pytest.raises(ConfigError) as e:
        LLMConfig(base_url="http://ann:hunter2@h:99999/v1", model="m")
    assert "hunter2" not in str(e.value) and "ann:***@" in str(e.value)


def test_one_wall_clock_deadline_for_a_trickling_server(servers):
    Hostile.mode = "trickle"
    t0 = time.monotonic()
    with pytest.raises(LLMError, match="no complete reply within 1.5 s"):
        chat(MESSAGES, config(servers[0], timeout_s=1.5))
    assert time.monotonic() - t0 < 4.0


def test_a_reply_over_the_cap_is_refused(servers):
    Hostile.body = json.dumps({"choices": [{"message": {"content": "x" * 5000}}]}).encode()
    with pytest.raises(LLMError, match="over the cap of 1000 bytes"):
        chat(MESSAGES, config(servers[0], max_reply_bytes=1000))
    Hostile.mode = "unsized"
    with pytest.raises(LLMError, match="over the cap of 20000 bytes"):
        chat(MESSAGES, config(servers[0], max_reply_bytes=20000))
    with pytest.raises(ConfigError, match="max_reply_bytes"):
        config(servers[0], max_reply_bytes=0)
    with pytest.raises(ConfigError, match="timeout_s must be finite"):
        config(servers[0], timeout_s=float("inf"))


@pytest.mark.parametrize(
    ("body", "problem"),
    [
        (b"<html>not json</html>", "not JSON"),
        (b"[" * 100_000, "not JSON"),  # nesting deeper than the parser recurses
        (b'"just text"', "has no 'choices'"),
        (b'{"choices": []}', "has no 0"),
        (b'{"choices": {"0": 1}}', "has no 0"),
        (b'{"choices": ["text"]}', "has no 'message'"),
        (b'{"choices": [{"message": {"role": "assistant"}}]}', "has no 'content'"),
        (b'{"choices": [{"message": {"content": null}}]}', "not text but NoneType"),
        (b'{"choices": [{"message": {"content": [1, 2]}}]}', "not text but list"),
    ],
)
def test_every_malformed_reply_is_a_clear_llm_error(servers, body, problem):
    Hostile.body = body
    with pytest.raises(LLMError, match=problem):
        chat(MESSAGES, config(servers[0]))
